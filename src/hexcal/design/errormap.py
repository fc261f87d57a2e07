"""Error maps: the platform pose error that kinematic parameter errors cause over the workspace.

The seed paper's section IV (Figs. 4-9) gives the parameters random errors in
``[-0.1, 0.1]`` mm and plots the resulting pose error of the platform along sweeps of x,
y and z (one curve per z level, 100 levels) and over pairs of angles, and reads from the
figures that the error, hence the observability of parameter errors, is largest on the
workspace boundary and at larger z. This module computes those maps for many random
parameter draws at once.

The controller commands the nominal leg readings of a target pose; a machine with
parameter errors ``δθ`` reaches another pose. To first order the pose error is
``E δθ`` with ``E = -J_pose⁻¹ A`` (:func:`hexcal.calibration.accuracy.pose_error_map`); with
``method="exact"`` the reached pose is the forward kinematics of the perturbed machine.
Position error is ``|δp|`` (mm); orientation error the angle of the rotation between the
target and the reached orientation (rad). The numbers that test the paper's claims are in
:mod:`hexcal.design.paper_claims`. Imports :mod:`hexcal.core` and :mod:`hexcal.design.pose_errors`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core import (
    POSE_NAMES,
    Geometry,
    as_box,
    box_corners,
    parameter_names,
    random_interior,
    workspace_box,
)
from hexcal.core.progress import task
from hexcal.design.identifiability import as_mask
from hexcal.design.pose_errors import mean_pose_errors, parameter_error_draws, pose_error_samples

LINE_AXES = ("x", "y", "z")
ANGLE_PAIRS = (("a", "b"), ("a", "c"), ("b", "c"))


@dataclass(frozen=True)
class LineMap:
    """Pose error along a sweep of one coordinate, one curve per level of another.

    Attributes
    ----------
    axis : str
        Swept coordinate (``x``, ``y`` or ``z``).
    level_axis : str
        Coordinate that differs between curves (``z``; ``x`` for the z sweep).
    values : ndarray, shape (P,)
        Swept values, mm.
    levels : ndarray, shape (L,)
        Level values, mm.
    poses : ndarray, shape (L, P, 6)
    position, orientation : ndarray, shape (L, P, D)
        Error of every parameter draw, mm and rad.
    """

    axis: str
    level_axis: str
    values: NDArray[np.float64]
    levels: NDArray[np.float64]
    poses: NDArray[np.float64]
    position: NDArray[np.float64]
    orientation: NDArray[np.float64]

    def to_dict(self) -> dict[str, Any]:
        """Plain-Python form (for JSON): the sweep and the mean and standard deviation of
        the errors over the draws, shape (L, P) each (not the draws themselves)."""
        return {
            "axis": self.axis,
            "level_axis": self.level_axis,
            "values": self.values.tolist(),
            "levels": self.levels.tolist(),
            "draws": int(self.position.shape[-1]),
            "position_mean_mm": self.position.mean(axis=-1).tolist(),
            "position_sd_mm": self.position.std(axis=-1).tolist(),
            "orientation_mean_rad": self.orientation.mean(axis=-1).tolist(),
            "orientation_sd_rad": self.orientation.std(axis=-1).tolist(),
        }


@dataclass(frozen=True)
class AngleMap:
    """Mean pose error over a grid of two angles, one grid per z level.

    Attributes
    ----------
    axes : tuple of str
        The two angles (``a``, ``b`` or ``c``).
    values : tuple of ndarray, shape (G,) each
        Grid values, rad.
    levels : ndarray, shape (L,)
        z levels, mm.
    poses : ndarray, shape (L, G, G, 6)
    position, orientation : ndarray, shape (L, G, G)
        Mean error over the parameter draws, mm and rad.
    """

    axes: tuple[str, str]
    values: tuple[NDArray[np.float64], NDArray[np.float64]]
    levels: NDArray[np.float64]
    poses: NDArray[np.float64]
    position: NDArray[np.float64]
    orientation: NDArray[np.float64]

    def to_dict(self) -> dict[str, Any]:
        """Plain-Python form (for JSON): the grid and the mean errors, shape (L, G, G)."""
        return {
            "axes": list(self.axes),
            "values": [v.tolist() for v in self.values],
            "levels": self.levels.tolist(),
            "position_mean_mm": self.position.tolist(),
            "orientation_mean_rad": self.orientation.tolist(),
        }


@dataclass(frozen=True)
class ErrorMaps:
    """All error maps of a geometry (the seed paper's Figs. 4-9) and reference poses.

    Attributes
    ----------
    lines : dict of str to LineMap
        ``x``, ``y`` and ``z`` sweeps.
    angles : dict of str to AngleMap
        ``"a-b"``, ``"a-c"``, ``"b-c"`` grids.
    corners, interior : dict of str to ndarray
        ``poses`` and the mean ``position`` / ``orientation`` error at the 64 corners of the
        workspace box and at uniform random interior poses.
    amplitude : float
        Half-width of the uniform parameter errors, mm.
    draws : int
    method : str
    """

    lines: dict[str, LineMap]
    angles: dict[str, AngleMap]
    corners: dict[str, NDArray[np.float64]]
    interior: dict[str, NDArray[np.float64]]
    amplitude: float
    draws: int
    method: str
    parameters: tuple[str, ...] = field(default=())

    def to_dict(self) -> dict[str, Any]:
        """Plain-Python form (for JSON): settings, the mean maps and the reference poses.

        >>> from hexcal.core import preset
        >>> maps = error_maps(preset("paper-hmt"), levels=2, points=3, grid=2, draws=4, rng=0, interior=5)
        >>> data = maps.to_dict()
        >>> sorted(data), data["settings"]["draws"], len(data["lines"]["x"]["position_mean_mm"])
        (['angles', 'corners', 'interior', 'lines', 'settings'], 4, 2)
        """
        refs = {
            name: {key: np.asarray(value).tolist() for key, value in ref.items()}
            for name, ref in (("corners", self.corners), ("interior", self.interior))
        }
        return {
            "settings": {
                "amplitude_mm": self.amplitude,
                "draws": self.draws,
                "method": self.method,
                "parameters": list(self.parameters),
            },
            "lines": {axis: line.to_dict() for axis, line in self.lines.items()},
            "angles": {name: grid.to_dict() for name, grid in self.angles.items()},
            **refs,
        }


def _centre(box: NDArray[np.float64]) -> NDArray[np.float64]:
    return box.mean(axis=1)


def line_sweep_poses(
    box: ArrayLike, axis: str, level_axis: str, points: int, levels: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Poses of a line sweep: ``axis`` over its range, one row per level of ``level_axis``.

    The other coordinates sit at the centre of the box. Returns the swept values (P,),
    the levels (L,) and the poses (L, P, 6).

    >>> box = [[-1, 1], [-1, 1], [0, 2], [0, 0], [0, 0], [0, 0]]
    >>> values, levels, poses = line_sweep_poses(box, "x", "z", points=3, levels=2)
    >>> values.tolist(), levels.tolist(), poses.shape
    ([-1.0, 0.0, 1.0], [0.0, 2.0], (2, 3, 6))
    """
    b = as_box(box)
    k, kl = POSE_NAMES.index(axis), POSE_NAMES.index(level_axis)
    values = np.linspace(b[k, 0], b[k, 1], int(points))
    level_values = np.linspace(b[kl, 0], b[kl, 1], int(levels))
    poses = np.broadcast_to(_centre(b), (int(levels), int(points), 6)).copy()
    poses[:, :, k] = values
    poses[:, :, kl] = level_values[:, None]
    return values, level_values, poses


def angle_grid_poses(
    box: ArrayLike, axes: tuple[str, str], grid: int, levels: int
) -> tuple[tuple[NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64], NDArray[np.float64]]:
    """Poses of a grid over two angles at ``levels`` z levels, shape (L, G, G, 6).

    The other coordinates sit at the centre of the box. Returns the two angles' values
    (G,) each, the z levels (L,) and the poses.

    >>> box = [[0, 0], [0, 0], [0, 2], [-0.1, 0.1], [-0.1, 0.1], [0, 0]]
    >>> (a, b), zs, poses = angle_grid_poses(box, ("a", "b"), grid=3, levels=2)
    >>> a.tolist(), zs.tolist(), poses.shape
    ([-0.1, 0.0, 0.1], [0.0, 2.0], (2, 3, 3, 6))
    """
    b = as_box(box)
    k1, k2, kz = POSE_NAMES.index(axes[0]), POSE_NAMES.index(axes[1]), 2
    v1 = np.linspace(b[k1, 0], b[k1, 1], int(grid))
    v2 = np.linspace(b[k2, 0], b[k2, 1], int(grid))
    zs = np.linspace(b[kz, 0], b[kz, 1], int(levels))
    poses = np.broadcast_to(_centre(b), (int(levels), int(grid), int(grid), 6)).copy()
    poses[..., k1] = v1[None, :, None]
    poses[..., k2] = v2[None, None, :]
    poses[..., kz] = zs[:, None, None]
    return (v1, v2), zs, poses


def error_maps(
    geometry: Geometry,
    levels: int = 100,
    points: int = 41,
    grid: int = 21,
    draws: int = 200,
    amplitude: float = 0.1,
    mask: ArrayLike | None = None,
    rng: np.random.Generator | int | None = None,
    method: str = "linear",
    interior: int = 2000,
) -> ErrorMaps:
    """Error maps like the seed paper's Figs. 4-9.

    Parameters
    ----------
    geometry : Geometry
        Nominal geometry with a workspace box.
    levels : int
        Curves per line sweep (z levels; x levels for the z sweep) and z levels of the
        angle grids (the paper: 100).
    points : int
        Points along each line sweep.
    grid : int
        Points per angle of the angle grids.
    draws : int
        Random parameter error draws (the same draws everywhere).
    amplitude : float
        Parameter errors are uniform in ``±amplitude`` mm (the paper: 0.1).
    mask : array_like of bool, shape (48,), optional
        Parameters with errors (default joints and ``l0``).
    rng : Generator, int or None
        Seed of the draws (and of the interior reference poses).
    method : {"linear", "exact"}
        See :func:`pose_error_samples`; ``exact`` is slow for large maps.
    interior : int
        Uniform random interior poses to compare with the corners.

    Returns
    -------
    ErrorMaps

    Examples
    --------
    >>> from hexcal.core import preset
    >>> maps = error_maps(preset("paper-hmt"), levels=2, points=3, grid=2, draws=4, rng=0, interior=5)
    >>> maps.lines["x"].position.shape, maps.angles["a-b"].position.shape, maps.corners["position"].shape
    ((2, 3, 4), (2, 2, 2), (64,))
    """
    box = workspace_box(geometry)
    mask = as_mask(mask)
    for name, value, low in (("levels", levels, 1), ("points", points, 2), ("grid", grid, 2)):
        if int(value) < low:
            raise ValueError(f"{name} must be at least {low}, got {value}")
    gen = np.random.default_rng(rng)
    sample = parameter_error_draws(draws, mask, amplitude, gen)
    with task("error maps", len(LINE_AXES) + len(ANGLE_PAIRS) + 2) as step:
        return _maps(geometry, box, sample, mask, method, (points, levels, grid, interior), gen, step,
                     (amplitude, draws))  # fmt: skip


def _maps(
    geometry: Geometry, box: Any, sample: Any, mask: Any, method: str, sizes: tuple, gen: Any, step: Any,
    settings: tuple,
) -> ErrorMaps:  # fmt: skip
    """The maps of :func:`error_maps`, one ``step`` per map."""
    points, levels, grid, interior = sizes
    amplitude, draws = settings
    lines: dict[str, LineMap] = {}
    for axis in LINE_AXES:
        level_axis = "x" if axis == "z" else "z"
        values, level_values, poses = line_sweep_poses(box, axis, level_axis, points, levels)
        pos, ang = pose_error_samples(geometry, poses, sample, mask, method)
        lines[axis] = LineMap(axis, level_axis, values, level_values, poses, pos, ang)
        step()
    angles: dict[str, AngleMap] = {}
    for pair in ANGLE_PAIRS:
        values2, zs, poses = angle_grid_poses(box, pair, grid, levels)
        pos, ang = mean_pose_errors(geometry, poses, sample, mask, method)
        angles["-".join(pair)] = AngleMap(pair, values2, zs, poses, pos, ang)
        step()
    refs = {}
    for name, poses in (("corners", box_corners(box)), ("interior", random_interior(box, interior, gen))):
        pos, ang = mean_pose_errors(geometry, poses, sample, mask, method)
        refs[name] = {"poses": poses, "position": pos, "orientation": ang}
        step()
    return ErrorMaps(
        lines=lines,
        angles=angles,
        corners=refs["corners"],
        interior=refs["interior"],
        amplitude=float(amplitude),
        draws=int(draws),
        method=method,
        parameters=parameter_names(mask),
    )
