"""Figures of error maps (the seed paper's Figs. 4-9): pose error along a sweep, one curve
per level, and over a grid of two angles, from the maps' ``to_dict()`` means.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize

from hexcal.report.figures.render import note, plt, round_levels, save_png


def error_lines_figure(line_map: Any, curves: int = 20, note_text: str = "") -> Any:
    """Like the seed paper's Figs. 4-6: pose error along a sweep, one curve per level.

    Shows ``curves`` of the levels (evenly chosen, coloured by the level value); each curve
    is the mean over the parameter draws (``LineMap.to_dict()``). Left: position error (mm);
    right: orientation error (mrad); ``note_text`` is written below.
    """
    data = line_map.to_dict()
    mean_pos = np.asarray(data["position_mean_mm"], dtype=float)
    mean_ang = np.asarray(data["orientation_mean_rad"], dtype=float) * 1e3
    levels, values = np.asarray(data["levels"], dtype=float), np.asarray(data["values"], dtype=float)
    n_levels = mean_pos.shape[0]
    show = np.unique(np.linspace(0, n_levels - 1, min(curves, n_levels)).round().astype(int))
    cmap = plt.get_cmap("viridis")
    lo, hi = levels[0], levels[-1]
    norm = Normalize(lo, hi if hi > lo else lo + 1)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    for ax, curve, label in zip(
        axes, (mean_pos, mean_ang), ("position error (mm)", "orientation error (mrad)"), strict=True
    ):
        for k in show:
            ax.plot(values, curve[k], color=cmap(norm(levels[k])), lw=1.2)
        ax.set_xlabel(f"{data['axis']} (mm)")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    bar = fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=axes, shrink=0.9)
    bar.set_label(f"{data['level_axis']} (mm)")
    fig.suptitle(
        f"Pose error along {data['axis']} ({len(show)} of {n_levels} {data['level_axis']} levels; "
        f"mean over {data['draws']} parameter error draws)"
    )
    note(fig, note_text)
    return fig


def plot_error_lines(line_map: Any, path: str | os.PathLike[str], curves: int = 20, note: str = "") -> None:
    """:func:`error_lines_figure` written as a PNG file."""
    save_png(error_lines_figure(line_map, curves, note), path)


def error_angles_figure(angle_map: Any, note_text: str = "") -> Any:
    """Mean pose error over a grid of two angles (the seed paper's Figs. 7-9).

    Top row position error (mm), bottom row orientation error (mrad); left at the lowest,
    right at the highest z level. The two panels of a row share one colour scale (and one
    colour bar, on round numbers), so that the z levels compare at a glance; labelled white
    contours show the variation within each panel; ``note_text`` is written below.
    """
    v1, v2 = (np.rad2deg(v) for v in angle_map.values)
    picks = (0, len(angle_map.levels) - 1)
    fig, axes = plt.subplots(2, 2, figsize=(10, 8), constrained_layout=True)
    rows = (
        (angle_map.position, "position error (mm)"),
        (angle_map.orientation * 1e3, "orientation error (mrad)"),
    )
    for row, (values, label) in enumerate(rows):
        shown = values[list(picks)]
        bounds = round_levels(float(np.min(shown)), float(np.max(shown)), 12)
        for col, k in enumerate(picks):
            ax = axes[row, col]
            filled = ax.contourf(v1, v2, values[k].T, levels=bounds, cmap="viridis")
            # labelled contours of the panel itself: the variation within one z level
            own = round_levels(float(np.min(values[k])), float(np.max(values[k])), 5)
            inside = own[(own > np.min(values[k])) & (own < np.max(values[k]))]
            lines = ax.contour(
                v1, v2, values[k].T, levels=inside if inside.size else 5, colors="white", linewidths=0.6
            )
            ax.clabel(lines, fontsize=7, fmt="%g")
            ax.set_xlabel(f"{angle_map.axes[0]} (deg)")
            ax.set_ylabel(f"{angle_map.axes[1]} (deg)")
            ax.set_title(f"z = {angle_map.levels[k]:g} mm")
        fig.colorbar(filled, ax=axes[row, :], label=label)
    fig.suptitle(
        f"Mean pose error over {angle_map.axes[0]} and {angle_map.axes[1]} "
        "(one colour scale per row, shared by the z levels)"
    )
    note(fig, note_text)
    return fig


def plot_error_angles(angle_map: Any, path: str | os.PathLike[str], note: str = "") -> None:
    """:func:`error_angles_figure` written as a PNG file."""
    save_png(error_angles_figure(angle_map, note), path)
