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

from browser_support import open_report, screenshot
from hexcal.calibration import estimate, validate
from hexcal.core.noise import NoiseModel
from hexcal.core.presets import preset
from hexcal.core.workspace import workspace_corners
from hexcal.instruments.pose import Measurements
from hexcal.report import identification_report, render_html, validation_report
from hexcal.simulation import simulate_measurements
from test_report_pages import hostile_pages, tracker_identify_page

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
    path.write_text(render_html(identification_report(result, inputs)), encoding="utf-8")
    return path


def test_report_is_self_contained(identify_page: Path) -> None:
    text = identify_page.read_text(encoding="utf-8")
    # nothing that a browser would fetch: no external sources, links or imports
    assert not re.search(r'(src|href)="(https?:)?//', text)
    assert "@import" not in text and "<link" not in text
    assert text.count("<svg") == 5


def test_identify_page_in_the_browser(browser, identify_page: Path) -> None:
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
                    "#parameters tbody tr td:nth-child(5)",  # parameter, unit, nominal, identified, change
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


def test_validation_page_in_the_browser(browser, tmp_path: Path, data: Measurements) -> None:
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


# -- paper and simulate: the tables and figures the commands already make ------------------------


@pytest.fixture(scope="module")
def command_pages(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """``hexcal paper --html`` and ``hexcal simulate --html`` (few trials, one process)."""
    from hexcal.cli.main import main

    folder = tmp_path_factory.mktemp("commands")
    pages = {"paper": folder / "paper.html", "simulate": folder / "simulate.html"}
    common = ["--trials", "2", "--jobs", "1", "--quiet", "--seed", "3"]
    assert main(["paper", *common, "--out", str(folder / "paper"), "--html", str(pages["paper"])]) == 0
    study = ["--poses", "7,15", "--methods", "paper,ml", "--noise-levels", "1,2"]
    assert main(["simulate", *common, *study, "--html", str(pages["simulate"])]) == 0
    poses = folder / "selected.csv"
    pages |= {"select": folder / "select.html", "observability": folder / "observability.html"}
    assert (
        main(["select", "--geometry", "paper-hmt", "--out", str(poses), "--html", str(pages["select"])]) == 0
    )
    observe = ["observability", "--geometry", "paper-hmt", "--poses", str(poses)]
    assert main([*observe, "--html", str(pages["observability"])]) == 0
    return pages


@pytest.mark.parametrize(
    ("name", "figures", "table", "rows"),
    [
        ("paper", 2, "table-i-mean-absolute-error-of-the-42-parameters-mm", 5),
        ("simulate", 1, "study-parameter-error-mm-and-pose-errors-per-campaign", 16),
        ("select", 1, "selected-poses", 15),
        ("observability", 2, "predicted-standard-deviation-per-parameter", 42),
    ],
)
def test_command_page_in_the_browser(
    browser,
    command_pages: dict[str, Path],
    name: str,
    figures: int,
    table: str,
    rows: int,
) -> None:
    text = command_pages[name].read_text(encoding="utf-8")
    assert not re.search(r'(src|href)="(https?:)?//', text) and "<link" not in text
    if name in ("paper", "simulate"):  # the conditions, on the page and on every figure
        assert text.count("2 trials · seed 3") >= 1 + figures
    opened = open_report(browser, command_pages[name])
    page = opened.page
    try:
        assert opened.blocked == [] and opened.console_errors == [] and opened.page_errors == []
        drawn = page.locator("figure svg")
        assert drawn.count() == figures
        for k in range(figures):
            box = drawn.nth(k).bounding_box()
            assert box is not None and box["width"] > 400 and box["height"] > 150
            # something is drawn in it: paths of the data, not only an empty frame
            assert drawn.nth(k).locator("path").count() > 20
        body = page.locator(f"#{table} tbody tr")
        assert body.count() == rows
        header = page.locator(f"#{table} th").nth(1)  # a numeric column, or noise of the study
        header.click()
        header.click()
        assert header.get_attribute("aria-sort") == "descending"
        values = page.eval_on_selector_all(
            f"#{table} tbody tr td:nth-child(2)", "cells => cells.map(c => c.dataset.value ?? c.textContent)"
        )
        numeric = None if name == "simulate" else [float(v) for v in values]
        if numeric is not None:
            assert numeric == sorted(numeric, reverse=True)
        else:
            assert values == sorted(values, reverse=True)
        assert page.locator("#inputs").get_by_text("hexcal version").count() == 1
        shot = screenshot(opened, f"{name}-report")
        assert shot.stat().st_size > 10_000
    finally:
        page.context.close()


def test_html_target_refused_up_front(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from hexcal.cli.main import main

    out = tmp_path / "paper"
    out.mkdir()
    clash = out / "table1.json"
    clash.write_text("{}", encoding="utf-8")  # an earlier run's output: left as it is
    assert main(["paper", "--trials", "1", "--out", str(out), "--html", str(clash)]) == 1
    assert "is also another output" in capsys.readouterr().err
    assert clash.read_text(encoding="utf-8") == "{}" and sorted(out.iterdir()) == [clash]
    assert main(["simulate", "--trials", "1", "--html", str(tmp_path / "no" / "x.html")]) == 1
    assert not (tmp_path / "no").exists()


# -- pages a person reads (tests/test_report_pages.py builds them) ------------------------------


@pytest.mark.slow  # fast: test_report_pages.py::test_hostile_ids_and_names_are_escaped_on_the_pages
def test_hostile_pages_in_the_browser(browser, tmp_path: Path) -> None:
    """Pose ids like ``<img src=x onerror=...>`` and a geometry named ``<script>...``: no
    dialog, no image, no error; the page shows them as text."""
    paths, _ = hostile_pages(tmp_path)
    for name, path in paths.items():
        opened = open_report(browser, path)
        dialogs: list[str] = []
        opened.page.on("dialog", lambda dialog, seen=dialogs: seen.append(dialog.message))
        try:
            opened.page.reload(wait_until="load")
            assert not dialogs and opened.console_errors == [] and opened.page_errors == []
            assert opened.page.locator("img").count() == 0
            assert opened.page.get_by_text('<img src=x onerror="alert(1)">', exact=False).count() > 0
            screenshot(opened, f"hostile-{name}-report")
        finally:
            opened.page.context.close()


@pytest.mark.slow  # fast: test_identify_page_in_the_browser, test_report_pages.py's tracker page
def test_tracker_identify_page_in_the_browser(browser, tmp_path: Path) -> None:
    """A tracker campaign's identify page: sessions, the setup in degrees, every figure drawn."""
    opened = open_report(browser, tracker_identify_page(tmp_path))
    page = opened.page
    try:
        assert opened.blocked == [] and opened.console_errors == [] and opened.page_errors == []
        assert page.locator("#sessions tbody tr").count() == 1
        assert page.locator("#setup-1 tbody tr").count() == 15  # frame and three targets
        figures = page.locator("figure svg")
        assert figures.count() == 5
        for k in range(figures.count()):
            box = figures.nth(k).bounding_box()
            assert box is not None and box["width"] > 400 and box["height"] > 150
        screenshot(opened, "tracker-identify-report")
    finally:
        page.context.close()
