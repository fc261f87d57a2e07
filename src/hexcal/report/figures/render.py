"""A figure, once described, drawn to PNG (a file) or to SVG (text for an HTML page).

Every figure function of :mod:`hexcal.report.figures` returns a matplotlib ``Figure``;
:func:`save_png` writes it through the command's output set, :func:`svg` returns it as
inline SVG. Both close it. Also the conventions every figure shares: the conditions line
below it (:func:`conditions`, :func:`note`), legends off the data, round ticks, and
:func:`plain`, through which every text built from an input (a geometry's name, ids)
passes, so that a ``$`` is drawn as a dollar sign and not parsed as mathtext.
"""

from __future__ import annotations

import io
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.ticker import LogFormatterSciNotation, MaxNLocator

from hexcal.core.text import printable_lines
from hexcal.report.staging import staged_path

#: Above this many points a scatter or line layer is rasterised inside the SVG.
RASTER_POINTS = 1500

#: The resolution of PNG files (dots per inch).
PNG_DPI = 120


def save_png(fig: Any, path: str | os.PathLike[str]) -> None:
    """Write the figure to ``path`` (PNG, or the format its suffix names) through the
    command's output set, committed with its other outputs; the figure is closed."""
    try:
        with staged_path(path) as tmp:
            fig.savefig(tmp, dpi=PNG_DPI, bbox_inches="tight", format=Path(path).suffix[1:] or "png")
    finally:
        plt.close(fig)


def svg(fig: Any) -> str:
    """The figure as SVG text; the figure is closed."""
    buffer = io.StringIO()
    # text stays text (the browser draws it): ten times faster and smaller than glyph paths
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        fig.savefig(buffer, format="svg", bbox_inches="tight")
    plt.close(fig)
    return buffer.getvalue()


def plain(text: Any) -> str:
    """Text from an input, safe to draw: every ``$`` escaped (no mathtext).

    >>> plain("rig $1$")
    'rig \\\\$1\\\\$'
    """
    return printable_lines(text).replace("$", r"\$")


def note(fig: Any, text: str) -> None:
    """The conditions of a figure (amplitude, noise, trials) as a text line below it."""
    if text:
        fig.text(0.5, -0.01, plain(text), ha="center", va="top", fontsize=8, color="0.25")


def legend_outside(ax: Any, fontsize: float = 8, **options: Any) -> None:
    """The legend right of the axes, off the data."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=fontsize, frameon=False, **options)


class PlainLogFormatter(LogFormatterSciNotation):
    """Log-axis labels as plain numbers (0.2, 0.3, 1) over at most three decades, where
    matplotlib would write 2×10⁻¹; powers of ten beyond."""

    def __call__(self, x: float, pos: int | None = None) -> str:
        text = super().__call__(x, pos)
        lo, hi = sorted(abs(v) for v in self.axis.get_view_interval())
        if text and lo > 0 and hi / lo <= 1e3 and 1e-4 <= x < 1e5:
            return f"{x:g}"
        return text


def log_ticks(ax: Any, which: str = "y") -> None:
    """Plain-number labels on the logarithmic ``which`` axis of ``ax`` (see
    :class:`PlainLogFormatter`)."""
    axis = ax.yaxis if which == "y" else ax.xaxis
    axis.set_major_formatter(PlainLogFormatter())
    axis.set_minor_formatter(PlainLogFormatter(labelOnlyBase=False, minor_thresholds=(1, 0.4)))


def round_levels(lo: float, hi: float, count: int = 12) -> Any:
    """About ``count`` contour levels on round numbers covering ``[lo, hi]`` (colour-bar
    ticks like 0.45, 0.46, not 0.45283).

    >>> [round(float(v), 6) for v in round_levels(0.4528, 0.6029, 8)]
    [0.44, 0.46, 0.48, 0.5, 0.52, 0.54, 0.56, 0.58, 0.6, 0.62]
    """
    if not hi > lo:
        hi = lo + max(abs(lo) * 1e-6, 1e-12)
    return MaxNLocator(count, steps=[1, 2, 2.5, 5, 10]).tick_values(lo, hi)


def trials_phrase(trials: int) -> str:
    """``1 trial``, ``100 trials``."""
    return f"{trials} trial{'' if trials == 1 else 's'}"


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
        parts.append(trials_phrase(trials))
    if seed is not None:
        parts.append(f"seed {seed}")
    return " · ".join(parts)


def one_trial(text: str, trials: int) -> str:
    """The conditions line of a figure that shows one trial of ``trials``: says so.

    >>> one_trial("noise x1 · 100 trials · seed 0", 100)
    'noise x1 · the first of 100 trials · seed 0'
    """
    if trials == 1:
        return text
    phrase = trials_phrase(trials)
    shown = f"the first of {phrase}"
    return text.replace(phrase, shown) if phrase in text else " · ".join(p for p in (text, shown) if p)
