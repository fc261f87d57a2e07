"""The ISO page and text from plain dictionaries: hostile text from inputs (pose ids) is
escaped on the page and printable in the text; the page holds the polar plot, the table of
the circular test and every pose visited twice."""

from __future__ import annotations

import numpy as np
import pytest

from hexcal.calibration import circular_test, pose_statistics
from hexcal.report import iso_dict, iso_report, iso_text, render_html

HOSTILE = '<script>alert("x")</script>\u2028'


def test_hostile_ids_are_escaped_and_printable():
    commanded = np.zeros((4, 6))
    attained = np.zeros((4, 6))
    attained[:, 0] = [0.0, 0.002, 0.004, 0.010]
    stats = pose_statistics(commanded, attained, [0, 0, 0, 1], ids=(HOSTILE, "b", "c", "d"))
    data = iso_dict(None, {"calibrated": stats}, tolerance=0.01)
    page = render_html(iso_report(data, inputs={"command": HOSTILE}))
    assert "<script>alert" not in page and "&lt;script&gt;" in page
    text = iso_text(data)
    assert "\u2028" not in text and "visited more than once" in text
    # pose "d" is visited once: left out of the table, said so
    assert "1 visited once left out" in text


def test_the_circle_page_has_its_plot_and_table():
    t = np.radians(np.r_[np.arange(0, 360, 10.0), np.arange(360, 0, -10.0)])
    q = 100 * np.column_stack([np.cos(t), np.sin(t)])
    dev = 0.003 * np.cos(2 * t) + np.r_[np.full(36, 0.001), np.full(36, -0.001)]
    tests = {"nominal": circular_test(q, 10 * dev), "calibrated": circular_test(q, dev)}
    data = iso_dict(tests, None, instrument="a ball bar")
    page = render_html(iso_report(data))
    assert 'data-figure="polar"' in page and "µm/div" in page and 'id="iso230-4-table"' in page
    assert "before (nominal)" in page and "after (calibrated)" in page
    # H = 0.002 after (the runs 2 µm apart), 0.02 before: in µm in the text
    assert tests["calibrated"].hysteresis == pytest.approx(0.002)
    line = next(x for x in iso_text(data).splitlines() if "hysteresis" in x)
    assert line.split()[-2:] == ["20", "2"]
