"""What reports show of poses and parameters (issue 31): per-pose plots name the poses by
their ids (not row numbers), and the HTML parameter table shows values to the precision of
their standard errors."""

from __future__ import annotations

from hexcal.report import data_table, parameter_rows


def _labels(ax) -> list[str]:
    ax.figure.canvas.draw()
    return [t.get_text() for t in ax.get_xticklabels() if t.get_text()]


def test_per_pose_plots_label_poses_by_their_ids() -> None:
    from hexcal.report.figures.poses import pose_residuals, validation_errors
    from hexcal.report.figures.render import plt

    ids = ["home", "left", "right", "g324"]
    fig = pose_residuals(ids, [1.0, 2.0, 3.0, 4.0], [0.1, 0.2, 0.3, 0.4])
    assert set(_labels(fig.axes[0])) <= set(ids) and "g324" in _labels(fig.axes[0])
    assert fig.axes[0].get_xlabel() == "measured pose (id)"
    plt.close(fig)
    errors = {"calibrated": {"position_error": [0.1, 0.2, 0.3, 0.4], "orientation_error": [1e-4] * 4}}
    fig = validation_errors(ids, errors)
    assert "right" in _labels(fig.axes[0]) and set(_labels(fig.axes[1])) <= set(ids)
    plt.close(fig)


def test_the_parameter_table_shows_values_to_the_precision_of_their_errors() -> None:
    """It showed 305.401234 ± 0.0123 (six significant digits, four of them noise)."""
    result = {
        "names": ["u1.x", "l0_1"],
        "parameters": {"u1.x": 305.401234567, "l0_1": 604.8652},
        "start": {"u1.x": 305.4, "l0_1": 604.8652},
        "stderr": {"u1.x": 0.0123, "l0_1": 0.0},
    }
    rows = parameter_rows(result)
    name, _, _, identified, change, error, _ = rows[0]
    assert (name, identified.text, change.text, error.text) == ("u1.x", "305.401", "0.001", "0.012")
    html = data_table(("parameter", "unit", "nominal", "identified", "change", "std. error", "bound"), rows)
    assert '<td data-value="305.401234567">305.401</td>' in html
    assert rows[1][3] == 604.8652  # no error to round to: the value as it is
