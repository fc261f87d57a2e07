"""Load time of the HTML calibration report of a 10,000-pose identification (issue 13).

Run ``python benchmarks/html_report.py`` (``--poses N`` for another size). It identifies the
parameters of paper-hmt from N random poses measured on paper-hmt-true (maximum likelihood,
the paper's noise, a few poses bumped to be outliers), renders the ``identify --html`` page
and opens it in headless Chromium from ``file://`` (every other request blocked). Printed
for the large report and for a 40-pose baseline built and opened in the same run: the page
size, the build time, the ``page.goto`` duration (until the ``load`` event) and the
navigation timing (``loadEventEnd - navigationStart``), and the ratio of the large page's
load time to the baseline's. The target is a load under 2 s for 10,000 poses.

Needs Chromium and Playwright, like the browser tests (``tests/browser_support.py``).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from browser_support import CHROMIUM_ARGS, chromium_path
from hexcal.calibration import estimate
from hexcal.core.noise import NoiseModel
from hexcal.core.presets import preset
from hexcal.core.workspace import random_poses
from hexcal.instruments.pose import Measurements
from hexcal.report import identification_report, render_html
from hexcal.simulation import simulate_measurements

SEED = 20261130
NOISE = NoiseModel(0.01, 0.025, 0.001)


def build(n: int, folder: Path) -> tuple[Path, float]:
    """The identify page of ``n`` poses, written to ``folder``; and its build time (s)."""
    nominal, true = preset("paper-hmt"), preset("paper-hmt-true")
    measured = simulate_measurements(nominal, true, random_poses(nominal, n, SEED), NOISE, SEED + 1)
    poses = measured.poses.copy()
    poses[:: max(n // 5, 1), 0] += 3.0  # a few gross errors: outliers to mark
    data = Measurements(poses, measured.readings, measured.ids)
    start = time.perf_counter()
    result = estimate(nominal, data, "ml", noise=NOISE, robust=True)
    fit = time.perf_counter() - start
    start = time.perf_counter()
    text = render_html(identification_report(result, {"hexcal": "benchmark", "poses": n}))
    built = time.perf_counter() - start
    path = folder / f"identify-{n}.html"
    path.write_text(text, encoding="utf-8")
    print(f"  {n} poses: identification {fit:.1f} s, report built in {built:.2f} s")
    return path, built


def load(browser: object, path: Path, repeats: int = 3) -> tuple[float, float]:
    """Best of ``repeats``: ``page.goto`` seconds and navigation-timing milliseconds."""
    best_goto, best_nav = float("inf"), float("inf")
    for _ in range(repeats):
        context = browser.new_context(viewport={"width": 1366, "height": 900})
        page = context.new_page()
        page.route("**/*", lambda r: r.continue_() if r.request.url.startswith("file://") else r.abort())
        start = time.perf_counter()
        page.goto(path.resolve().as_uri(), wait_until="load")
        goto = time.perf_counter() - start
        nav = page.evaluate("() => performance.timing.loadEventEnd - performance.timing.navigationStart")
        context.close()
        best_goto, best_nav = min(best_goto, goto), min(best_nav, float(nav))
    return best_goto, best_nav


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=10_000)
    args = parser.parse_args()
    exe = chromium_path()
    if exe is None:
        sys.exit("no Chromium: apt-get install chromium && pip install playwright")
    from playwright.sync_api import sync_playwright

    print(f"HTML report load time (load average {os.getloadavg()[0]:.1f})")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        pages = {n: build(n, folder) for n in (40, args.poses)}
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=exe, args=CHROMIUM_ARGS)
            times = {n: load(browser, path) for n, (path, _) in pages.items()}
            browser.close()
        for n, (path, _) in pages.items():
            goto, nav = times[n]
            size = path.stat().st_size / 1e6
            print(f"  {n:>6} poses: page {size:.2f} MB, load (goto) {goto:.2f} s, navigation {nav:.0f} ms")
    ratio = times[args.poses][0] / times[40][0]
    verdict = "under" if times[args.poses][0] < 2.0 else "OVER"
    print(f"  load time {args.poses} poses / 40 poses: {ratio:.2f}; {verdict} the 2 s target")
    assert np.isfinite(ratio)


if __name__ == "__main__":
    main()
