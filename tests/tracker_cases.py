"""Shared cases of the tracker tests: a random non-symmetric 6-6 machine and tracker setups."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from hexcal.core.geometry import Geometry
from hexcal.core.presets import preset
from hexcal.core.workspace import random_poses
from hexcal.instruments.setup import Setup

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
