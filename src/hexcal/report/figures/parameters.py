"""Figures over the parameters: identified changes, the paper's Fig. 10, correlations,
singular values.

A figure with one value per parameter is drawn by :func:`parameter_axes` once: one panel per
unit (lengths in mm, gains in 10⁻³, instrument angles in degrees), the names under the
bars. The identify page's parameter changes and the paper's parameter errors differ only
in what they draw in those panels.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.ticker import MaxNLocator

from hexcal.core.parameters import PARAMETER_NAMES, PARAMETER_UNITS
from hexcal.report.figures.render import legend_outside, log_ticks, note, plain, plt, save_png
from hexcal.report.units import blocks, unit_of

#: Per unit a parameter is held in: the factor to the drawn unit and its label (another unit
#: is drawn as it is).
UNIT_SCALES = {"mm": (1.0, "mm"), "1": (1e3, "×10⁻³"), "rad": (180.0 / math.pi, "deg")}

#: Panels are drawn in this order of their units (then any other unit, as met).
UNIT_ORDER = ("mm", "1", "rad")


def parameter_axes(
    names: Sequence[str], units: Sequence[str], height: float = 4.0, per_name: float = 0.2, base: float = 3.0
) -> tuple[Any, list[tuple[Any, np.ndarray, float, str]]]:
    """A figure with one panel per unit of ``names`` (each parameter's ``units`` as held):
    ``(fig, [(ax, indices, scale, unit label), ...])``; each panel's x axis carries its
    parameters' names."""
    held = np.array(list(units), dtype=object)
    order = [u for u in UNIT_ORDER if u in set(held)]
    order += list(dict.fromkeys(u for u in held if u not in UNIT_ORDER))
    groups = [(u, np.flatnonzero(held == u)) for u in order]
    widths = [max(len(idx), 3) for _, idx in groups]
    fig, axes = plt.subplots(
        1,
        len(groups),
        figsize=(min(base + per_name * sum(widths), 16), height),
        gridspec_kw={"width_ratios": widths},
        squeeze=False,
    )
    panels = []
    for ax, (unit, idx) in zip(axes[0], groups, strict=True):
        scale, label = UNIT_SCALES.get(unit, (1.0, unit))
        x = np.arange(len(idx))
        ax.set_xticks(x, [plain(names[k]) for k in idx], rotation=90, fontsize=7)
        ax.set_xlim(-0.7, len(idx) - 0.3)
        ax.grid(True, axis="y", which="major", alpha=0.3)
        panels.append((ax, idx, scale, label))
    return fig, panels


def _values(result: Mapping[str, Any], key: str, names: Sequence[str]) -> np.ndarray:
    table = result.get(key) or {}
    return np.array([np.nan if table.get(n) is None else table[n] for n in names], dtype=float)


def parameter_changes(result: Mapping[str, Any]) -> Any:
    """Change of every identified parameter from its start, with ±2 standard errors (bars)
    and ±2 Cramér–Rao σ (ticks); ``result`` is ``IdentificationResult.to_dict()``."""
    names = list(result.get("names") or result["parameters"])
    change = _values(result, "parameters", names) - _values(result, "start", names)
    err, crb = _values(result, "stderr", names), _values(result, "bound", names)
    fig, panels = parameter_axes(names, [unit_of(result, n) for n in names])
    for ax, idx, scale, unit in panels:
        x = np.arange(len(idx))
        ax.axhline(0, color="0.6", lw=0.8)
        ax.errorbar(
            x,
            change[idx] * scale,
            yerr=2 * err[idx] * scale,
            fmt="o",
            ms=3,
            capsize=2,
            color="C0",
            label="identified change ± 2 std. errors",
        )
        if np.isfinite(crb[idx]).any():
            ax.errorbar(
                x,
                change[idx] * scale,
                yerr=2 * crb[idx] * scale,
                fmt="none",
                capsize=5,
                elinewidth=0,
                color="C3",
                label="± 2 Cramér–Rao σ",
            )
        ax.set_ylabel(f"change ({unit})")
    panels[0][0].legend(loc="upper left", bbox_to_anchor=(0, -0.28), ncol=2, fontsize=8, frameon=False)
    fig.suptitle(
        f"Identified parameter changes ({plain(result.get('method', ''))}, {result.get('poses', '?')} poses)"
    )
    return fig


def parameter_errors_figure(data: Mapping[str, Any]) -> Any:
    """Like the paper's Fig. 10: the mean absolute error of each of the 42 parameters over
    the trials, before and after calibration (log scale).

    ``data`` is :func:`hexcal.report.paper_figure_data`: bars ``before``, ``interior`` and
    ``boundary`` (42,), mm; ``trials``; an optional ``note`` (:func:`conditions`) below.
    """
    names = PARAMETER_NAMES[:42]
    series = (
        ("before", "before calibration", {"color": "0.65"}),
        (
            "interior",
            "after: 15 interior poses",
            {"color": "C1", "hatch": "//", "edgecolor": "white", "lw": 0},
        ),
        ("boundary", "after: 15 corners", {"color": "C0"}),
    )
    fig, panels = parameter_axes(names, PARAMETER_UNITS[:42], height=4.5, per_name=0.24, base=3.0)
    for ax, idx, scale, unit in panels:
        x = np.arange(len(idx))
        for k, (key, label, style) in enumerate(series):
            ax.bar(x + (k - 1) * 0.27, np.asarray(data[key])[idx] * scale, 0.27, label=label, **style)
        ax.set_ylabel(f"mean absolute parameter error ({unit})")
        ax.set_yscale("log")
        log_ticks(ax)
    trials = int(data["trials"])
    panels[0][0].set_title(
        f"Identified parameter errors (mean over {trials} trial{'' if trials == 1 else 's'})"
    )
    legend_outside(panels[-1][0])
    note(fig, data.get("note", ""))
    return fig


def plot_parameter_errors(data: Mapping[str, Any], path: str | os.PathLike[str]) -> None:
    """:func:`parameter_errors_figure` written as a PNG file."""
    save_png(parameter_errors_figure(data), path)


def correlation(names: Sequence[str], matrix: Any) -> Any:
    """Correlation heat map on the fixed scale −1 to 1, its parameters grouped by block
    (base joints, platform joints, l0, gains, the instrument's): thin lines between blocks,
    block names above, every parameter's name beside (every k-th beyond 80)."""
    corr = np.asarray(matrix, dtype=float)
    n = len(names)
    # about 11 pt per parameter up to 80 of them, so that 9 pt names stay apart
    size = float(np.clip(2.2 + 0.155 * min(n, 80), 5.0, 14.5))
    fig, ax = plt.subplots(figsize=(size + 1.4, size))
    image = ax.imshow(corr, cmap="RdBu_r", vmin=-1, vmax=1, interpolation="nearest")
    step = max(1, math.ceil(n / 80))
    font = 9.0
    labels = [plain(name) for name in names][::step]
    ax.set_xticks(range(0, n, step), labels, rotation=90, fontsize=font)
    ax.set_yticks(range(0, n, step), labels, fontsize=font)
    groups = blocks(names)
    if len(groups) > 1:
        for _, _, stop in groups[:-1]:
            ax.axhline(stop - 0.5, color="0.15", lw=0.7)
            ax.axvline(stop - 0.5, color="0.15", lw=0.7)
        for label, start, stop in groups:
            # centred over its block; on two lines where the block is narrower than the name
            wrapped = label if (stop - start) * 1.6 >= len(label) else label.replace(" ", "\n")
            ax.text(
                (start + stop - 1) / 2,
                1.01,
                plain(wrapped),
                transform=ax.get_xaxis_transform(),
                ha="center",
                va="bottom",
                fontsize=8.5,
                linespacing=1.0,
            )
    fig.colorbar(image, ax=ax, shrink=0.8, label="correlation", ticks=np.linspace(-1, 1, 9))
    ax.set_title(f"Parameter correlations ({n} parameters, by block)", pad=30 if len(groups) > 1 else 6)
    return fig


def singular_values(values: Sequence[float], threshold: float) -> Any:
    """Singular values of the column-normalised Jacobian relative to the largest, with the
    rank threshold."""
    sv = np.asarray(values, dtype=float)
    rel = sv / sv[0]
    fig, ax = plt.subplots(figsize=(7, 3.6))
    ax.semilogy(np.arange(1, rel.size + 1), rel, "o-", ms=3, label="σ / σmax")
    ax.axhline(threshold, ls="--", color="C3", lw=1, label=f"rank threshold {threshold:g}")
    ax.set_xlabel("singular value (largest first)")
    ax.set_ylabel("σ / σmax (column-normalised)")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title("Singular values of the identification Jacobian")
    return fig
