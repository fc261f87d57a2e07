"""Figures a person reads (issue 22, "Reports a person reads"): every pose visible, both
geometries' error distributions visible, readable correlation labels, round colour-bar
ticks, a one-count study drawn with its bound, Fig. 11 saying it is one trial, and no
mathtext from an input's ``$``."""

from __future__ import annotations

import math

import matplotlib.pyplot as plt
import numpy as np
import pytest

from hexcal.core import PARAMETER_NAMES, preset
from hexcal.design import error_maps
from hexcal.report import (
    correlation,
    plot_study,
    svg,
    validation_distributions,
    workspace_poses,
)
from hexcal.report.figures import error_angles_figure, study_figure, validation_errors_figure

BOX = np.array([[-250, 250], [-250, 250], [700, 900], *[[-np.pi / 18, np.pi / 18]] * 3], dtype=float)


def _texts(fig: plt.Figure) -> str:
    return " ".join(t.get_text() for t in fig.findobj(plt.Text))


def corner_grid_poses() -> np.ndarray:
    """15 poses on the corners and centre of a grid, as ``hexcal select`` picks them: many
    share their x–y position (different z) and their a–b angles (different c)."""
    rows = [
        (-250, -250, 700, -1, -1, 1), (-250, 0, 900, 1, 1, 1), (250, 250, 700, 1, -1, 1),
        (-250, 250, 700, 1, -1, -1), (250, -250, 900, 1, -1, -1), (250, -250, 900, -1, 1, 1),
        (-250, 250, 700, -1, 1, 1), (0, 0, 700, -1, -1, 1), (0, 0, 700, 1, -1, 1),
        (-250, 250, 700, -1, -1, 1), (-250, -250, 900, -1, -1, -1), (-250, -250, 700, 1, 1, -1),
        (250, -250, 700, 1, 1, 1), (0, 0, 700, -1, 1, -1), (250, 250, 900, -1, 1, -1),
    ]  # fmt: skip
    poses = np.array(rows, dtype=float)
    poses[:, 3:] *= np.pi / 18
    return poses


def test_workspace_plot_shows_every_pose() -> None:
    """30 (here 15) poses on a grid overplotted into 7 dots: now one marker per pose in each
    projection (a ring per pose at a shared place) and the count beside."""
    poses = corner_grid_poses()
    fig = workspace_poses(poses, BOX, "Selected poses")
    fig.canvas.draw()
    panels = [ax for ax in fig.axes if ax.get_xlabel() in ("x (mm)", "a (deg)")]
    assert len(panels) == 2
    for ax in panels:
        markers = {
            (round(float(x), 6), round(float(y), 6), round(float(s), 3))
            for coll in ax.collections
            for (x, y), s in zip(
                coll.get_offsets(), np.broadcast_to(coll.get_sizes(), len(coll.get_offsets())), strict=True
            )
        }
        assert len(markers) == len(poses)  # no two poses drawn as one marker
        counts = [t.get_text() for t in ax.texts if t.get_text().startswith("×")]
        assert counts and sum(int(c[1:]) for c in counts) <= len(poses)  # ×3 beside three rings
    assert "15 poses" in fig._suptitle.get_text()
    plt.close(fig)


def test_validation_histograms_show_both_geometries() -> None:
    """Calibrated errors of micrometres beside nominal ones of tens of millimetres: shared
    linear bins collapsed the calibrated ones into one bar; log bins show both shapes."""
    rng = np.random.default_rng(0)
    errors = {
        "calibrated": {
            "position_error": rng.uniform(0.005, 0.05, 40),
            "orientation_error": rng.uniform(2e-4, 2e-3, 40),
        },
        "nominal": {
            "position_error": rng.uniform(35, 55, 40),
            "orientation_error": rng.uniform(0.08, 0.11, 40),
        },
    }
    fig = validation_distributions(errors)
    fig.canvas.draw()
    for ax in (a for a in fig.axes if a.patches):
        for patch in ax.patches:
            vertices = patch.get_path().vertices
            heights = vertices[:, 1]
            # the bins with poses: each geometry spreads over several of them
            filled = {round(x, 12) for x, h in vertices if h > 0}
            assert heights.max() < 40 and len(filled) >= 6, patch.get_label()
    plt.close(fig)


def test_correlation_labels_are_readable() -> None:
    """48 parameters: every name at 9 pt, at least one font height apart, and the blocks
    (joints, l0, gains) separated and named."""
    names = list(PARAMETER_NAMES)
    matrix = np.eye(48) + 0.3 * np.random.default_rng(1).uniform(-1, 1, (48, 48))
    fig = correlation(names, (matrix + matrix.T) / 2)
    fig.canvas.draw()
    ax = fig.axes[0]
    labels = [t for t in ax.get_yticklabels() if t.get_text()]
    assert [t.get_text() for t in labels] == names
    assert min(t.get_fontsize() for t in labels) >= 8
    points = fig.dpi / 72
    y = sorted(t.get_window_extent().y0 for t in labels)
    assert min(np.diff(y)) / points >= labels[0].get_fontsize()  # names do not overlap
    text = _texts(fig)
    assert all(block in text for block in ("base joints", "platform joints", "l0", "gains"))
    plt.close(fig)


