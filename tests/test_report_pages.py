"""The HTML pages a person reads (issue 22, "Reports a person reads"), through the command
line (``hexcal ... --html``) and the renderers: the verdict's failures first, the user's
options only, the noise as its own rows, sessions and setups in degrees, validate in mrad,
the selection criterion in words and units, hostile ids and names escaped and ``$`` drawn."""

from __future__ import annotations

import html
import json
import re
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from hexcal.calibration import estimate, validate
from hexcal.cli.main import main
from hexcal.core import NoiseModel, preset, workspace_corners
from hexcal.instruments.pose import Measurements
from hexcal.report import identification_report, render, render_html, validation_report
from hexcal.simulation import simulate_measurements

TRUE_SETUP = """units: mm
instrument_frame: {x: 2500, y: -800, z: 300, a_deg: 2, b_deg: -3, c_deg: 35}
targets:
  t1: [0, 0, 60]
  t2: [150, 20, 55]
  t3: [-40, 160, 70]
"""
START_SETUP = """units: mm
instrument_frame: auto
targets:
  t1: [1, -1, 61]
  t2: [149, 21, 54]
  t3: [-41, 158, 71]
"""
NOISE = ["--noise", "leg=0.01,pos=0.025,ang=0.001"]


class Tables(HTMLParser):
    """Every table of a page: ``{id or heading: [[cell text, ...], ...]}`` (header row first)."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: dict[str, list[list[str]]] = {}
        self._heading = ""
        self._in_heading = False
        self._rows: list[list[str]] | None = None
        self._cell: list[str] | None = None

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag in ("h2", "h3"):
            self._in_heading, self._heading = True, ""
        elif tag == "table":
            self._rows = []
            self.tables[dict(attrs).get("id") or self._heading] = self._rows
        elif tag == "tr" and self._rows is not None:
            self._rows.append([])
        elif tag in ("td", "th") and self._rows is not None:
            self._cell = []

    def handle_endtag(self, tag: str) -> None:
        if tag in ("h2", "h3"):
            self._in_heading = False
        elif tag == "table":
            self._rows = None
        elif tag in ("td", "th") and self._cell is not None and self._rows is not None:
            self._rows[-1].append("".join(self._cell).strip())
            self._cell = None

    def handle_data(self, data: str) -> None:
        if self._in_heading:
            self._heading += data
        if self._cell is not None:
            self._cell.append(data)


def tables(path: Path) -> dict[str, list[list[str]]]:
    parser = Tables()
    parser.feed(path.read_text(encoding="utf-8"))
    return parser.tables


def column(table: list[list[str]], name: str) -> dict[str, str]:
    """``{first cell: cell of column name}`` of a table."""
    k = table[0].index(name)
    return {row[0]: row[k] for row in table[1:]}


def run(*argv: object) -> None:
    assert main([str(a) for a in argv]) == 0


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Full-pose files: 30 poses to identify, 12 held out."""
    d = tmp_path_factory.mktemp("pages")
    for name, n, seed in (("cal", 30, 1), ("val", 12, 2)):
        run("candidates", "--geometry", "paper-hmt", "--candidates", f"random:{n}", "--seed", seed,
            "--out", d / f"{name}_poses.csv")  # fmt: skip
    for name, seed in (("cal", 1), ("val", 2)):
        run("synthesize", "--nominal", "paper-hmt", "--true", "paper-hmt-true", "--poses",
            d / f"{name}_poses.csv", *NOISE, "--seed", seed, "--out", d / f"{name}.csv")  # fmt: skip
    return d


@pytest.fixture(scope="module")
def identify_page(campaign: Path) -> Path:
    d = campaign
    run("identify", "--geometry", "paper-hmt", "--data", d / "cal.csv", "--out", d / "cal.yaml",
        "--json", d / "cal.json", "--html", d / "identify.html")  # fmt: skip
    return d / "identify.html"


