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


def _note(fig: plt.Figure, note: str) -> None:
    """The conditions of a figure (amplitude, noise, trials) as a text line below it."""
    if note:
        fig.text(0.5, -0.01, note, ha="center", va="top", fontsize=8, color="0.25")


def _legend_outside(ax: Any, fontsize: float = 8) -> None:
    """The legend right of the axes, off the data."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=fontsize, frameon=False)


def conditions(
    trials: int | None = None,
    noise: Mapping[str, Any] | str | None = None,
    amplitude: str | float | None = None,
    seed: int | None = None,
) -> str:
    """The one-line conditions written on a figure: parameter errors, noise, trials, seed.

    >>> conditions(100, "leg 0.01 mm", 5.0, 0)
    'parameter errors ±5 mm · noise leg 0.01 mm · 100 trials · seed 0'
    """
    parts = []
    if amplitude is not None:
        parts.append(
            f"parameter errors ±{amplitude:g} mm"
            if isinstance(amplitude, float | int)
            else f"parameter errors: {amplitude}"
        )
    if isinstance(noise, Mapping):
        text = (
            f"noise leg {noise['leg']:g} mm, position {noise['position']:g} mm, "
            f"orientation {noise['orientation']:g} rad"
        )
        if noise.get("distribution"):
            text += f" ({noise['distribution']})"
        parts.append(text)
    elif noise:
        parts.append(f"noise {noise}")
    if trials is not None:
        parts.append(f"{trials} trials")
    if seed is not None:
        parts.append(f"seed {seed}")
    return " · ".join(parts)


def parameter_errors_figure(data: Mapping[str, Any]) -> plt.Figure:
    """The figure of :func:`plot_parameter_errors` (``data["note"]``: the conditions line)."""
    names = PARAMETER_NAMES[:42]
    before, interior, boundary = data["before"], data["interior"], data["boundary"]
    x = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(13, 4.5))
    ax.bar(x - 0.27, before, 0.27, color="0.65", label="before calibration")
    ax.bar(
        x, interior, 0.27, color="C1", hatch="//", edgecolor="white", lw=0, label="after: 15 interior poses"
    )
    ax.bar(x + 0.27, boundary, 0.27, color="C0", label="after: 15 corners")
    ax.set_xticks(x, names, rotation=90, fontsize=7)
    ax.set_xlim(-0.7, len(names) - 0.3)
    ax.set_ylabel("mean absolute parameter error (mm)")
    ax.set_yscale("log")
    ax.grid(True, axis="y", which="major", alpha=0.3)
    ax.set_title(f"Identified parameter errors (mean over {data['trials']} trials)")
    _legend_outside(ax)
    _note(fig, data.get("note", ""))
    return fig


def plot_parameter_errors(data: Mapping[str, Any], path: str | os.PathLike[str]) -> None:
    """Like the paper's Fig. 10: error of each parameter before and after calibration.

    ``data`` is :func:`hexcal.report.paper_figure_data`: bars are its ``before``,
    ``interior`` and ``boundary`` arrays (42,), the mean absolute error over ``trials``
    trials of each of the 42 parameters (mm); an optional ``note`` (see :func:`conditions`)
    is written below the figure.
    """
    _save(parameter_errors_figure(data), path)


def validation_errors_figure(data: Mapping[str, Any]) -> plt.Figure:
    """The figure of :func:`plot_validation_errors`."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    k = np.arange(1, len(data["validation_before"]["position"]) + 1)
    for ax, key, scale, unit in zip(
        axes, ("position", "orientation"), (1.0, 1e3), ("mm", "mrad"), strict=True
    ):
        ax.semilogy(
            k,
            np.asarray(data["validation_before"][key]) * scale,
            "o--",
            color="C1",
            label="nominal parameters",
        )
        ax.semilogy(
            k,
            np.asarray(data["validation_after"][key]) * scale,
            "s-",
            color="C0",
            label="identified parameters (15 corners)",
        )
        ax.set_xlabel("validation pose (corner number)")
        ax.set_ylabel(f"{key} error ({unit})")
        ax.set_xticks(k)
        ax.grid(True, which="both", alpha=0.3)
    _legend_outside(axes[1])
    fig.suptitle("Pose errors at the validation corners (first trial)")
    _note(fig, data.get("note", ""))
    return fig


def plot_validation_errors(data: Mapping[str, Any], path: str | os.PathLike[str]) -> None:
    """Like the paper's Fig. 11: position and orientation error of the validation poses.

    ``data`` is :func:`hexcal.report.paper_figure_data`: the first trial's errors at the
    validation poses, before (``validation_before``) and after (``validation_after``)
    calibration, each with ``position`` (mm) and ``orientation`` (rad) arrays; drawn in mm
    and mrad, with the optional ``note`` below.
    """
    _save(validation_errors_figure(data), path)


_STYLES = ("-", "--", "-.", (0, (6, 2, 1, 2, 1, 2)))
_MARKERS = ("o", "s", "^", "D", "v", "P")