def _round_step(levels: np.ndarray) -> bool:
    step = float(np.median(np.diff(levels)))
    mantissa = step / 10 ** math.floor(math.log10(step))
    multiples = levels / step
    return any(abs(mantissa - m) < 1e-6 for m in (1, 2, 2.5, 5)) and np.allclose(
        multiples, np.round(multiples)
    )


def test_colour_bar_ticks_are_round() -> None:
    """The error-map colour bars said 0.4528, 0.4743, ...: levels on round numbers."""
    maps = error_maps(preset("paper-hmt"), levels=3, points=3, grid=5, draws=4, amplitude=0.1, rng=0)
    fig = error_angles_figure(maps.angles["a-b"], "parameter errors ±0.1 mm")
    fig.canvas.draw()
    filled = [c for ax in fig.axes for c in ax.collections if hasattr(c, "levels") and c.filled]
    assert filled
    for contour in filled:
        assert _round_step(np.asarray(contour.levels))
    colorbars = [ax for ax in fig.axes if ax.get_ylabel().endswith("error (mm)") or "mrad" in ax.get_ylabel()]
    for bar in colorbars:
        for tick in bar.get_yticklabels():
            if tick.get_text():
                assert len(tick.get_text().replace("−", "-").lstrip("-").replace(".", "").strip("0")) <= 3
    plt.close(fig)


def _study_rows(counts: tuple[int, ...]) -> list[dict]:
    return [
        {"strategy": s, "noise": "x1", "method": m, "poses": p, "error_mean": e / p, "error_std": 0.1 * e / p,
         "bound": 0.8 * e / p, "failures": 0}
        for s, e in (("corners", 3.0), ("interior", 6.0))
        for m in ("ml", "paper")
        for p in counts
    ]  # fmt: skip


def test_one_count_study_is_a_chart_per_campaign_with_its_bound(tmp_path) -> None:
    """``simulate --poses 30`` drew an x axis from 28.5 to 31.5 with no bound in sight."""
    rows = _study_rows((30,))
    fig = study_figure(rows, "noise x1 · 2 trials · seed 3")
    fig.canvas.draw()
    ax = fig.axes[0]
    ticks = [t.get_text() for t in ax.get_xticklabels()]
    assert len(ticks) == 4 and all("noise x1" in t for t in ticks)
    assert any(t.startswith("corners") for t in ticks) and any(t.startswith("interior") for t in ticks)
    bounds = sorted({r["bound"] for r in rows})
    drawn = [
        line for line in ax.get_lines() if len(line.get_xdata()) == 2 and len(set(line.get_ydata())) == 1
    ]
    assert sorted({float(line.get_ydata()[0]) for line in drawn}) == pytest.approx(bounds)
    assert all(line.get_linewidth() >= 2 for line in drawn)  # a visible bar, not a lone point
    assert "30 poses" in ax.get_title()
    plt.close(fig)
    several = study_figure(_study_rows((15, 30)))
    assert several.axes[0].get_xlabel() == "number of measurement poses"
    plt.close(several)
    plot_study(rows, tmp_path / "study.png")
    assert (tmp_path / "study.png").read_bytes()[:4] == b"\x89PNG"


def test_fig11_says_it_is_one_trial_of_the_study() -> None:
    """Fig. 11 draws the first trial; its footer said "100 trials"."""
    data = {
        "trials": 100,
        "validation_before": {"position": np.full(10, 40.0), "orientation": np.full(10, 0.09)},
        "validation_after": {"position": np.full(10, 0.2), "orientation": np.full(10, 1e-3)},
        "note": "parameter errors ±5 mm · noise x1 · 100 trials · seed 0",
    }
    fig = validation_errors_figure(data)
    text = _texts(fig)
    assert "the first of 100 trials" in text and "· 100 trials ·" not in text
    plt.close(fig)
    data["trials"], data["note"] = 1, "noise x1 · 1 trial · seed 0"
    fig = validation_errors_figure(data)
    assert "noise x1 · 1 trial · seed 0" in _texts(fig)
    plt.close(fig)


def test_a_dollar_in_an_input_is_drawn_as_a_dollar() -> None:
    """A geometry named ``rig $\\foo$`` broke every figure whose title or note carried it
    (matplotlib parsed it as mathtext and raised)."""
    name = r"rig $\foo$ <b>&"
    fig = study_figure(_study_rows((15, 30)), f"parameter errors: true machine {name} · 1 trial")
    text = svg(fig)  # draws it: raised ValueError (Unknown symbol: \foo) before
    assert "rig $\\foo$ &lt;b&gt;&amp;" in text
    fig = workspace_poses(corner_grid_poses(), BOX, f"Poses of {name}")
    assert "rig $\\foo$" in svg(fig)
