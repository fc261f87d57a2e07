"""Shared fixtures: the seed paper's machine and simulated measurements.

``simulate_measurements`` follows the protocol of :mod:`hexcal.simulation` (and of the
seed paper's section VI): leg readings come from the nominal inverse kinematics, the
true machine reaches the forward kinematics of its own parameters at those readings
(plus the leg sensor error), and the measured pose is that plus the measurement noise.
"""

from __future__ import annotations

import os

# One OpenBLAS thread (unless the caller chose otherwise), set before numpy loads: its threads
# busy-wait, and on a loaded 2-core machine the many small SVDs and solves of these tests ran
# about 25 times slower with two threads (the coverage check: 1 s -> 29 s).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import pytest

from browser_support import browser  # noqa: F401  (one session-wide Chromium for every test module)
from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import forward_kinematics, inverse_kinematics, leg_lengths, leg_readings
from hexcal.core.noise import NoiseModel
from hexcal.core.presets import preset
from hexcal.core.workspace import workspace_corners
from hexcal.instruments.pose import Measurements


def simulate_measurements(
    nominal: Geometry,
    true: Geometry,
    poses: np.ndarray,
    noise: NoiseModel | None = None,
    rng: np.random.Generator | int | None = None,
) -> Measurements:
    """Measurements of commanded ``poses`` (m, 6) on the ``true`` machine; noise-free if ``noise`` is None."""
    poses = np.asarray(poses, dtype=float)
    rng = np.random.default_rng(rng)
    readings = leg_readings(nominal, inverse_kinematics(nominal, poses))
    lengths = leg_lengths(true, readings)
    if noise is not None:
        lengths = lengths + noise.leg_errors(rng, poses.shape[:-1])
    reached = forward_kinematics(true, lengths, guess=poses)
    assert reached.all_converged, "simulated poses must be reachable by the true machine"
    measured = reached.poses
    if noise is not None:
        measured = measured + noise.pose_errors(rng, poses.shape[:-1])
    return Measurements(measured, readings)


@pytest.fixture
def nominal() -> Geometry:
    """The seed paper's machine, nominal values (Table 1 of the companion paper)."""
    return preset("paper-hmt")


@pytest.fixture
def true_machine() -> Geometry:
    """The seed paper's machine, simulated real values (Table 2 of the companion paper)."""
    return preset("paper-hmt-true")


@pytest.fixture
def simulate():
    """The :func:`simulate_measurements` helper, as a fixture."""
    return simulate_measurements


@pytest.fixture
def corner_poses(nominal: Geometry) -> np.ndarray:
    """15 of the 64 workspace corners of paper-hmt, chosen with a fixed seed (as the paper measures)."""
    corners = workspace_corners(nominal)
    return corners[np.random.default_rng(20090101).choice(len(corners), 15, replace=False)]
