"""Figures: the only module of hexcal that imports matplotlib.

Every ``plot_*`` draws from plain data (dictionaries of :mod:`hexcal.report.convert`,
study rows, arrays, or the array attributes of an error map) and writes a PNG file
atomically. Imports numpy, matplotlib and :mod:`hexcal.core`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from hexcal.core import PARAMETER_NAMES
from hexcal.report.staging import staged_path


def _save(fig: plt.Figure, path: str | os.PathLike[str]) -> None:
    """Save through the command's output set (committed with its other outputs)."""
    try:
        with staged_path(path) as tmp:
            fig.savefig(tmp, dpi=120, bbox_inches="tight", format=Path(path).suffix[1:] or "png")
    finally:
        plt.close(fig)


def plot_parameter_errors(data: Mapping[str, Any], path: str | os.PathLike[str]) -> None:
    """Like the paper's Fig. 10: error of each parameter before and after calibration.

    ``data`` is :func:`hexcal.report.paper_figure_data`: bars are its ``before``,
    ``interior`` and ``boundary`` arrays (42,), the mean absolute error over ``trials``
    trials of each of the 42 parameters (mm).
    """
    names = PARAMETER_NAMES[:42]
    before, interior, boundary = data["before"], data["interior"], data["boundary"]
    x = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(13, 4.5))
    ax.bar(x - 0.27, before, 0.27, label="before calibration")
    ax.bar(x, interior, 0.27, label="after: 15 interior poses")
    ax.bar(x + 0.27, boundary, 0.27, label="after: 15 corners")
    ax.set_xticks(x, names, rotation=90, fontsize=7)
    ax.set_ylabel("mean absolute error (mm)")
    ax.set_yscale("log")
    ax.set_title(f"Identified parameter errors ({data['trials']} trials)")
    ax.legend()
    _save(fig, path)


def plot_validation_errors(data: Mapping[str, Any], path: str | os.PathLike[str]) -> None:
    """Like the paper's Fig. 11: position and orientation error of the validation poses.

    ``data`` is :func:`hexcal.report.paper_figure_data`: the first trial's errors at the
    validation poses, before (``validation_before``) and after (``validation_after``)
    calibration, each with ``position`` (mm) and ``orientation`` (rad) arrays.
    """
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    k = np.arange(1, len(data["validation_before"]["position"]) + 1)
    for ax, key, unit in zip(axes, ("position", "orientation"), ("mm", "rad"), strict=True):
        ax.semilogy(k, data["validation_before"][key], "o-", label="nominal parameters")
        ax.semilogy(k, data["validation_after"][key], "s-", label="identified parameters")
        ax.set_xlabel("validation pose")
        ax.set_ylabel(f"{key} error ({unit})")
        ax.set_xticks(k)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend()
    fig.suptitle("Pose errors at the validation corners (first trial)")
    _save(fig, path)


def plot_study(rows: Sequence[Any], path: str | os.PathLike[str]) -> None:
    """Mean absolute parameter error against the number of poses, per strategy and method.

    Dashed lines are the Cramér–Rao bounds of the same pose strategies (one per strategy
    and noise level). ``rows`` are the ``StudyCell.row()`` dictionaries of a study (cells
    themselves are accepted too).
    """
    rows = [r.row() if hasattr(r, "row") else r for r in rows]
    fig, ax = plt.subplots(figsize=(8, 5))
    keys = sorted({(r["strategy"], r["noise"], r["method"]) for r in rows})
    for strategy, noise, method in keys:
        sel = sorted(
            (r for r in rows if (r["strategy"], r["noise"], r["method"]) == (strategy, noise, method)),
            key=lambda r: r["poses"],
        )
        ax.plot(
            [r["poses"] for r in sel],
            [r["error_mean"] for r in sel],
            "o-",
            label=f"{strategy}, {method}, noise {noise}",
        )
    for strategy, noise in sorted({(r["strategy"], r["noise"]) for r in rows}):
        sel = sorted(
            (r for r in rows if (r["strategy"], r["noise"]) == (strategy, noise)), key=lambda r: r["poses"]
        )
        ax.plot([r["poses"] for r in sel], [r["bound"] for r in sel], "k--", lw=0.8, alpha=0.6)
    ax.set_xlabel("number of measurement poses")
    ax.set_ylabel("mean absolute parameter error (mm)")
    ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title("Calibration campaigns (dashed: Cramér–Rao bounds)")
    ax.legend(fontsize=7)
    _save(fig, path)


