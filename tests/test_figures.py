"""The figures answer an engineer's questions: units, legends off the data, shared colour
scales where panels are compared, the conditions written on them, distinct line styles."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest

from hexcal.core.presets import preset
from hexcal.design import error_maps
from hexcal.report.figures import (
    conditions,
    error_angles_figure,
    parameter_errors_figure,
    plot_parameter_errors,
    plot_study,
    study_figure,
    validation_errors_figure,
)

NOTE = conditions(7, {"leg": 0.01, "position": 0.025, "orientation": 0.001}, 5.0, 3)


def _texts(fig: plt.Figure) -> str:
    return " ".join(t.get_text() for t in fig.findobj(plt.Text))


def _legend_outside(ax: plt.Axes) -> bool:
    fig = ax.figure
    fig.canvas.draw()
    legend = ax.get_legend().get_window_extent()
    return legend.x0 >= ax.get_window_extent().x1


@pytest.fixture
def paper_data() -> dict:
    rng = np.random.default_rng(0)
    return {
        "trials": 7,
        "before": rng.uniform(1, 5, 42),
        "interior": rng.uniform(0.1, 1, 42),
        "boundary": rng.uniform(0.05, 0.5, 42),
        "validation_before": {"position": rng.uniform(10, 60, 10), "orientation": rng.uniform(0.05, 0.1, 10)},
        "validation_after": {"position": rng.uniform(0.1, 1, 10), "orientation": rng.uniform(1e-3, 3e-3, 10)},
        "note": NOTE,
    }


def test_conditions_line() -> None:
    assert NOTE == (
        "parameter errors ±5 mm · noise leg 0.01 mm, position 0.025 mm, orientation 0.001 rad"
        " · 7 trials · seed 3"
    )
    assert (
        conditions(amplitude="true machine paper-hmt-true") == "parameter errors: true machine paper-hmt-true"
    )


def test_paper_figures_carry_units_conditions_and_outside_legends(paper_data: dict, tmp_path: Path) -> None:
    for build, trials in (
        (parameter_errors_figure, "7 trials"),
        (validation_errors_figure, "the first of 7 trials"),
    ):
        fig = build(paper_data)
        text = _texts(fig)
        # Fig. 10 is the mean over the trials; Fig. 11 one trial of them, and says so
        assert NOTE.replace("7 trials", trials) in text
        axes = fig.axes
        assert all("(mm)" in ax.get_ylabel() or "(mrad)" in ax.get_ylabel() for ax in axes)
        with_legend = [ax for ax in axes if ax.get_legend() is not None]
        assert len(with_legend) == 1 and _legend_outside(with_legend[0])
        plt.close(fig)
    plot_parameter_errors(paper_data, tmp_path / "fig10.png")
    assert (tmp_path / "fig10.png").read_bytes()[:4] == b"\x89PNG"


def test_study_curves_differ_in_style_not_only_colour(tmp_path: Path) -> None:
    rows = [
        {"strategy": s, "noise": n, "method": m, "poses": p, "error_mean": 1.0 / p, "bound": 0.5 / p}
        for s in ("corners", "interior", "selected")
        for n in ("x0.5", "x1", "x2")
        for m in ("paper", "ml", "length", "gls")
        for p in (7, 15, 30)
    ]
    fig = study_figure(rows, NOTE)
    ax = fig.axes[0]
    curves = [line for line in ax.get_lines() if line.get_label().count(",") == 2]
    assert len(curves) == 36
    # the dash pattern itself (get_linestyle() names every custom pattern "--")
    looks = {(line.get_color(), str(line._unscaled_dash_pattern), line.get_marker()) for line in curves}
    assert len(looks) == 36  # every curve tells itself apart
    assert _legend_outside(ax) and NOTE in _texts(fig)
    assert "(mm)" in ax.get_ylabel()
    plt.close(fig)
    plot_study(rows, tmp_path / "study.png", NOTE)
    assert (tmp_path / "study.png").stat().st_size > 10_000


def test_error_map_rows_share_one_colour_scale() -> None:
    maps = error_maps(preset("paper-hmt"), levels=3, points=3, grid=5, draws=4, amplitude=0.1, rng=0)
    grid = maps.angles["a-b"]
    fig = error_angles_figure(grid, "parameter errors ±0.1 mm")
    panels = [ax for ax in fig.axes if ax.get_title().startswith("z =")]
    assert len(panels) == 4
    filled = [next(c for c in ax.collections if hasattr(c, "levels") and c.filled) for ax in panels]
    for row in (filled[:2], filled[2:]):
        np.testing.assert_array_equal(row[0].levels, row[1].levels)  # one scale per row
        lo, hi = row[0].levels[0], row[0].levels[-1]
        assert all(lo <= c.get_array().min() and c.get_array().max() <= hi for c in row)
    # the rows differ: position (mm) and orientation (mrad) have their own scales
    assert not np.array_equal(filled[0].levels, filled[2].levels)
    colorbars = [ax for ax in fig.axes if ax not in panels]
    assert len(colorbars) == 2 and {"position error (mm)", "orientation error (mrad)"} == {
        ax.get_ylabel() for ax in colorbars
    }
    assert "±0.1 mm" in _texts(fig)
    plt.close(fig)