def study_figure(rows: Sequence[Any], note: str = "") -> plt.Figure:
    """The figure of :func:`plot_study`: colour per strategy, line style per method, marker
    per noise level, so that no two curves look alike even where colours repeat."""
    rows = [r.row() if hasattr(r, "row") else r for r in rows]
    fig, ax = plt.subplots(figsize=(8, 5))
    strategies = sorted({r["strategy"] for r in rows})
    methods = sorted({r["method"] for r in rows})
    noises = sorted({r["noise"] for r in rows})
    keys = sorted({(r["strategy"], r["noise"], r["method"]) for r in rows})
    for strategy, noise, method in keys:
        sel = sorted(
            (r for r in rows if (r["strategy"], r["noise"], r["method"]) == (strategy, noise, method)),
            key=lambda r: r["poses"],
        )
        ax.plot(
            [r["poses"] for r in sel],
            [r["error_mean"] for r in sel],
            color=f"C{strategies.index(strategy) % 10}",
            ls=_STYLES[methods.index(method) % len(_STYLES)],
            marker=_MARKERS[noises.index(noise) % len(_MARKERS)],
            label=f"{strategy}, {method}, noise {noise}",
        )
    for strategy, noise in sorted({(r["strategy"], r["noise"]) for r in rows}):
        sel = sorted(
            (r for r in rows if (r["strategy"], r["noise"]) == (strategy, noise)), key=lambda r: r["poses"]
        )
        ax.plot(
            [r["poses"] for r in sel],
            [r["bound"] for r in sel],
            color=f"C{strategies.index(strategy) % 10}",
            ls=(0, (1, 2)),
            lw=1,
            alpha=0.7,
        )
    ax.plot([], [], color="0.3", ls=(0, (1, 2)), lw=1, label="Cramér–Rao bound (per strategy, noise)")
    ax.set_xlabel("number of measurement poses")
    ax.set_ylabel("mean absolute parameter error (mm)")
    ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title("Calibration campaigns: parameter error against pose count")
    _legend_outside(ax, 7)
    _note(fig, note)
    return fig


def plot_study(rows: Sequence[Any], path: str | os.PathLike[str], note: str = "") -> None:
    """Mean absolute parameter error against the number of poses, per strategy and method.

    Dotted lines are the Cramér–Rao bounds of the same pose strategies (one per strategy
    and noise level). ``rows`` are the ``StudyCell.row()`` dictionaries of a study (cells
    themselves are accepted too); ``note`` (see :func:`conditions`) is written below.
    """
    _save(study_figure(rows, note), path)


# -- observability and pose selection (issue 4) -------------------------------------------------


def plot_error_lines(line_map: Any, path: str | os.PathLike[str], curves: int = 20, note: str = "") -> None:
    """Like the seed paper's Figs. 4-6: pose error along a sweep, one curve per level.

    Shows ``curves`` of the levels (evenly chosen, coloured by the level value); each curve
    is the mean over the parameter draws. Left: position error (mm); right: orientation
    error (mrad); ``note`` (amplitude of the parameter errors, see :func:`conditions`) is
    written below.
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
    _note(fig, note)
    _save(fig, path)


def plot_error_angles(angle_map: Any, path: str | os.PathLike[str], note: str = "") -> None:
    """Like the seed paper's Figs. 7-9 (:func:`error_angles_figure`), saved as a PNG."""
    _save(error_angles_figure(angle_map, note), path)


def error_angles_figure(angle_map: Any, note: str = "") -> plt.Figure:
    """Mean pose error over a grid of two angles (the seed paper's Figs. 7-9).

    Top row position error (mm), bottom row orientation error (mrad); left at the lowest,
    right at the highest z level. The two panels of a row share one colour scale (and one
    colour bar), so that the z levels compare at a glance; labelled white contours show the
    variation within each panel; ``note`` is written below.
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
        lo, hi = float(np.min(shown)), float(np.max(shown))
        bounds = np.linspace(lo, hi if hi > lo else lo + 1e-12, 16)
        for col, k in enumerate(picks):
            ax = axes[row, col]
            filled = ax.contourf(v1, v2, values[k].T, levels=bounds, cmap="viridis")
            # labelled contours of the panel itself: the variation within one z level
            lines = ax.contour(v1, v2, values[k].T, levels=5, colors="white", linewidths=0.6)
            ax.clabel(lines, fontsize=7, fmt="%.3g")
            ax.set_xlabel(f"{angle_map.axes[0]} (deg)")
            ax.set_ylabel(f"{angle_map.axes[1]} (deg)")
            ax.set_title(f"z = {angle_map.levels[k]:g} mm")
        fig.colorbar(filled, ax=axes[row, :], label=label)
    fig.suptitle(
        f"Mean pose error over {angle_map.axes[0]} and {angle_map.axes[1]} "
        "(one colour scale per row, shared by the z levels)"
    )
    _note(fig, note)
    return fig


def plot_selection_study(
    counts: np.ndarray,
    predicted: dict[str, np.ndarray],
    empirical: dict[str, tuple[np.ndarray, np.ndarray]],
    path: str | os.PathLike[str],
    title: str = "",
    note: str = "",
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
    note : str
        The conditions (noise, trials; see :func:`conditions`), written below the figure.
    """
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for k, (label, values) in enumerate(predicted.items()):
        color = f"C{k}"
        ax.plot(counts, values, _STYLES[k % len(_STYLES)], color=color, label=f"{label}: predicted")
        if label in empirical:
            n, err = empirical[label]
            marker = _MARKERS[k % len(_MARKERS)]
            ax.plot(n, err, marker, color=color, mfc="none", label=f"{label}: Monte Carlo")
    ax.set_xlabel("number of measurement poses")
    ax.set_ylabel("mean absolute parameter error (mm)")
    ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.3)
    _legend_outside(ax)
    if title:
        ax.set_title(title)
    _note(fig, note)
    _save(fig, path)
