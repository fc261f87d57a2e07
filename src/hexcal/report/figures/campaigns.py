"""Figures of calibration campaigns: parameter error against the number of poses (the
simulate study, the selection study), or, for one pose count, per campaign.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from hexcal.report.figures.render import legend_outside, log_ticks, note, plain, plt, save_png

STYLES = ("-", "--", "-.", (0, (6, 2, 1, 2, 1, 2)))
MARKERS = ("o", "s", "^", "D", "v", "P")

#: The label of the Cramér–Rao bound in the study figures.
BOUND_LABEL = "Cramér–Rao bound (per strategy, noise)"


def _rows(rows: Sequence[Any]) -> list[Mapping[str, Any]]:
    return [r.row() if hasattr(r, "row") else r for r in rows]


def study_figure(rows: Sequence[Any], note_text: str = "") -> Any:
    """Mean absolute parameter error of every campaign of a study (``StudyCell.row()``
    dictionaries, or the cells) with the Cramér–Rao bounds.

    Against the number of poses when the study has several counts: colour per strategy,
    line style per method, marker per noise level, so that no two curves look alike; one
    count: a point per campaign (with its spread) and its bound as a bar, on a campaign axis.
    """
    rows = _rows(rows)
    if len({r["poses"] for r in rows}) == 1:
        return _one_count(rows, note_text)
    fig, ax = plt.subplots(figsize=(8, 5))
    strategies = sorted({r["strategy"] for r in rows})
    methods = sorted({r["method"] for r in rows})
    noises = sorted({r["noise"] for r in rows})
    for strategy, noise, method in sorted({(r["strategy"], r["noise"], r["method"]) for r in rows}):
        sel = sorted(
            (r for r in rows if (r["strategy"], r["noise"], r["method"]) == (strategy, noise, method)),
            key=lambda r: r["poses"],
        )
        ax.plot(
            [r["poses"] for r in sel],
            [r["error_mean"] for r in sel],
            color=f"C{strategies.index(strategy) % 10}",
            ls=STYLES[methods.index(method) % len(STYLES)],
            marker=MARKERS[noises.index(noise) % len(MARKERS)],
            label=plain(f"{strategy}, {method}, noise {noise}"),
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
    ax.plot([], [], color="0.3", ls=(0, (1, 2)), lw=1, label=BOUND_LABEL)
    counts = sorted({r["poses"] for r in rows})
    if len(counts) <= 12:
        ax.set_xticks(counts)  # the pose counts of the study, not 16, 18, ... between them
    ax.set_xlabel("number of measurement poses")
    ax.set_ylabel("mean absolute parameter error (mm)")
    ax.set_yscale("log")
    log_ticks(ax)
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title("Calibration campaigns: parameter error against pose count")
    legend_outside(ax, 7)
    note(fig, note_text)
    return fig


def _one_count(rows: list[Mapping[str, Any]], note_text: str) -> Any:
    """One pose count: each campaign at its own place, error ± its spread, bound as a bar."""
    cells = sorted(rows, key=lambda r: (r["strategy"], r["noise"], r["method"]))
    strategies = sorted({r["strategy"] for r in cells})
    x = np.arange(len(cells))
    fig, ax = plt.subplots(figsize=(max(5.5, 1.1 * len(cells) + 3), 4.6))
    for k, r in enumerate(cells):
        color = f"C{strategies.index(r['strategy']) % 10}"
        spread = r.get("error_std")
        ax.errorbar(
            k,
            r["error_mean"],
            yerr=None if spread is None else [[min(spread, 0.9 * r["error_mean"])], [spread]],
            fmt="o",
            ms=7,
            capsize=4,
            color=color,
        )
        ax.plot([k - 0.3, k + 0.3], [r["bound"], r["bound"]], color=color, lw=2.5, alpha=0.8)
    ax.plot([], [], "o", color="0.3", label="mean error ± std over the trials")
    ax.plot([], [], "-", lw=2.5, color="0.3", label="Cramér–Rao bound")
    ax.set_xticks(
        x, [plain(f"{r['strategy']}\n{r['method']}, noise {r['noise']}") for r in cells], fontsize=8
    )
    ax.set_xlim(-0.7, len(cells) - 0.3)
    ax.set_ylabel("mean absolute parameter error (mm)")
    ax.set_yscale("log")
    log_ticks(ax)
    ax.grid(True, axis="y", which="both", alpha=0.3)
    ax.set_title(f"Calibration campaigns of {cells[0]['poses']} poses: parameter error per campaign")
    legend_outside(ax, 8)
    note(fig, note_text)
    return fig


def plot_study(rows: Sequence[Any], path: str | os.PathLike[str], note: str = "") -> None:
    """:func:`study_figure` written as a PNG file (``note``: the conditions line)."""
    save_png(study_figure(rows, note), path)


def selection_study_figure(
    counts: Any,
    predicted: Mapping[str, Any],
    empirical: Mapping[str, tuple[Any, Any]],
    title: str = "",
    note_text: str = "",
) -> Any:
    """Mean parameter error against the number of measurement poses, per strategy.

    Parameters
    ----------
    counts : array_like, shape (k,)
        Numbers of poses of the predicted curves.
    predicted : dict of str to array_like, shape (k,)
        Predicted mean absolute parameter error (mm) per strategy (lines).
    empirical : dict of str to (array_like, array_like)
        Pose counts and Monte Carlo mean errors (markers), same keys.
    note_text : str
        The conditions (noise, trials; see :func:`conditions`), written below the figure.
    """
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for k, (label, values) in enumerate(predicted.items()):
        color = f"C{k}"
        ax.plot(counts, values, STYLES[k % len(STYLES)], color=color, label=plain(f"{label}: predicted"))
        if label in empirical:
            n, err = empirical[label]
            marker = MARKERS[k % len(MARKERS)]
            ax.plot(n, err, marker, color=color, mfc="none", label=plain(f"{label}: Monte Carlo"))
    ax.set_xlabel("number of measurement poses")
    ax.set_ylabel("mean absolute parameter error (mm)")
    ax.set_yscale("log")
    log_ticks(ax)
    ax.grid(True, which="both", alpha=0.3)
    legend_outside(ax)
    if title:
        ax.set_title(plain(title))
    note(fig, note_text)
    return fig


def plot_selection_study(
    counts: Any,
    predicted: Mapping[str, Any],
    empirical: Mapping[str, tuple[Any, Any]],
    path: str | os.PathLike[str],
    title: str = "",
    note: str = "",
) -> None:
    """:func:`selection_study_figure` written as a PNG file."""
    save_png(selection_study_figure(counts, predicted, empirical, title, note), path)
