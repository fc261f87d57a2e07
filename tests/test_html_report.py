"""The HTML calibration report, rendered and used in a real browser (headless Chromium).

The page must load from ``file://`` with every network request blocked (none is made), log no
console error, show the verdict, the parameter table (sorted on a click) and every figure
with a non-empty drawing, and print. A screenshot of each page is kept as a test artefact
(``build/test-artifacts/``).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from browser_support import browser, open_report, screenshot  # noqa: F401  (fixture)
from hexcal.core.noise import NoiseModel
from hexcal.core.presets import preset
from hexcal.core.workspace import workspace_corners
from hexcal.estimation import estimate, validate
from hexcal.models.pose import Measurements
from hexcal.report.html_reports import identification_report, render_html, validation_report
from hexcal.simulation import simulate_measurements

NOMINAL, TRUE = preset("paper-hmt"), preset("paper-hmt-true")


@pytest.fixture(scope="module")
def data() -> Measurements:
    """40 corners of paper-hmt measured on paper-hmt-true, one pose bumped by 3 mm."""
    measured = simulate_measurements(NOMINAL, TRUE, workspace_corners(NOMINAL)[:40], NoiseModel(), 1)
    poses = measured.poses.copy()
    poses[7, 0] += 3.0
    return Measurements(poses, measured.readings, measured.ids)


@pytest.fixture(scope="module")
def identify_page(tmp_path_factory: pytest.TempPathFactory, data: Measurements) -> Path:
    result = estimate(NOMINAL, data, "ml", robust=True)
    inputs = {"files": [{"role": "data", "path": "measured.csv", "sha256": "0" * 64}], "hexcal": "test"}
    path = tmp_path_factory.mktemp("html") / "identify.html"
    path.write_text(render_html(identification_report(result, data, inputs)), encoding="utf-8")
    return path


def test_report_is_self_contained(identify_page: Path) -> None:
    text = identify_page.read_text(encoding="utf-8")
    # nothing that a browser would fetch: no external sources, links or imports
    assert not re.search(r'(src|href)="(https?:)?//', text)
    assert "@import" not in text and "<link" not in text
    assert text.count("<svg") == 5


def test_identify_page_in_the_browser(browser, identify_page: Path) -> None:  # noqa: F811
    opened = open_report(browser, identify_page)
    page = opened.page
    try:
        assert opened.blocked == [] and opened.console_errors == [] and opened.page_errors == []
        assert page.locator(".verdict").count() == 1
        # every figure is drawn with a non-empty size
        figures = page.locator("figure svg")
        assert figures.count() == 5
        for k in range(figures.count()):
            box = figures.nth(k).bounding_box()
            assert box is not None and box["width"] > 200 and box["height"] > 100
        # the parameter table: 42 rows, sorted by the clicked column, both ways
        rows = page.locator("#parameters tbody tr")
        assert rows.count() == 42
        header = page.locator("#parameters th", has_text="change")

        def column() -> np.ndarray:
            return np.array(
                page.eval_on_selector_all(
                    "#parameters tbody tr td:nth-child(4)",
                    "cells => cells.map(c => parseFloat(c.dataset.value))",
                )
            )

        header.click()
        assert np.all(np.diff(column()) >= 0)
        header.click()
        assert np.all(np.diff(column()) <= 0)
        assert page.locator("text=outliers removed (pose ids)").count() == 1
        shot = screenshot(opened, "identify-report")
        assert shot.stat().st_size > 10_000
        # printable: the print style sheet renders to a PDF of a few pages
        pdf = page.pdf(format="A4")
        assert pdf[:4] == b"%PDF" and len(pdf) > 10_000
    finally:
        page.context.close()


def test_validation_page_in_the_browser(browser, tmp_path: Path, data: Measurements) -> None:  # noqa: F811
    calibrated = estimate(NOMINAL, data, "ml", robust=True).geometry
    held_out = simulate_measurements(NOMINAL, TRUE, workspace_corners(NOMINAL)[40:], NoiseModel(), 2)
    report = validation_report(
        {"calibrated": validate(calibrated, held_out), "nominal": validate(NOMINAL, held_out)}
    )
    path = tmp_path / "validate.html"
    path.write_text(render_html(report), encoding="utf-8")
    opened = open_report(browser, path)
    try:
        assert opened.blocked == [] and opened.console_errors == [] and opened.page_errors == []
        assert opened.page.locator("figure svg").count() == 2
        assert opened.page.locator("#poses tbody tr").count() == 24
        screenshot(opened, "validate-report")
    finally:
        opened.page.context.close()
