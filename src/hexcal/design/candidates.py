"""Candidate measurement poses and their feasibility.

Candidates come from the workspace box of a geometry (its 64 corners, grids on its
boundary, uniform random interior poses) or from the user; every candidate is checked
against the leg length limits and against a minimum distance from singularity before
it may be proposed (:func:`check_feasibility`). Imports :mod:`hexcal.core`.

>>> from hexcal.core import preset
>>> machine = preset("paper-hmt")
>>> candidate_poses(machine, "corners").shape
(64, 6)
>>> check_feasibility(machine, candidate_poses(machine, "corners")).n_infeasible
0
>>> report = check_feasibility(machine, [machine.home_pose, [0, 0, 0, 0, 0, 1.57]])
>>> report.feasible.tolist(), report.to_dict()["reasons"][1]
([True, False], 'leg below its lower limit, near singular (0 < 0.05)')
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core import (
    LEG_LIMIT_MARGIN,
    Geometry,
    as_box,
    as_poses,
    box_corners,
    inverse_kinematics,
    leg_limit_violations,
    pose_jacobian,
    random_interior,
    workspace_box,
)

#: Default minimum of :func:`singularity_distance`. At 0.05 a leg length error of 1 µm can
#: move points of the platform by up to 20 µm; on the seed paper's machine the value is
#: between 0.18 and 0.28 everywhere in its workspace box, 0.25 at home, and it falls to 0
#: at the rotation singularity ``c = ±90°``, below 0.05 beyond about ``|c| = 81°``.
MIN_SINGULARITY_DISTANCE = 0.05

KINDS = ("corners", "grid", "edges", "random")


def boundary_grid(box: ArrayLike, levels: int = 3, min_extreme: int = 1) -> NDArray[np.float64]:
    """Points of a regular grid on the boundary of a box.

    Parameters
    ----------
    box : array_like, shape (6, 2)
    levels : int
        Grid levels per coordinate (>= 2), evenly spaced from low to high.
    min_extreme : int
        Keep grid points with at least this many coordinates at a bound: 1 keeps the
        whole boundary (faces), 5 the edges (1-dimensional), 6 only the corners.

    Returns
    -------
    ndarray, shape (k, 6)
        With ``levels=3`` and ``min_extreme=1``: ``3⁶ - 1 = 728`` points (all but the
        centre); with ``min_extreme=5``: 64 corners and the 192 edge midpoints.

    Examples
    --------
    >>> box = [[-1, 1]] * 6
    >>> boundary_grid(box).shape, boundary_grid(box, 3, 5).shape, boundary_grid(box, 2).shape
    ((728, 6), (256, 6), (64, 6))
    """
    b = as_box(box)
    levels = int(levels)
    if levels < 2:
        raise ValueError(f"grid levels must be at least 2, got {levels}")
    if not 1 <= min_extreme <= 6:
        raise ValueError(f"min_extreme must be between 1 and 6, got {min_extreme}")
    index = np.array(list(itertools.product(range(levels), repeat=6)))
    extreme = np.sum((index == 0) | (index == levels - 1), axis=1)
    index = index[extreme >= min_extreme]
    t = index / (levels - 1)
    return b[:, 0] + t * (b[:, 1] - b[:, 0])


def candidate_poses(
    geometry: Geometry,
    kind: str,
    count: int | None = None,
    rng: np.random.Generator | int | None = None,
) -> NDArray[np.float64]:
    """Candidate poses of one kind from the geometry's workspace box.

    Parameters
    ----------
    geometry : Geometry
    kind : {"corners", "grid", "edges", "random"}
        ``corners``: the 64 corners; ``grid``: the boundary grid with ``count`` levels
        (default 3: 728 poses); ``edges``: the grid points on the box edges with ``count``
        levels (default 3: 256 poses); ``random``: ``count`` uniform interior poses.
    count : int, optional
    rng : Generator, int or None
        For ``random``.

    Returns
    -------
    ndarray, shape (k, 6)
    """
    box = workspace_box(geometry)
    if kind == "corners":
        return box_corners(box)
    if kind == "grid":
        return boundary_grid(box, 3 if count is None else count, 1)
    if kind == "edges":
        return boundary_grid(box, 3 if count is None else count, 5)
    if kind == "random":
        if count is None:
            raise ValueError("random candidates need a number, e.g. random:1000")
        return random_interior(box, count, rng)
    raise ValueError(f"unknown candidate kind {kind!r}; choose from {', '.join(KINDS)}")


# -- feasibility --------------------------------------------------------------------------


def platform_radius(geometry: Geometry) -> float:
    """Mean distance of the platform joints from the platform origin, mm.

    >>> from hexcal.core import preset
    >>> round(platform_radius(preset("paper-hmt")), 1)
    125.0
    """
    return float(np.mean(np.linalg.norm(geometry.platform_joints, axis=1)))


def singularity_distance(
    geometry: Geometry, poses: ArrayLike, length_scale: float | None = None
) -> NDArray[np.float64]:
    """Smallest singular value of the dimensionless pose Jacobian, shape (...).

    Parameters
    ----------
    geometry : Geometry
    poses : array_like, shape (..., 6)
    length_scale : float, optional
        Length ``L`` (mm) that makes the angular columns comparable with the linear ones;
        default the platform radius (:func:`platform_radius`).

    Notes
    -----
    ``σmin(J diag(1, 1, 1, 1/L, 1/L, 1/L))`` with ``J = d l / d pose``: the smallest leg
    length change (mm) per mm of motion of the platform points at distance ``L`` from
    its origin. It is 0 at a singular pose, where some motion does not change any leg.

    Examples
    --------
    >>> from hexcal.core import preset
    >>> machine = preset("paper-hmt")
    >>> round(float(singularity_distance(machine, machine.home_pose)), 2)
    0.25
    """
    poses = as_poses(poses)
    scale = platform_radius(geometry) if length_scale is None else float(length_scale)
    jac = pose_jacobian(geometry, poses)
    col = np.array([1.0, 1.0, 1.0, 1.0 / scale, 1.0 / scale, 1.0 / scale])
    return np.linalg.svd(jac * col, compute_uv=False)[..., -1]


@dataclass(frozen=True)
class Feasibility:
    """Which poses may be measured, and why the others may not.

    Attributes
    ----------
    too_short, too_long : ndarray of bool, shape (m,)
        Some leg below the lower / above the upper leg length limit.
    near_singular : ndarray of bool, shape (m,)
        :func:`singularity_distance` below ``min_distance``.
    distance : ndarray, shape (m,)
        :func:`singularity_distance` of every pose.
    min_distance : float
    """

    too_short: NDArray[np.bool_]
    too_long: NDArray[np.bool_]
    near_singular: NDArray[np.bool_]
    distance: NDArray[np.float64]
    min_distance: float

    @property
    def feasible(self) -> NDArray[np.bool_]:
        """Poses within the leg limits and far enough from singularity, shape (m,)."""
        return ~(self.too_short | self.too_long | self.near_singular)

    @property
    def n_infeasible(self) -> int:
        return int(np.sum(~self.feasible))

    def reasons(self, k: int) -> str:
        """Why pose ``k`` is infeasible (empty when it is feasible)."""
        out = []
        if self.too_short[k]:
            out.append("leg below its lower limit")
        if self.too_long[k]:
            out.append("leg above its upper limit")
        if self.near_singular[k]:
            out.append(f"near singular ({self.distance[k]:.3g} < {self.min_distance:g})")
        return ", ".join(out)

    def summary(self) -> str:
        """One line: how many poses fail each test."""
        parts = [
            f"{int(self.too_short.sum())} with a leg below its lower limit",
            f"{int(self.too_long.sum())} above the upper limit",
            f"{int(self.near_singular.sum())} near a singularity (distance < {self.min_distance:g})",
        ]
        return f"{self.n_infeasible} of {self.feasible.size} infeasible: " + ", ".join(parts)

    def to_dict(self) -> dict[str, Any]:
        """Plain-Python form (for JSON): counts, and per pose whether it is feasible, its
        singularity distance and why not (empty when it is)."""
        return {
            "n_poses": int(self.feasible.size),
            "n_feasible": int(self.feasible.sum()),
            "n_infeasible": self.n_infeasible,
            "too_short": int(self.too_short.sum()),
            "too_long": int(self.too_long.sum()),
            "near_singular": int(self.near_singular.sum()),
            "min_distance": self.min_distance,
            "feasible": self.feasible.tolist(),
            "distance": self.distance.tolist(),
            "reasons": [self.reasons(k) for k in range(self.feasible.size)],
        }


def check_feasibility(
    geometry: Geometry,
    poses: ArrayLike,
    min_distance: float = MIN_SINGULARITY_DISTANCE,
    margin: float = LEG_LIMIT_MARGIN,
) -> Feasibility:
    """Check poses against the leg length limits and a minimum distance from singularity.

    Parameters
    ----------
    geometry : Geometry
        Without ``leg_length_limits`` only the singularity test applies.
    poses : array_like, shape (m, 6)
    min_distance : float
        Minimum :func:`singularity_distance` (dimensionless), default
        :data:`MIN_SINGULARITY_DISTANCE`.
    margin : float
        Tolerance beyond the leg length limits, mm.

    Returns
    -------
    Feasibility
        With :meth:`Feasibility.reasons` per pose (see the module's example).
    """
    poses = as_poses(poses).reshape(-1, 6)
    if not np.all(np.isfinite(poses)):
        raise ValueError("candidate poses contain NaN or inf")
    short, long = leg_limit_violations(geometry, inverse_kinematics(geometry, poses), margin)
    distance = singularity_distance(geometry, poses)
    return Feasibility(
        too_short=short,
        too_long=long,
        near_singular=distance < min_distance,
        distance=distance,
        min_distance=float(min_distance),
    )


@dataclass(frozen=True)
class PlannedMeasurements:
    """An instrument planner's candidate or chosen measurements: poses ``(m, 6)`` (mm, rad),
    their ids, the lines that describe them, what they are (``ballbar circles``) and, for a
    selection, its JSON-ready ``data``."""

    poses: NDArray[np.float64]
    ids: tuple[str, ...]
    lines: list[str]
    what: str = "candidate measurements"
    data: dict[str, Any] | None = None