# -- observability and pose selection (issue 4) -------------------------------------------------


def plot_error_lines(line_map: Any, path: str | os.PathLike[str], curves: int = 20) -> None:
    """Like the seed paper's Figs. 4-6: pose error along a sweep, one curve per level.

    Shows ``curves`` of the levels (evenly chosen, coloured by the level value); each curve
    is the mean over the parameter draws. Left: position error (mm); right: orientation
    error (mrad).
    """
    mean_pos = line_map.position.mean(axis=-1)
    mean_ang = line_map.orientation.mean(axis=-1) * 1e3
    n_levels = mean_pos.shape[0]
    show = np.unique(np.linspace(0, n_levels - 1, min(curves, n_levels)).round().astype(int))
    cmap = plt.get_cmap("viridis")
    lo, hi = line_map.levels[0], line_map.levels[-1]
    norm = matplotlib.colors.Normalize(lo, hi if hi > lo else lo + 1)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    for ax, values, label in zip(
        axes, (mean_pos, mean_ang), ("position error (mm)", "orientation error (mrad)"), strict=True
    ):
        for k in show:
            ax.plot(line_map.values, values[k], color=cmap(norm(line_map.levels[k])), lw=1.2)
        ax.set_xlabel(f"{line_map.axis} (mm)")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    bar = fig.colorbar(matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap), ax=axes, shrink=0.9)
    bar.set_label(f"{line_map.level_axis} (mm)")
    fig.suptitle(
        f"Pose error along {line_map.axis} ({len(show)} of {n_levels} {line_map.level_axis} levels; "
        f"mean over {line_map.position.shape[-1]} parameter error draws)"
    )
    _save(fig, path)


def plot_error_angles(angle_map: Any, path: str | os.PathLike[str]) -> None:
    """Like the seed paper's Figs. 7-9: mean pose error over a grid of two angles.

    Top row position error (mm), bottom row orientation error (mrad); left at the lowest,
    right at the highest z level, each panel with its own colour scale.
    """
    v1, v2 = (np.rad2deg(v) for v in angle_map.values)
    picks = (0, len(angle_map.levels) - 1)
    fig, axes = plt.subplots(2, 2, figsize=(10, 8), constrained_layout=True)
    rows = (
        (angle_map.position, "position error (mm)"),
        (angle_map.orientation * 1e3, "orientation error (mrad)"),
    )
    for row, (values, label) in enumerate(rows):
        for col, k in enumerate(picks):
            ax = axes[row, col]
            # one colour scale per panel: the variation within a z level is what matters
            filled = ax.contourf(v1, v2, values[k].T, levels=15, cmap="viridis")
            ax.set_xlabel(f"{angle_map.axes[0]} (deg)")
            ax.set_ylabel(f"{angle_map.axes[1]} (deg)")
            ax.set_title(f"z = {angle_map.levels[k]:g} mm")
            fig.colorbar(filled, ax=ax, label=label)
    fig.suptitle(f"Pose error over {angle_map.axes[0]} and {angle_map.axes[1]}")
    _save(fig, path)


def plot_selection_study(
    counts: np.ndarray,
    predicted: dict[str, np.ndarray],
    empirical: dict[str, tuple[np.ndarray, np.ndarray]],
    path: str | os.PathLike[str],
    title: str = "",
) -> None:
    """Mean parameter error against the number of measurement poses, per strategy.

    Parameters
    ----------
    counts : ndarray, shape (k,)
        Numbers of poses of the predicted curves.
    predicted : dict of str to ndarray, shape (k,)
        Predicted mean absolute parameter error (mm) per strategy (lines).
    empirical : dict of str to (ndarray, ndarray)
        Pose counts and Monte Carlo mean errors (markers), same keys.
    """
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for k, (label, values) in enumerate(predicted.items()):
        color = f"C{k}"
        ax.plot(counts, values, "-", color=color, label=f"{label}: predicted")
        if label in empirical:
            n, err = empirical[label]
            ax.plot(n, err, "o", color=color, label=f"{label}: Monte Carlo")
    ax.set_xlabel("number of measurement poses")
    ax.set_ylabel("mean absolute parameter error (mm)")
    ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    if title:
        ax.set_title(title)
    _save(fig, path)
