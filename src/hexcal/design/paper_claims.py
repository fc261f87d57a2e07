"""The seed paper's claims about its error maps, in numbers.

The seed paper reads from its Figs. 4-9 that the pose error that parameter errors cause,
hence their observability, is largest on the workspace boundary and at larger z.
:func:`claims` turns the maps of :func:`hexcal.design.errormap.error_maps` into numbers
that test both claims (:func:`hexcal.report.claims_text` writes them as a short text). Imports numpy and
:mod:`hexcal.design.errormap`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hexcal.design.errormap import AngleMap, ErrorMaps, LineMap


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

    Examples
    --------
    >>> from hexcal.core import preset
    >>> from hexcal.design import error_maps
    >>> maps = error_maps(preset("paper-hmt"), levels=3, points=5, grid=3, draws=8, rng=0, interior=50)
    >>> summary = claims(maps)
    >>> sorted(summary), sorted(summary["lines"]["x"])
    (['angles', 'lines', 'workspace'], ['orientation', 'position'])
    >>> summary["workspace"]["position"]["corners_over_interior"] > 1  # the boundary claim
    True
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
