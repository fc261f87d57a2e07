"""The workspace: its box, corners and random poses, and the leg length limits.

The single place where poses are checked against the leg length limits
(:func:`leg_limit_violations`) and where the 64 corners of a box are enumerated
(:func:`box_corners`). Imports numpy and the rest of :mod:`hexcal.core`.

>>> from hexcal.core.presets import preset
>>> machine = preset("paper-hmt")
>>> workspace_corners(machine).shape
(64, 6)
>>> bool(is_feasible(machine, machine.home_pose))
True
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import inverse_kinematics
from hexcal.errors import GeometryError, UsageError

#: Tolerance, mm, beyond the leg length limits (the seed machine's lowest corners touch
#: its lower limit up to rounding).
LEG_LIMIT_MARGIN = 1e-6


def workspace_box(geometry: Geometry) -> NDArray[np.float64]:
    """The geometry's workspace box (6, 2), or :class:`GeometryError` naming the missing key."""
    if geometry.workspace is None:
        name = f" {geometry.name}" if geometry.name else ""
        raise GeometryError(f"geometry{name} has no workspace box (add a 'workspace:' mapping)")
    return geometry.workspace


def as_box(box: ArrayLike) -> NDArray[np.float64]:
    """A box ``[low, high]`` per pose coordinate as a float array (6, 2), or UsageError."""
    arr = np.asarray(box, dtype=float)
    if arr.shape != (6, 2):
        raise UsageError(f"workspace box must have shape (6, 2), got {arr.shape}")
    return arr


def box_corners(box: ArrayLike) -> NDArray[np.float64]:
    """The 64 corners of a box (6, 2), shape (64, 6).

    Corner ``k`` takes the high end of coordinate ``j`` when bit ``5 - j`` of ``k`` is set
    (x is the most significant bit).
    """
    b = as_box(box)
    bits = (np.arange(64)[:, None] >> np.arange(5, -1, -1)) & 1
    return np.where(bits == 1, b[:, 1], b[:, 0])


def workspace_corners(geometry: Geometry) -> NDArray[np.float64]:
    """The 64 corners of the geometry's workspace box, shape ``(64, 6)`` (:func:`box_corners`)."""
    return box_corners(workspace_box(geometry))


def random_interior(
    box: ArrayLike, n: int, rng: np.random.Generator | int | None = None
) -> NDArray[np.float64]:
    """``n`` poses drawn uniformly inside a box, shape (n, 6)."""
    b = as_box(box)
    if int(n) < 0:
        raise UsageError(f"number of random poses must be >= 0, got {n}")
    gen = np.random.default_rng(rng)
    return gen.uniform(b[:, 0], b[:, 1], size=(int(n), 6))


def random_poses(
    geometry: Geometry, n: int, rng: np.random.Generator | int | None = None
) -> NDArray[np.float64]:
    """``n`` poses drawn uniformly inside the workspace box, shape ``(n, 6)``."""
    return random_interior(workspace_box(geometry), n, rng)


def leg_limit_violations(
    geometry: Geometry, lengths: ArrayLike, margin: float = LEG_LIMIT_MARGIN
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Which rows of absolute leg lengths ``(..., 6)`` have a leg below / above the limits.

    Both all false when the geometry has no leg length limits.
    """
    lengths = np.asarray(lengths, dtype=float)
    if geometry.leg_length_limits is None:
        none = np.zeros(lengths.shape[:-1], dtype=bool)
        return none, none.copy()
    lo, hi = geometry.leg_length_limits
    return np.any(lengths < lo - margin, axis=-1), np.any(lengths > hi + margin, axis=-1)


def is_feasible(geometry: Geometry, poses: ArrayLike, margin: float = 0.0) -> NDArray[np.bool_]:
    """Whether every leg length of each pose lies within the leg length limits.

    Parameters
    ----------
    geometry : Geometry
    poses : array_like, shape (..., 6)
    margin : float
        Tolerance in mm allowed beyond the limits.

    Returns
    -------
    ndarray of bool, shape (...)
        All true when the geometry has no leg length limits.
    """
    short, long = leg_limit_violations(geometry, inverse_kinematics(geometry, poses), margin)
    return ~(short | long)
