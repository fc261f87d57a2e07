"""Shared cases of the tracker tests: a random non-symmetric 6-6 machine and tracker setups."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from hexcal.calibration import estimate
from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import forward_kinematics, inverse_kinematics, leg_lengths, leg_readings
from hexcal.core.noise import NoiseModel
from hexcal.core.presets import preset
from hexcal.core.workspace import random_poses
from hexcal.estimation.result import IdentificationResult
from hexcal.instruments import Session, instrument_for
from hexcal.instruments.setup import Setup
from hexcal.simulation import simulate_session

TARGETS3 = {"t1": [0.0, 0.0, 60.0], "t2": [150.0, 20.0, 55.0], "t3": [-40.0, 160.0, 70.0]}


def general_machines(seed: int = 7) -> tuple[Geometry, Geometry]:
    """A nominal general 6-6 machine (paper-hmt's joints moved by ~20 mm at random) and a
    'true' machine that differs from it by ~1 mm per joint and l0."""
    rng = np.random.default_rng(seed)
    base = preset("paper-hmt")
    nominal = base.replace(
        base_joints=base.base_joints + rng.normal(0, 20, (6, 3)),
        platform_joints=base.platform_joints + rng.normal(0, 20, (6, 3)),
        name="general",
    )
    vec = nominal.to_vector(gains=True)
    vec[:42] += rng.normal(0, 1.0, 42)
    return nominal, nominal.with_vector(vec)


def tracker_setups(n_targets: int, seed: int = 3) -> tuple[Setup, Setup]:
    """(true setup with a frame metres away at an arbitrary rotation, nominal setup: auto
    frame and targets off by a few mm)."""
    rng = np.random.default_rng(seed)
    angles = Rotation.random(random_state=seed).as_euler("XYZ")
    frame = np.concatenate([rng.uniform(-4000, 4000, 3), angles])
    names = list(TARGETS3)[:n_targets]
    true = Setup(frame, {k: TARGETS3[k] for k in names})
    nominal = Setup(None, {k: np.array(TARGETS3[k]) + rng.normal(0, 2.0, 3) for k in names})
    return true, nominal


def poses(geometry: Geometry, n: int, seed: int) -> np.ndarray:
    return random_poses(geometry, n, seed)


def simulate(
    nominal: Geometry,
    true: Geometry,
    setup: Setup,
    poses: np.ndarray,
    noise: NoiseModel | None = None,
    missing_rate: float = 0.0,
    seed: int = 0,
):
    """The data the instrument of the true ``setup`` records at commanded ``poses`` on the
    ``true`` machine (noise-free when ``noise`` is None; ``missing_rate`` for targets)."""
    quiet = NoiseModel(0.0, 0.0, 0.0) if noise is None else noise
    session = simulate_session(
        nominal, true, instrument_for(setup), poses, quiet, seed, missing_rate=missing_rate
    )
    return session.data


def identify(
    nominal: Geometry, data, setup: Setup, noise: NoiseModel | None = None, **kw
) -> IdentificationResult:
    """Maximum likelihood on one session of ``data`` seen by the instrument of ``setup``
    (bound attached, no verdict)."""
    return estimate(nominal, Session(data, instrument_for(setup)), "ml", noise=noise, verdict=False, **kw)


def reached_poses(nominal: Geometry, true: Geometry, commanded: np.ndarray) -> np.ndarray:
    """The poses ``(m, 6)`` the true machine reaches for the nominal leg commands of
    ``commanded`` poses (noise-free)."""
    commanded = np.asarray(commanded, dtype=float).reshape(-1, 6)
    readings = leg_readings(nominal, inverse_kinematics(nominal, commanded))
    fk = forward_kinematics(true, leg_lengths(true, readings), guess=commanded)
    assert fk.all_converged, "the true machine must reach every commanded pose"
    return fk.poses
