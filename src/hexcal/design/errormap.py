"""Error maps: the platform pose error that kinematic parameter errors cause over the workspace.

The seed paper's section IV (Figs. 4-9) gives the parameters random errors in
``[-0.1, 0.1]`` mm and plots the resulting pose error of the platform along sweeps of x,
y and z (one curve per z level, 100 levels) and over pairs of angles, and reads from the
figures that the error, hence the observability of parameter errors, is largest on the
workspace boundary and at larger z. This module computes those maps for many random
parameter draws at once and the numbers that test the two claims (:func:`claims`).

The controller commands the nominal leg readings of a target pose; a machine with
parameter errors ``δθ`` reaches another pose. To first order the pose error is
``E δθ`` with ``E = -J_pose⁻¹ A`` (:func:`hexcal.design.identifiability.pose_error_map`); with
``method="exact"`` the reached pose is the forward kinematics of the perturbed machine.
Position error is ``|δp|`` (mm); orientation error the angle of the rotation between the
target and the reached orientation (rad).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.conventions import POSE_NAMES, as_poses, orientation_error
from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import forward_kinematics_from_arrays, inverse_kinematics
from hexcal.core.parameters import PARAMETER_SCALE, select_parameters
from hexcal.core.workspace import box_corners, random_interior, workspace_box
from hexcal.design.identifiability import pose_error_map, rotation_vector_map

LINE_AXES = ("x", "y", "z")
ANGLE_PAIRS = (("a", "b"), ("a", "c"), ("b", "c"))
_CHUNK = 2048  # poses per block of the linear map


def parameter_error_draws(
    n_draws: int,
    mask: ArrayLike | None = None,
    amplitude: float = 0.1,
    rng: np.random.Generator | int | None = None,
) -> NDArray[np.float64]:
    """Random parameter errors, uniform in ``±amplitude`` characteristic units, shape (D, n).

    ``amplitude`` is in mm for joints and ``l0`` (the paper's 0.1 mm); gains get
    ``amplitude`` times their scale (1e-3, :data:`hexcal.estimation.identification.PARAMETER_SCALE`).
    """
    mask = select_parameters() if mask is None else np.asarray(mask, dtype=bool)
    if int(n_draws) < 1:
        raise ValueError(f"the number of parameter draws must be at least 1, got {n_draws}")
    if not (np.isfinite(amplitude) and amplitude > 0):
        raise ValueError(f"the parameter error amplitude must be > 0, got {amplitude}")
    gen = np.random.default_rng(rng)
    scale = PARAMETER_SCALE[mask]
    return gen.uniform(-amplitude, amplitude, size=(int(n_draws), scale.size)) * scale


def _linear_errors(
    geometry: Geometry, poses: NDArray[np.float64], draws: NDArray[np.float64], mask: NDArray[np.bool_]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Position and orientation errors (m, D) of flat poses (m, 6) by the first-order map."""
    m, n = poses.shape[0], draws.shape[1]
    e = pose_error_map(geometry, poses, mask)  # (m, 6, n)
    # angle rows to rotation-vector rows first: n columns are fewer than D draws
    e[:, 3:] = np.matmul(rotation_vector_map(geometry, poses), e[:, 3:])
    d = (e.reshape(-1, n) @ draws.T).reshape(m, 6, -1)  # (m, 6, D): δp and ω
    d *= d
    return np.sqrt(d[:, 0] + d[:, 1] + d[:, 2]), np.sqrt(d[:, 3] + d[:, 4] + d[:, 5])


def _exact_errors(
    geometry: Geometry, poses: NDArray[np.float64], draws: NDArray[np.float64], mask: NDArray[np.bool_]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Position and orientation errors (m, D) by the forward kinematics of each perturbed machine."""
    full = geometry.to_vector(gains=True)
    vectors = np.broadcast_to(full, (draws.shape[0], full.size)).copy()
    vectors[:, mask] += draws
    u = vectors[:, :18].reshape(-1, 1, 6, 3)
    s = vectors[:, 18:36].reshape(-1, 1, 6, 3)
    readings = (inverse_kinematics(geometry, poses) - geometry.initial_leg_lengths) / geometry.leg_gains
    lengths = vectors[:, None, 36:42] + vectors[:, None, 42:48] * readings  # (D, m, 6)
    result = forward_kinematics_from_arrays(u, s, lengths, poses, geometry.euler)
    if not result.all_converged:
        raise ValueError(
            f"forward kinematics of the perturbed machines did not converge for "
            f"{int(np.sum(~result.converged))} pose(s)"
        )
    reached = np.swapaxes(result.poses, 0, 1)  # (m, D, 6)
    targets = np.broadcast_to(poses[:, None], reached.shape)
    position = np.linalg.norm(reached[..., :3] - targets[..., :3], axis=-1)
    return position, orientation_error(targets[..., 3:], reached[..., 3:], geometry.euler)


def pose_error_samples(
    geometry: Geometry,
    poses: ArrayLike,
    draws: ArrayLike,
    mask: ArrayLike | None = None,
    method: str = "linear",
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Pose error at every pose for every parameter draw.

    Parameters
    ----------
    geometry : Geometry
        The nominal machine (the controller's parameters).
    poses : array_like, shape (..., 6)
        Target poses.
    draws : array_like, shape (D, n)
        Parameter errors (parameter units), columns the parameters of ``mask``.
    mask : array_like of bool, shape (48,), optional
        Default joints and ``l0``.
    method : {"linear", "exact"}
        First-order map, or forward kinematics of every perturbed machine.

    Returns
    -------
    position : ndarray, shape (..., D), mm
    orientation : ndarray, shape (..., D), rad
    """
    mask = select_parameters() if mask is None else np.asarray(mask, dtype=bool)
    poses = as_poses(poses)
    draws = np.atleast_2d(np.asarray(draws, dtype=float))
    if draws.shape[1] != int(mask.sum()):
        raise ValueError(f"draws must have shape (D, {int(mask.sum())}), got {draws.shape}")
    batch = poses.shape[:-1]
    flat = poses.reshape(-1, 6)
    if method == "linear":
        fn = _linear_errors
    elif method == "exact":
        fn = _exact_errors
    else:
        raise ValueError(f"unknown method {method!r}; choose linear or exact")
    pos = np.empty((flat.shape[0], draws.shape[0]))
    ang = np.empty_like(pos)
    step = max(1, _CHUNK * 64 // draws.shape[0])
    for start in range(0, flat.shape[0], step):
        sl = slice(start, start + step)
        pos[sl], ang[sl] = fn(geometry, flat[sl], draws, mask)
    return pos.reshape(batch + (-1,)), ang.reshape(batch + (-1,))


# -- maps -----------------------------------------------------------------------------------


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


def _centre(box: NDArray[np.float64]) -> NDArray[np.float64]:
    return box.mean(axis=1)


def line_sweep_poses(
    box: ArrayLike, axis: str, level_axis: str, points: int, levels: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Poses of a line sweep: ``axis`` over its range, one row per level of ``level_axis``.

    The other coordinates sit at the centre of the box. Returns the swept values (P,),
    the levels (L,) and the poses (L, P, 6).
    """
    b = np.asarray(box, dtype=float)
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

    The other coordinates sit at the centre of the box.
    """
    b = np.asarray(box, dtype=float)
    k1, k2, kz = POSE_NAMES.index(axes[0]), POSE_NAMES.index(axes[1]), 2
    v1 = np.linspace(b[k1, 0], b[k1, 1], int(grid))
    v2 = np.linspace(b[k2, 0], b[k2, 1], int(grid))
    zs = np.linspace(b[kz, 0], b[kz, 1], int(levels))
    poses = np.broadcast_to(_centre(b), (int(levels), int(grid), int(grid), 6)).copy()
    poses[..., k1] = v1[None, :, None]
    poses[..., k2] = v2[None, None, :]
    poses[..., kz] = zs[:, None, None]
    return (v1, v2), zs, poses


def _mean_errors(
    geometry: Geometry,
    poses: NDArray[np.float64],
    draws: NDArray[np.float64],
    mask: NDArray[np.bool_],
    method: str,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean over draws of the position and orientation error, shape ``poses.shape[:-1]``,
    block by block so that the draws of a large grid never sit in memory at once."""
    flat = poses.reshape(-1, 6)
    pos = np.empty(flat.shape[0])
    ang = np.empty(flat.shape[0])
    step = max(1, _CHUNK * 64 // draws.shape[0])
    for start in range(0, flat.shape[0], step):
        sl = slice(start, start + step)
        p, a = pose_error_samples(geometry, flat[sl], draws, mask, method)
        pos[sl], ang[sl] = p.mean(axis=-1), a.mean(axis=-1)
    return pos.reshape(poses.shape[:-1]), ang.reshape(poses.shape[:-1])


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
    """
    box = workspace_box(geometry)
    mask = select_parameters() if mask is None else np.asarray(mask, dtype=bool)
    for name, value, low in (("levels", levels, 1), ("points", points, 2), ("grid", grid, 2)):
        if int(value) < low:
            raise ValueError(f"{name} must be at least {low}, got {value}")
    gen = np.random.default_rng(rng)
    sample = parameter_error_draws(draws, mask, amplitude, gen)
    lines: dict[str, LineMap] = {}
    for axis in LINE_AXES:
        level_axis = "x" if axis == "z" else "z"
        values, level_values, poses = line_sweep_poses(box, axis, level_axis, points, levels)
        pos, ang = pose_error_samples(geometry, poses, sample, mask, method)
        lines[axis] = LineMap(axis, level_axis, values, level_values, poses, pos, ang)
    angles: dict[str, AngleMap] = {}
    for pair in ANGLE_PAIRS:
        values2, zs, poses = angle_grid_poses(box, pair, grid, levels)
        pos, ang = _mean_errors(geometry, poses, sample, mask, method)
        angles["-".join(pair)] = AngleMap(pair, values2, zs, poses, pos, ang)
    refs = {}
    for name, poses in (("corners", box_corners(box)), ("interior", random_interior(box, interior, gen))):
        pos, ang = _mean_errors(geometry, poses, sample, mask, method)
        refs[name] = {"poses": poses, "position": pos, "orientation": ang}
    from hexcal.design.identifiability import parameter_names

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


# -- the paper's claims, in numbers ------------------------------------------------------------


def _spearman(x: NDArray[np.float64], y: NDArray[np.float64]) -> float:
    rx = np.argsort(np.argsort(x)).astype(float)
    ry = np.argsort(np.argsort(y)).astype(float)
    rx -= rx.mean()
    ry -= ry.mean()
    denom = np.sqrt(np.sum(rx**2) * np.sum(ry**2))
    return float(np.sum(rx * ry) / denom) if denom > 0 else 0.0


def _line_claims(line: LineMap, key: str) -> dict[str, float]:
    draws = getattr(line, key)  # (L, P, D)
    mean = draws.mean(axis=-1)  # (L, P)
    last = mean.shape[1] - 1
    at_end = np.isin(np.argmax(mean, axis=1), (0, last))
    at_end_draws = np.isin(np.argmax(draws, axis=1), (0, last))
    ends = np.maximum(mean[:, 0], mean[:, -1])
    out = {
        "max_at_an_end": float(at_end.mean()),
        "max_at_an_end_single_draws": float(at_end_draws.mean()),
        "max_at_upper_end": float(np.mean(np.argmax(mean, axis=1) == last)),
        "end_over_min": float(np.mean(ends / mean.min(axis=1))),
        "end_over_centre": float(np.mean(ends / mean[:, last // 2])),
    }
    level_mean = mean.mean(axis=1)
    out["level_rank_correlation"] = _spearman(line.levels, level_mean)
    out["top_level_over_bottom_level"] = float(level_mean[-1] / level_mean[0])
    return out


def _angle_claims(grid: AngleMap, key: str) -> dict[str, float]:
    values = getattr(grid, key)  # (L, G, G)
    n_levels, g, _ = values.shape
    flat = values.reshape(n_levels, -1)
    i, j = np.unravel_index(np.argmax(flat, axis=1), (g, g))
    on_edge = (i == 0) | (i == g - 1) | (j == 0) | (j == g - 1)
    at_corner = ((i == 0) | (i == g - 1)) & ((j == 0) | (j == g - 1))
    edge = np.ones((g, g), dtype=bool)
    edge[1:-1, 1:-1] = False
    level_mean = flat.mean(axis=1)
    return {
        "max_on_boundary": float(on_edge.mean()),
        "max_at_a_corner": float(at_corner.mean()),
        "boundary_mean_over_inside_mean": float(
            np.mean(values[:, edge].mean(axis=1) / values[:, ~edge].mean(axis=1))
        ),
        "max_over_centre": float(np.mean(flat.max(axis=1) / values[:, g // 2, g // 2])),
        "level_rank_correlation": _spearman(grid.levels, level_mean),
        "top_level_over_bottom_level": float(level_mean[-1] / level_mean[0]),
    }


def claims(maps: ErrorMaps) -> dict[str, dict[str, dict[str, float]] | dict[str, float]]:
    """Numbers that test the seed paper's claims about its error maps.

    Returns
    -------
    dict
        ``lines[axis][position|orientation]``: fraction of curves (mean over draws) whose
        maximum is at an end of the sweep (``max_at_an_end``; also of single-draw curves
        and at the upper end), the end value over the curve's minimum and over its centre,
        and the Spearman rank correlation between the level (z; x for the z sweep) and the
        curve's mean, with the ratio of the top level's mean to the bottom level's.
        ``angles[pair][...]``: fraction of z levels whose grid maximum is on the boundary of
        the angle square (and at one of its corners), boundary over inside mean, maximum
        over centre, and the z correlation. ``workspace``: mean error at the 64 corners
        over that at random interior poses, and the corners' mean at the top z over the
        bottom z.
    """
    out: dict = {"lines": {}, "angles": {}, "workspace": {}}
    for axis, line in maps.lines.items():
        out["lines"][axis] = {k: _line_claims(line, k) for k in ("position", "orientation")}
    for name, grid in maps.angles.items():
        out["angles"][name] = {k: _angle_claims(grid, k) for k in ("position", "orientation")}
    z = maps.corners["poses"][:, 2]
    top, bottom = z == z.max(), z == z.min()
    for key in ("position", "orientation"):
        c, i = maps.corners[key], maps.interior[key]
        out["workspace"][key] = {
            "corners_mean": float(c.mean()),
            "interior_mean": float(i.mean()),
            "corners_over_interior": float(c.mean() / i.mean()),
            "interior_above_corner_mean": float(np.mean(i > c.mean())),
            "corners_top_z_over_bottom_z": float(c[top].mean() / c[bottom].mean()),
        }
    return out


def format_claims(summary: dict) -> str:
    """The numbers of :func:`claims` as a short report on the paper's two claims."""
    lines_ = ["Boundary claim (errors largest on the workspace boundary):"]
    for axis, by_key in summary["lines"].items():
        p, o = by_key["position"], by_key["orientation"]
        lines_.append(
            f"  {axis} sweep: max at an end in {p['max_at_an_end']:.0%} (position) / "
            f"{o['max_at_an_end']:.0%} (orientation) of the mean curves, "
            f"{p['max_at_an_end_single_draws']:.0%} / {o['max_at_an_end_single_draws']:.0%} of single draws; "
            f"end / centre = {p['end_over_centre']:.3f} / {o['end_over_centre']:.3f}"
        )
    for name, by_key in summary["angles"].items():
        p, o = by_key["position"], by_key["orientation"]
        lines_.append(
            f"  {name} grid: max on the boundary at {p['max_on_boundary']:.0%} / "
            f"{o['max_on_boundary']:.0%} of z levels (at a corner {p['max_at_a_corner']:.0%} / "
            f"{o['max_at_a_corner']:.0%}); max / centre = {p['max_over_centre']:.3f} / "
            f"{o['max_over_centre']:.3f}"
        )
    wp, wo = summary["workspace"]["position"], summary["workspace"]["orientation"]
    lines_.append(
        f"  64 corners vs random interior poses: {wp['corners_mean']:.4f} vs {wp['interior_mean']:.4f} mm "
        f"(x{wp['corners_over_interior']:.3f}), {wo['corners_mean'] * 1e3:.4f} vs "
        f"{wo['interior_mean'] * 1e3:.4f} mrad (x{wo['corners_over_interior']:.3f}); "
        f"{wp['interior_above_corner_mean']:.0%} / {wo['interior_above_corner_mean']:.0%} of interior "
        "poses exceed the corners' mean"
    )
    lines_.append("Height claim (errors larger at larger z):")
    for axis in ("x", "y"):
        p, o = summary["lines"][axis]["position"], summary["lines"][axis]["orientation"]
        lines_.append(
            f"  {axis} sweeps: rank correlation of z with the curve mean "
            f"{p['level_rank_correlation']:+.3f} / {o['level_rank_correlation']:+.3f}; "
            f"top z / bottom z = {p['top_level_over_bottom_level']:.3f} / "
            f"{o['top_level_over_bottom_level']:.3f}"
        )
    p, o = summary["lines"]["z"]["position"], summary["lines"]["z"]["orientation"]
    lines_.append(
        f"  z sweeps: max at the upper end (largest z) in {p['max_at_upper_end']:.0%} / "
        f"{o['max_at_upper_end']:.0%} of the curves"
    )
    for name, by_key in summary["angles"].items():
        p, o = by_key["position"], by_key["orientation"]
        lines_.append(
            f"  {name} grids: top z / bottom z = {p['top_level_over_bottom_level']:.3f} / "
            f"{o['top_level_over_bottom_level']:.3f}"
        )
    lines_.append(
        f"  corners at the top z / bottom z: {wp['corners_top_z_over_bottom_z']:.3f} / "
        f"{wo['corners_top_z_over_bottom_z']:.3f}"
    )
    return "\n".join(lines_)