@pytest.fixture(scope="module")
def tracker_page(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tracker_identify_page(tmp_path_factory.mktemp("tracker"))


# -- the verdict and the inputs ------------------------------------------------------------------------


def test_identify_page_lists_failures_then_warnings_then_info() -> None:
    reasons = [
        {"severity": "info", "message": "first info"},
        {"severity": "warn", "message": "a warning <script>alert(1)</script>"},
        {"severity": "info", "message": "second info"},
        {"severity": "fail", "message": "the failure"},
    ]
    result = {
        "method": "ml",
        "poses": 3,
        "names": [],
        "parameters": {},
        "verdict": "fail",
        "reasons": reasons,
    }
    page = render("identification", {"result": result, "figures": {}, "inputs": {}}, "html")
    listed = re.findall(r'<li class="(\w+)"[^>]*>([^<]*)</li>', page)
    assert [s for s, _ in listed] == ["fail", "warn", "info", "info"]
    assert [m for _, m in listed][2:] == ["first info", "second info"]  # each kind in its order
    assert "<script>alert" not in page and "&lt;script&gt;alert(1)&lt;/script&gt;" in page


def test_inputs_show_the_users_options_not_the_commands_internals(
    identify_page: Path, campaign: Path
) -> None:
    rows = {row[0]: row[1] for row in tables(identify_page)["Inputs"] if len(row) == 2}
    options = rows["options (defaults included)"]
    assert f"--data {campaign / 'cal.csv'}" in options and "--geometry paper-hmt" in options
    for internal in ("folders", "outputs", "inputs", "noise_dist", "noise-dist"):
        assert internal not in options, internal
    d = campaign
    run("identify", "--geometry", "paper-hmt", "--data", d / "cal.csv", "--out", d / "given.yaml",
        *NOISE, "--noise-dist", "normal", "--html", d / "given.html")  # fmt: skip
    given = {row[0]: row[1] for row in tables(campaign / "given.html")["Inputs"] if len(row) == 2}
    assert "--noise leg=0.01,pos=0.025,ang=0.001" in given["options (defaults included)"]
    assert "--noise-dist normal" in given["options (defaults included)"]  # given: the user's choice


# -- the noise, the sessions, degrees ---------------------------------------------------------------------


def test_identify_page_shows_the_noise_of_every_group(identify_page: Path, campaign: Path) -> None:
    noise = tables(identify_page)["noise"]
    learned = json.loads((campaign / "cal.json").read_text())["noise"]["groups"]
    assert (
        [row[1] for row in noise[1:]] == [g["label"] for g in learned] == ["leg", "position", "orientation"]
    )
    for row, group in zip(noise[1:], learned, strict=True):
        scale, unit = (1e3, "mrad") if group["unit"] == "rad" else (1.0, "mm")
        assert float(row[2]) == pytest.approx(group["sigma"] * scale, rel=1e-3) and row[4] == unit
        assert row[5] == (
            "learned from the data" if group["estimated"] else "not learned: too few data (start value kept)"
        )
    run("identify", "--geometry", "paper-hmt", "--data", campaign / "cal.csv", "--out", campaign / "g.yaml",
        *NOISE, "--html", campaign / "g.html")  # fmt: skip
    given = tables(campaign / "g.html")["noise"]
    assert given[0][:3] == ["group", "given σ", "σ the data show"]
    assert {row[0] for row in given[1:]} == {"leg", "position", "orientation"}
    assert all(row[-1] in ("agrees", "disagrees") for row in given[1:])


def test_tracker_page_sessions_and_setup_angles_in_degrees(tracker_page: Path) -> None:
    page = tables(tracker_page)
    body = json.loads((tracker_page.parent / "track.json").read_text())
    session = body["sessions"][0]
    sessions = page["sessions"]
    assert sessions[1][1] == session["description"] and sessions[1][2] == "40"
    assert sessions[1][3].startswith("auto: registered from 120 points, residual RMS")
    assert "12 combinations no data can determine" in tracker_page.read_text(encoding="utf-8")
    setup = {row[0]: row[1:] for row in page["setup-1"][1:]}
    params = {row[0]: row[1:] for row in page["parameters"][1:]}
    for name in ("frame.a", "frame.b", "frame.c"):
        value, err = session["setup"][name]["value"], session["setup"][name]["stderr"]
        assert setup[name][2] == "deg" and params[name][0] == "deg"
        assert float(setup[name][0]) == pytest.approx(np.degrees(value), rel=1e-5)
        assert float(setup[name][1]) == pytest.approx(np.degrees(err), rel=1e-5)
        # identified, deg, shown to two significant digits of its standard error (half a unit
        # of the last digit shown is under a tenth of the error)
        assert float(params[name][2]) == pytest.approx(np.degrees(value), abs=np.degrees(err) / 10)
    assert setup["t1.x"][2] == "mm" and params["u1.x"][0] == "mm"
    # the learned noise: the groups the instrument has (no orientation for targets)
    assert [row[1] for row in page["noise"][1:]] == ["leg", "targets"]
    # the text report: one unit for an angle in both of its tables
    text = (tracker_page.parent / "track.txt").read_text()
    calibrated = next(
        ln for ln in text.split("[[Calibrated setup]]")[1].splitlines() if ln.split()[:1] == ["frame.c"]
    )
    listed = next(ln for ln in text.split("[[Parameters]]")[1].splitlines() if ln.split()[:1] == ["frame.c"])
    assert float(calibrated.split()[1]) == pytest.approx(float(listed.split()[2]), abs=1e-6)
    assert listed.split()[-1] == "deg" and 30 < float(listed.split()[2]) < 40


# -- validate ---------------------------------------------------------------------------------------------


def test_validate_page_and_text_in_mrad_like_the_figures(campaign: Path, identify_page: Path) -> None:
    d = campaign
    argv = ["validate", "--geometry", d / "cal.yaml", "--data", d / "val.csv", "--nominal", "paper-hmt"]
    run(*argv, "--html", d / "validate.html", "--out", d / "validate.csv")
    page = tables(d / "validate.html")
    summary = {row[0]: row[1:] for row in page["summary-table"][1:]}
    assert "orientation error RMS (mrad)" in summary and not any("(rad)" in k for k in summary)
    per_pose = page["poses"]
    assert per_pose[0] == ["pose", "calibrated position (mm)", "calibrated orientation (mrad)",
                           "nominal position (mm)", "nominal orientation (mrad)"]  # fmt: skip
    csv = {ln.split(",")[0]: ln.split(",") for ln in (d / "validate.csv").read_text().splitlines()[2:]}
    first = per_pose[1]
    assert float(first[2]) == pytest.approx(float(csv[first[0]][3]) * 1e3, rel=1e-5)  # rad in the CSV
    text = validate_text(argv)
    assert "orientation error RMS (mrad)" in text and "(rad)" not in text
    rms = float(next(ln for ln in text.splitlines() if "orientation error RMS" in ln).split()[-2])
    assert rms == pytest.approx(float(summary["orientation error RMS (mrad)"][0]), rel=1e-3)


def validate_text(argv: list[object]) -> str:
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        run(*argv)
    return out.getvalue()


# -- planning -----------------------------------------------------------------------------------------------


def test_select_and_observability_pages_say_what_their_numbers_are(campaign: Path) -> None:
    d = campaign
    run(
        "select",
        "--geometry",
        "paper-hmt",
        "--out",
        d / "sel.csv",
        "--json",
        d / "sel.json",
        "--html",
        d / "sel.html",
    )
    selection = {row[0]: row[1] for row in tables(d / "sel.html")["selection"][1:]}
    data = json.loads((d / "sel.json").read_text())
    assert (
        selection["criterion"].startswith("A-optimal: the smallest trace(F⁻¹)")
        and "mm²" in selection["criterion"]
    )
    assert selection["criterion of the selected poses"] == f"trace(F⁻¹) = {-data['value']:.4g} mm²"
    assert selection["criterion after the greedy start (before the exchanges)"].endswith("mm²")
    text = (d / "sel.html").read_text(encoding="utf-8")
    assert "greedy_value" not in text and f"{data['value']:.6g}" not in text  # no bare, negated number
    run(
        "observability", "--geometry", "paper-hmt", "--poses", d / "sel.csv", *NOISE, "--html", d / "obs.html"
    )
    noise = tables(d / "obs.html")["noise-assumed"]
    assert [row[:2] for row in noise[1:]] == [["leg", "half-width ±0.01"], ["position", "half-width ±0.025"],
                                              ["orientation", "half-width ±0.001"]]  # fmt: skip
    assert float(noise[1][2]) == pytest.approx(0.01 / np.sqrt(3), rel=1e-5)


# -- studies and hostile names ------------------------------------------------------------------------------


def test_a_dollar_in_a_geometry_name_and_one_pose_count(tmp_path: Path) -> None:
    """``simulate`` and ``paper`` with a true machine named ``rig $\\foo$``: the figure notes
    carry the name (matplotlib raised on it); one pose count is a per-campaign chart; Fig. 11
    says it draws the first trial of two."""
    geometry = tmp_path / "rig.yaml"
    run("preset", "paper-hmt-true", "--out", geometry)
    text = geometry.read_text().replace("name: paper-hmt-true", "name: 'rig $\\foo$ <b>'")
    geometry.write_text(text)
    common = ["--true", geometry, "--trials", "2", "--jobs", "1", "--quiet", "--seed", "3"]
    run("simulate", *common, "--poses", "15", "--methods", "ml", "--strategies", "corners",
        "--out", tmp_path / "sim", "--html", tmp_path / "sim.html")  # fmt: skip
    page = (tmp_path / "sim.html").read_text(encoding="utf-8")
    assert "true machine rig $\\foo$ &lt;b&gt;" in page and "<b>" not in page
    assert "Calibration campaigns of 15 poses" in page
    conditions = {row[0]: row[1] for row in tables(tmp_path / "sim.html")["conditions"][1:]}
    assert conditions["true machine"] == "rig $\\foo$ <b>"  # text, as typed
    assert conditions["noise: leg"] == "σ 0.005774 mm" and conditions["noise: orientation"].endswith("rad")
    assert (tmp_path / "sim" / "study.png").stat().st_size > 10_000
    run("paper", *common, "--out", tmp_path / "paper", "--html", tmp_path / "paper.html")
    conditions = {row[0]: row[1] for row in tables(tmp_path / "paper.html")["conditions"][1:]}
    assert conditions["noise: position"] == "uniform ±0.025 mm, σ 0.01443 mm" and conditions["trials"] == "2"
    figure = re.search(
        r'data-figure="fig11_validation_errors".*?</figure>', (tmp_path / "paper.html").read_text(), re.S
    )
    assert figure and "the first of 2 trials" in figure.group(0) and "· 2 trials ·" not in figure.group(0)


HOSTILE = '<img src=x onerror="alert(1)">'


def hostile_pages(folder: Path) -> tuple[dict[str, Path], object]:
    """The identify and validate pages of 30 poses with hostile ids (one an outlier) and a
    geometry named ``<script>...</script> $\\foo$``, written to ``folder``; and the result."""
    nominal, true = preset("paper-hmt"), preset("paper-hmt-true")
    measured = simulate_measurements(nominal, true, workspace_corners(nominal)[:30], NoiseModel(), 5)
    ids = tuple(f"{HOSTILE}{k}" if k % 7 == 0 else f"p&{k}" for k in range(30))
    poses = measured.poses.copy()
    poses[7, 0] += 3.0  # a gross error: its id is listed as an outlier
    data = Measurements(poses, measured.readings, ids)
    start = nominal.replace(name="<script>alert(2)</script> $\\foo$")
    result = estimate(start, data, "ml", robust=True)
    pages = {
        "identify": render_html(identification_report(result, {"command": f"hexcal {HOSTILE}"})),
        "validate": render_html(validation_report({"calibrated": validate(result.geometry, data)})),
    }
    paths = {}
    for name, page in pages.items():
        paths[name] = folder / f"hostile-{name}.html"
        paths[name].write_text(page, encoding="utf-8")
    return paths, result


def test_hostile_ids_and_names_are_escaped_on_the_pages(tmp_path: Path) -> None:
    """(Opened in Chromium by ``test_html_report.test_hostile_pages_in_the_browser``.)"""
    paths, result = hostile_pages(tmp_path)
    pages = {name: path.read_text(encoding="utf-8") for name, path in paths.items()}
    for name, page in pages.items():
        assert "<script>alert" not in page and "<img src=x" not in page, name
        assert "&lt;img src=x onerror=&quot;alert(1)&quot;&gt;" in page, name
    assert "&lt;script&gt;alert(2)&lt;/script&gt; $\\foo$" in pages["identify"]  # the title, as text
    assert result.outliers and all(html.escape(i) in pages["identify"] for i in result.outliers)
    assert "p&amp;8" in pages["validate"]  # every id of the per-pose table, escaped


def tracker_identify_page(folder: Path) -> Path:
    """``hexcal identify --html`` of a simulated tracker campaign (40 poses, three targets,
    the instrument frame unknown), written to ``folder``."""
    d = folder
    (d / "true.yaml").write_text(TRUE_SETUP)
    (d / "start.yaml").write_text(START_SETUP)
    run("candidates", "--geometry", "paper-hmt", "--candidates", "random:40", "--seed", 3,
        "--out", d / "track_poses.csv")  # fmt: skip
    run("synthesize", "--nominal", "paper-hmt", "--true", "paper-hmt-true", "--poses", d / "track_poses.csv",
        "--setup", d / "true.yaml", "--noise", "leg=0.005,pos=0.015", "--noise-dist", "normal",
        "--seed", 4, "--out", d / "track.csv")  # fmt: skip
    run("identify", "--geometry", "paper-hmt", "--setup", d / "start.yaml", "--data", d / "track.csv",
        "--out", d / "track.yaml", "--setup-out", d / "track-setup.yaml", "--json", d / "track.json",
        "--report", d / "track.txt", "--html", d / "track.html", "--force")  # fmt: skip
    return d / "track.html"


def test_text_reports_load_no_figure_code() -> None:
    """The pages' modules (and matplotlib) load only when a page is rendered."""
    import subprocess
    import sys

    code = (
        "import sys; from hexcal.report import render\n"
        "s = dict(poses=3, leg_rms=0.01, leg_max=0.02, position_rms=0.1, position_max=0.2,"
        " orientation_rms=1e-5, orientation_max=2e-5)\n"
        "render('validation', {'calibrated': s}); render('study', [], 'json')\n"
        "loaded = ('matplotlib', 'numpy', 'hexcal.report.calibration_pages')\n"
        "print(sorted(m for m in loaded if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
