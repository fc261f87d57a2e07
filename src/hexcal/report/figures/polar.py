"""The polar plot of an ISO 230-4 circular test: the usual look of a ballbar report.

Each panel shows one geometry's test (before and after calibration side by side): the
nominal circle (bold), the radial deviation of the counterclockwise run (solid) and of the
clockwise run (dashed), magnified: the radius drawn is the nominal circle's plus the
deviation at the scale stated above the panel (µm per division of the radial grid). As
ballbar software does, each panel has its own scale by default (the calibrated machine's
deviations are often a hundred times smaller), or one scale for all. Angles counterclockwise
from the plane's ``u`` axis, as in :mod:`hexcal.calibration.iso_tests`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from hexcal.report.figures.render import plain, plt, save_png

#: Divisions of the radial grid from the nominal circle to the rim (and to the centre).
DIVISIONS = 4

#: Style of each run: colour, line style, legend label.
RUN_STYLES = {"ccw": ("C0", "-", "CCW"), "cw": ("C3", "--", "CW")}


def nice_division(largest_um: float, divisions: int = DIVISIONS) -> float:
    """The scale, µm per division: the smallest 1, 2 or 5 times a power of ten with which
    the largest deviation stays inside ``divisions`` divisions (at least 0.1 µm).

    >>> nice_division(37.0), nice_division(0.0), nice_division(180.0)
    (10.0, 0.1, 50.0)
    """
    need = max(float(largest_um), 1e-9) / (divisions - 0.25)
    power = 10.0 ** math.floor(math.log10(need))
    for step in (1.0, 2.0, 5.0, 10.0):
        if step * power >= need:
            return max(step * power, 0.1)
    return max(10.0 * power, 0.1)


def _largest(tests: Mapping[str, Mapping[str, Any]]) -> float:
    """The largest radial deviation of the tests' runs, µm."""
    values = [
        abs(v)
        for test in tests.values()
        for name, run in test["runs"].items()
        if name != "both"
        for v in run["deviation_mm"]
    ]
    return 1e3 * max(values, default=0.0)


def polar_deviation(
    tests: Mapping[str, Mapping[str, Any]],
    labels: Mapping[str, str] | None = None,
    scale_um: float | None = None,
    shared: bool = False,
) -> Any:
    """Side-by-side polar plots of circular tests (``CircularTest.to_dict()`` by name): each
    at its own scale from its largest deviation (:func:`nice_division`), or all at one
    (``shared``, or ``scale_um`` µm per division given)."""
    labels = labels or {}
    common = scale_um or (nice_division(_largest(tests)) if shared else None)
    fig, axes = plt.subplots(
        1, len(tests), figsize=(5.4 * len(tests), 5.9), subplot_kw={"projection": "polar"}, squeeze=False
    )
    for ax, (name, test) in zip(axes[0], tests.items(), strict=True):
        scale = common or nice_division(_largest({name: test}))
        rim = 2 * DIVISIONS * scale
        circle = np.linspace(0, 2 * np.pi, 361)
        ax.plot(circle, np.full_like(circle, DIVISIONS * scale), color="0.15", lw=1.6, label="nominal circle")
        for run, (colour, style, label) in RUN_STYLES.items():
            if run not in test["runs"]:
                continue
            data = test["runs"][run]
            theta = np.radians(np.asarray(data["angles_deg"], dtype=float))
            r = DIVISIONS * scale + 1e3 * np.asarray(data["deviation_mm"], dtype=float)
            ax.plot(theta, np.clip(r, 0, rim), color=colour, ls=style, lw=1.3, label=label)
        ax.set_ylim(0, rim)
        ticks = np.arange(1, 2 * DIVISIONS) * scale
        ax.set_yticks(ticks)
        offsets = np.round(ticks / scale) * scale - DIVISIONS * scale  # µm from the nominal circle
        ax.set_yticklabels([f"{v:+g}" if v else "0" for v in offsets], fontsize=7, color="0.35")
        ax.set_rlabel_position(100)
        ax.set_xticks(np.radians(np.arange(0, 360, 45)))
        ax.tick_params(axis="x", labelsize=8)
        ax.grid(True, color="0.8", lw=0.6)
        ax.set_title(f"{plain(labels.get(name, name))}\n{scale:g} µm/div", fontsize=10, pad=14)
        runs = test["runs"]
        lines = [f"radius {test['nominal_radius_mm']:.4g} mm"]
        for run in ("ccw", "cw"):
            if run in runs:
                lines.append(f"G {RUN_STYLES[run][2]} {1e3 * runs[run]['circular_deviation_mm']:.3g} µm")
        if test.get("circular_hysteresis_mm") is not None:
            lines.append(f"H {1e3 * test['circular_hysteresis_mm']:.3g} µm")
        ax.text(0.5, -0.1, " · ".join(lines), transform=ax.transAxes, ha="center", va="top", fontsize=8)
    axes[0][-1].legend(loc="upper left", bbox_to_anchor=(0.92, 1.08), fontsize=8, frameon=False)
    fig.tight_layout()
    return fig


def plot_polar_deviation(
    tests: Mapping[str, Mapping[str, Any]],
    path: str | os.PathLike[str],
    labels: Mapping[str, str] | None = None,
    scale_um: float | None = None,
) -> None:
    """:func:`polar_deviation` written as a PNG file (through the command's output set)."""
    save_png(polar_deviation(tests, labels, scale_um), path)
