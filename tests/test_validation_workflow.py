"""One validation workflow (issue 29): ``hexcal.validate`` in Python and ``hexcal validate`` on
the command line give the same figures, the same JSON and the same per-pose table on the same
files, for every instrument kind and both ISO tests; every report of a validation (text, JSON,
HTML, the per-pose table, a notebook's view) says the same figures; the planning reports say
the noise and the instrument they assumed.

The campaigns are tests/instrument_campaigns.py's (the seed paper's machine ``paper-hmt``,
the real one ``paper-hmt-true``, each instrument simulated by ``hexcal synthesize``), held out
(20 poses, the ballbar's 7 other points on each of its 30 circles). Validation there is of the
real machine itself, through the setup the user starts from (its frame ``auto``: re-registered
on the session, 5 folds), beside the nominal machine; what the calibration expected needs a
calibrated geometry, so one campaign (three targets) is identified first. Figures are compared
exactly (the same library call on the same files), or to the rounding the text prints them
with.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import hexcal
from hexcal.errors import HexcalError, UsageError
from hexcal.report import json_text
from instrument_campaigns import INSTRUMENTS, Campaigns, identify, read_csv, run

KINDS = list(INSTRUMENTS)


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory: pytest.TempPathFactory) -> Campaigns:
    return Campaigns(tmp_path_factory.mktemp("validation-workflow"))


def _setup_path(campaigns: Campaigns, kind: str) -> Path | None:
    option = campaigns.setup(kind)
    return Path(option[1]) if option else None


def _python(campaigns: Campaigns, kind: str, geometry: Any = "paper-hmt-true", setup: Any = None, **options):
    """``hexcal.validate`` of the held-out campaign of ``kind``, from the files, as Python reads them."""
    calibrated = hexcal.load_geometry(geometry)
    setups = [s for s in [setup or _setup_path(campaigns, kind)] if s]
    sessions = hexcal.read_sessions([campaigns.data(kind, "held")], setups, calibrated.euler)
    return hexcal.validate(calibrated, sessions, **options)


def _command(campaigns: Campaigns, kind: str, stem: str, *extra: Any, geometry: Any = "paper-hmt-true",
             setup: Any = None):  # fmt: skip
    """``hexcal validate`` of the same files with ``--json``, ``--out`` and ``--html``."""
    root = campaigns.root
    files = {k: root / f"{stem}.{k}" for k in ("json", "csv", "html")}
    option = ["--setup", setup] if setup else campaigns.setup(kind)
    done = run("validate", "--geometry", geometry, "--data", campaigns.data(kind, "held"), *option,
               "--json", files["json"], "--out", files["csv"], "--html", files["html"], *extra)  # fmt: skip
    assert done.code == 0, done.err
    return done, files


def _same_json(python: Any, written: Path) -> None:
    """The command's JSON is the Python result's ``to_dict()`` (its inputs aside: the command
    records its files, options and the date)."""
    mine = json.loads(json_text(python.to_dict()))
    theirs = json.loads(written.read_text())
    assert set(mine) == set(theirs)
    assert theirs["inputs"]["command"] == "hexcal validate" and mine["inputs"] == {}
    mine.pop("inputs"), theirs.pop("inputs")
    assert mine == theirs


def _printed(out: str) -> str:
    """The report the command printed (its lines before ``wrote ...``)."""
    return "\n".join(line for line in out.splitlines() if not line.startswith("wrote "))


#: The kinds validated beside the nominal machine too (it costs a second validation each).
BESIDE_NOMINAL = ("pose", "targets")


@pytest.mark.parametrize("kind", KINDS)
def test_python_and_the_command_line_give_the_same_validation(campaigns: Campaigns, kind: str) -> None:
    beside = kind in BESIDE_NOMINAL
    done, files = _command(campaigns, kind, f"{kind}-cli", *(("--nominal", "paper-hmt") if beside else ()))
    python = _python(campaigns, kind, nominal=hexcal.load_geometry("paper-hmt") if beside else None)
    _same_json(python, files["json"])
    assert _printed(done.out) == python.report()
    # the per-pose table: the same columns and cells (empty where a value does not exist)
    columns, rows, ids, _ = python.table()
    _, header, body = read_csv(files["csv"])
    assert header == ["id", *columns] and [r[0] for r in body] == ids
    cells = np.array([[float(c) if c else np.nan for c in r[1:]] for r in body])
    np.testing.assert_allclose(cells, rows, rtol=1e-12, equal_nan=True)
    data = python.to_dict()
    own = {"target": "instrument_target_rms_mm", "ballbar": "instrument_bar_rms_mm"}
    own = own.get(kind, "position_rms_mm")
    # the free frame (a target's, a tool's, a ballbar's pivot) re-registered on the session: the
    # real machine then predicts the held-out data to about the noise (σ 15 µm; a ballbar 1 µm)
    if INSTRUMENTS[kind].start_setup is not None:
        assert data["registration"]["folds"] == 5
    assert 0 < data[own] < 0.1, data[own]
    if beside:  # the nominal machine misses by millimetres, its frame re-registered too
        assert data["nominal"][own] > 1.0
        if INSTRUMENTS[kind].start_setup is not None:
            assert data["nominal"]["registration"]["folds"] == 5


@pytest.fixture(scope="module")
def circle_files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A ball bar's circle measured on tests/test_iso_cli.py's machine (the seed paper's, its
    joints and l0 off by up to 0.5 mm) and that machine's geometry (standing in for a
    calibrated one): the files of ``hexcal validate --iso230-4``."""
    from hexcal.instruments import BallbarModel, BallbarSetup
    from hexcal.simulation import simulate_session
    from test_iso_cli import BALL, NOISE, PIVOT, RADIUS, circle_poses, machines

    folder = tmp_path_factory.mktemp("circle")
    nominal, true = machines()
    bar = BallbarModel(BallbarSetup(PIVOT, BALL, RADIUS, fixed=("pivot", "ball", "length")))
    session = simulate_session(nominal, true, bar, circle_poses(6.0), NOISE, 3)
    hexcal.write_session_data(folder / "circle.csv", session, nominal.euler)
    setup = f"units: mm\nballbar: {{pivot: {PIVOT}, ball: {BALL}, length: {RADIUS}}}\n"
    (folder / "ballbar.yaml").write_text(setup + "fixed: [pivot, ball, length]\n")
    hexcal.save_geometry(true, folder / "machine.yaml")
    return {"data": folder / "circle.csv", "setup": folder / "ballbar.yaml",
            "geometry": folder / "machine.yaml"}  # fmt: skip


@pytest.fixture(scope="module")
def circle(circle_files: dict[str, Path]) -> Any:
    """The ISO 230-4 circular test of that circle, from Python."""
    geometry = hexcal.load_geometry(circle_files["geometry"])
    session = hexcal.read_session(circle_files["data"], circle_files["setup"], geometry.euler)
    return hexcal.validate(geometry, session, nominal=hexcal.load_geometry("paper-hmt"), iso230_4=True)


def test_the_circular_test_is_the_same_from_python_and_the_command_line(circle_files, circle) -> None:
    folder = circle_files["data"].parent
    polar, target = folder / "polar.png", folder / "iso230.json"
    done = run("validate", "--geometry", circle_files["geometry"], "--nominal", "paper-hmt", "--data",
               circle_files["data"], "--setup", circle_files["setup"], "--iso230-4", "--polar", polar,
               "--json", target)  # fmt: skip
    assert done.code == 0, done.err
    python = circle
    _same_json(python, target)
    assert _printed(done.out) == python.report()
    data = python.to_dict()
    assert set(data["iso"]["iso230_4"]) == {"nominal", "calibrated"}
    assert "circular deviation G" in python.report() and polar.stat().st_size > 10_000
    python.save_polar(folder / "polar-python.png")  # the same figure, from Python
    assert (folder / "polar-python.png").stat().st_size > 10_000


@pytest.fixture(scope="module")
def visits(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Five poses of the real machine visited six times each, measured as full poses."""
    from hexcal.simulation import simulate_session

    nominal, real = hexcal.preset("paper-hmt"), hexcal.preset("paper-hmt-true")
    poses = np.tile(hexcal.random_poses(nominal, 5, 7), (6, 1))
    noise = hexcal.NoiseModel(0.001, 0.001, 1e-6, distribution="normal")
    path = tmp_path_factory.mktemp("visits") / "visits.csv"
    hexcal.write_session_data(path, simulate_session(nominal, real, None, poses, noise, rng=4), nominal.euler)
    return path


def test_the_pose_figures_are_the_same_from_python_and_the_command_line(visits: Path, capsys) -> None:
    from hexcal.cli.main import main

    target = visits.parent / "iso9283.json"
    argv = ["validate", "--geometry", "paper-hmt-true", "--nominal", "paper-hmt", "--data", str(visits),
            "--iso9283", "--visit-tolerance", "0.005", "--json", str(target)]  # fmt: skip
    assert main(argv) == 0
    out = capsys.readouterr().out
    nominal = hexcal.load_geometry("paper-hmt")
    session = hexcal.read_session(visits, None, nominal.euler)
    real = hexcal.load_geometry("paper-hmt-true")
    python = hexcal.validate(real, session, nominal=nominal, iso9283=True, visit_tolerance=0.005)
    _same_json(python, target)
    assert _printed(out) == python.report()
    stats = python.to_dict()["iso"]["iso9283"]
    assert [p["visits"] for p in stats["calibrated"]["poses"]] == [6] * 5
    assert python.to_dict()["iso"]["visit_tolerance_mm"] == 0.005


# -- every report of one validation says the same figures ---------------------------------------


@pytest.fixture(scope="module")
def calibrated(campaigns: Campaigns) -> dict[str, Any]:
    """Three targets identified (``hexcal identify``, the geometry with its uncertainty and the
    calibrated setup), then validated on the held-out session beside the nominal machine."""
    done, files = identify(campaigns, "targets", campaigns.data("targets"), "targets-cal")
    assert done.code == 0, done.err
    run_done, outputs = _command(campaigns, "targets", "targets-val", "--nominal", "paper-hmt",
                                 geometry=files["out"], setup=files["setup-out"])  # fmt: skip
    data = json.loads(outputs["json"].read_text())
    return {"files": files, "run": run_done, "outputs": outputs, "data": data,
            "held": campaigns.data("targets", "held")}  # fmt: skip


def _table(page: str, table_id: str) -> list[list[str]]:
    """The cells of an HTML table, each a ``data-value`` where it has one, else its text."""
    body = re.search(rf'<table id="{table_id}".*?</table>', page, re.S).group(0)
    rows = []
    for row in re.findall(r"<tr>(.*?)</tr>", body, re.S):
        cells = []
        for attributes, text in re.findall(r"<t[dh]([^>]*)>(.*?)</t[dh]>", row, re.S):
            value = re.search(r'data-value="([^"]*)"', attributes)
            cells.append(value.group(1) if value else re.sub("<[^>]+>", "", text))
        rows.append(cells)
    return rows


def _text_figures(text: str) -> dict[str, list[float]]:
    """``label -> values`` of the rows of the printed summary table."""
    out = {}
    for line in text.splitlines():
        m = re.match(r"\s{4}(\S.*?\((?:mm|mrad)\))\s+([-+\d.e]+(?:\s+[-+\d.e]+)*)$", line)
        if m:
            out[m.group(1)] = [float(v) for v in m.group(2).split()]
    return out


def test_the_page_shows_the_figures_the_text_prints(calibrated: dict) -> None:
    text, page = calibrated["run"].out, calibrated["outputs"]["html"].read_text()
    figures = _text_figures(text)
    summary = {row[0]: [float(v) for v in row[1:]] for row in _table(page, "summary-table")[1:]}
    assert set(summary) == set(figures) and len(figures) >= 8
    for label, shown in figures.items():  # the page keeps more digits than the text's 4
        np.testing.assert_allclose(summary[label], shown, rtol=5e-4, err_msg=label)


def test_the_page_shows_what_the_calibration_expected_and_the_re_registration(calibrated: dict) -> None:
    data, text = calibrated["data"], calibrated["run"].out
    page = calibrated["outputs"]["html"].read_text()
    expected = data["expected"]
    assert expected["noise"] == "calibration"
    rows = {row[0]: row[1:] for row in _table(page, "expected-table")[1:]}
    for label, key, scale in (("position RMS (mm)", "position_rms_mm", 1.0),
                              ("orientation RMS (mrad)", "orientation_rms_rad", 1e3),
                              ("leg RMS (mm)", "leg_rms_mm", 1.0)):  # fmt: skip
        measured, predicted, ratio = (float(v) for v in rows[label][:3])
        assert measured == pytest.approx(data[key] * scale, rel=1e-12)
        assert predicted == pytest.approx(expected[key] * scale, rel=1e-12)
        assert ratio == pytest.approx(expected["measured_over_expected"][key], rel=1e-12)
    # the text says the same expectation and ratios, to its rounding
    said = re.search(r"measured / expected: position ([\d.]+), orientation ([\d.]+), legs ([\d.]+)", text)
    ratios = expected["measured_over_expected"]
    assert [float(v) for v in said.groups()] == pytest.approx(
        [ratios["position_rms_mm"], ratios["orientation_rms_rad"], ratios["leg_rms_mm"]], abs=0.005
    )
    assert f"position RMS {expected['position_rms_mm']:.3g} mm" in text
    # the re-registration: the text's sentence on the page, and the quantities it fitted
    sentence = next(line for line in text.splitlines() if line.startswith("Re-registered on this session"))
    assert f"<p>{sentence}.</p>" in page.replace("&#x27;", "'")
    registered = {row[0]: float(row[1]) for row in _table(page, "registration-table")[1:]}
    assert set(registered) == set(data["registration"]["quantities"])
    assert registered["frame.x"] == pytest.approx(data["registration"]["values"]["frame.x"], rel=1e-12)


def _key_values(page: str, section_id: str) -> dict[str, str]:
    """The rows of the labelled-values table of a page's section."""
    body = page.split(f'id="{section_id}"')[1].split("</section>")[0]
    return dict(re.findall(r"<tr><td>([^<]*)</td><td>([^<]*)</td></tr>", body))


def test_the_page_names_the_instrument_and_its_setup_files(calibrated: dict) -> None:
    page = calibrated["outputs"]["html"].read_text()
    conditions = _key_values(page, "conditions")
    assert conditions["instrument"] == calibrated["data"]["instrument"]
    assert conditions["held-out observations"] == "20"
    assert conditions["instrument setup"].startswith("re-registered on this session (frame, t1, t2, t3)")
    assert conditions["nominal geometry"] == "paper-hmt"
    inputs = page.split('id="inputs"')[1]
    for role in ("geometry", "data", "setup", "nominal"):
        assert f'<td class="text">{role}</td>' in inputs, role
    assert str(calibrated["files"]["setup-out"]) in inputs and str(calibrated["held"]) in inputs


def test_the_iso_page_shows_the_validation_the_text_prints(circle) -> None:
    python = circle
    page, text = python.html(), python.report()
    iso = python.to_dict()["iso"]["iso230_4"]
    table = {row[0]: [float(v) for v in row[1:]] for row in _table(page, "iso230-4-table")[1:]}
    g = iso["calibrated"]["runs"]["ccw"]["circular_deviation_mm"]
    assert table["circular deviation G, CCW (µm)"][1] == pytest.approx(1e3 * g, rel=1e-12)
    line = next(ln for ln in text.splitlines() if "circular deviation G, CCW" in ln)
    assert float(line.split()[-1]) == pytest.approx(1e3 * g, rel=5e-4)
    # beside the tests: the validation's summary, how the setup was taken (the bar's, fixed: as
    # given, no re-registration), as the text says it
    summary = {row[0]: [float(v) for v in row[1:]] for row in _table(page, "summary-table")[1:]}
    bar = python.to_dict()["instrument_bar_rms_mm"]
    assert summary["bar RMS (mm)"][1] == pytest.approx(bar, rel=1e-12)  # after (calibrated), as printed
    assert f"{bar:.4g}" in next(ln for ln in text.splitlines() if ln.strip().startswith("bar RMS (mm)"))
    assert "Re-registered on this session" not in text and 'id="registration"' not in page
    said = "after calibration: the setup as given (its quantities fixed"
    assert said in text and said.capitalize() in page
    assert _key_values(page, "conditions")["instrument setup"] == "as given (every quantity fixed)"


# -- a notebook shows them ------------------------------------------------------------------------


def test_a_validation_shows_itself_in_a_notebook(calibrated: dict) -> None:
    from hexcal.workflow import Validation

    files = calibrated["files"]
    geometry = hexcal.load_geometry(files["out"])
    sessions = hexcal.read_sessions([calibrated["held"]], [files["setup-out"]], geometry.euler)
    python = hexcal.validate(geometry, sessions, nominal=hexcal.load_geometry("paper-hmt"))
    assert isinstance(python, Validation)
    _same_json(python, calibrated["outputs"]["json"])  # the same as the command's, expectation included
    shown = python._repr_html_()
    assert shown.startswith("<div>") and "<html" not in shown and "<script" not in shown
    summary = {row[0]: [float(v) for v in row[1:]] for row in _table(shown, "summary-table")[1:]}
    assert summary["position error RMS (mm)"][0] == pytest.approx(python.to_dict()["position_rms_mm"])
    assert 'id="expected-table"' in shown and "Re-registered on this session" in shown
    assert "held-out observations" in repr(python)


def test_a_calibration_shows_itself_in_a_notebook() -> None:
    from hexcal.simulation import simulate_session

    nominal = hexcal.preset("paper-hmt")
    session = simulate_session(nominal, hexcal.preset("paper-hmt-true"), None,
                               hexcal.workspace_corners(nominal)[:30], rng=1)  # fmt: skip
    calibration = hexcal.calibrate(nominal, [session])
    shown = calibration._repr_html_()
    assert shown.startswith("<div>") and "<html" not in shown
    assert f'data-verdict="{calibration.status}"' in shown
    rows = {row[0]: row for row in _table(shown, "parameters")[1:]}
    assert set(rows) == set(calibration.names)
    assert float(rows["u1.x"][3]) == pytest.approx(calibration.parameters["u1.x"], rel=1e-12)
    # and its validation on the poses it has not seen takes the Calibration itself
    held = simulate_session(nominal, hexcal.preset("paper-hmt-true"), None,
                            hexcal.workspace_corners(nominal)[30:50], rng=2)  # fmt: skip
    check = hexcal.validate(calibration, held)
    assert check.geometry.name == calibration.geometry.name
    assert check.to_dict()["expected"]["noise"] == "calibration"


def test_the_calibration_page_shows_the_leg_model_choice_the_text_prints() -> None:
    """``leg_model="auto"`` on 30 full poses of the real machine (linear legs: the cross-validation
    keeps them or a stroke model within a standard error); the page's table of scores and the
    text's lines say the same figures."""
    from hexcal.report import identification_report, render_html
    from hexcal.simulation import simulate_session

    nominal = hexcal.preset("paper-hmt")
    noise = hexcal.NoiseModel(0.005, 0.015, 0.0002, distribution="normal")
    session = simulate_session(nominal, hexcal.preset("paper-hmt-true"), None,
                               hexcal.random_poses(nominal, 30, 1), noise, rng=1)  # fmt: skip
    calibration = hexcal.calibrate(nominal, [session], leg_model="auto")
    choice = calibration.to_dict()["leg_model_choice"]
    text = calibration.report()
    page = render_html(identification_report(calibration))
    rows = {row[0]: row[1:] for row in _table(page, "leg-model-scores")[1:]}
    assert set(rows) == {n + (" (chosen)" if n == choice["choice"] else "") for n in choice["scores"]}
    for name, score in choice["scores"].items():
        row = rows[name + (" (chosen)" if name == choice["choice"] else "")]
        assert float(row[0]) == pytest.approx(score["leg_rms_mm"], rel=1e-12)
        assert float(row[2]) == pytest.approx(1e3 * score["orientation_rms_rad"], rel=1e-12)
        line = next(ln for ln in text.splitlines() if ln.strip().startswith(f"{name} "))
        assert f"held-out leg RMS {score['leg_rms_mm']:.4g} mm" in line
        assert line.endswith("<- chosen") == (name == choice["choice"])
    chosen = f"leg model chosen by cross-validation ({choice['scheme']}): {calibration.leg_model}"
    assert chosen in text and calibration.leg_model in page


# -- refusals, in one line, from Python and the command line alike --------------------------------


@pytest.mark.parametrize(
    ("options", "argv", "message"),
    [
        ({"folds": 1}, ["--folds", "1"], "--folds must be at least 2, got 1"),
        ({"iso230_4": True, "iso9283": True}, ["--iso230-4", "--iso9283"], "need different instruments"),
        ({"visit_tolerance": 0.005}, ["--visit-tolerance", "0.005"], "give --iso9283"),
        ({"iso9283": True, "visit_tolerance": 1.0}, ["--iso9283", "--visit-tolerance", "1"], "joins"),
    ],
)
def test_options_that_cannot_act_are_refused_alike(campaigns: Campaigns, options, argv, message) -> None:
    session = hexcal.read_session(campaigns.data("pose", "held"), None, "XYZ")
    with pytest.raises(HexcalError, match=re.escape(message)):
        hexcal.validate(hexcal.preset("paper-hmt-true"), session, **options)
    target = campaigns.root / "refused.json"
    done = run("validate", "--geometry", "paper-hmt-true", "--data", campaigns.data("pose", "held"),
               *argv, "--json", target)  # fmt: skip
    assert done.code == 1 and done.err.count("\n") == 1 and message in done.err
    assert not target.exists()


def test_several_sessions_are_refused(campaigns: Campaigns) -> None:
    held = campaigns.data("pose", "held")
    sessions = hexcal.read_sessions([held, campaigns.data("pose")], [], "XYZ")
    with pytest.raises(UsageError, match="validate each session on its own"):
        hexcal.validate(hexcal.preset("paper-hmt-true"), sessions)
    done = run("validate", "--geometry", "paper-hmt-true", "--data", held, "--data", campaigns.data("pose"))
    assert done.code == 1 and "validate each session on its own" in done.err and "Traceback" not in done.err


# -- the planning reports say the noise and the instrument they assumed ---------------------------


def test_select_says_the_noise_and_the_instrument_it_planned_for(campaigns: Campaigns) -> None:
    root = campaigns.root
    files = {k: root / f"select.{k}" for k in ("csv", "json", "html")}
    done = run("select", "--geometry", "paper-hmt", *campaigns.setup("targets"), "--n", 20, "--candidates",
               "random:60", "--noise", "leg=0.005,pos=0.015,ang=0.0002", "--noise-dist", "normal",
               "--out", files["csv"], "--json", files["json"], "--html", files["html"])  # fmt: skip
    assert done.code == 0, done.err
    body = json.loads(files["json"].read_text())
    assert body["noise"]["distribution"] == "normal" and body["noise"]["leg"] == 0.005
    assert body["instrument"].startswith("3 target position(s)")
    assert "Noise (normal): legs 0.005 mm, position 0.015 mm, orientation 0.0002 rad" in done.out
    assert f"Measured by the {body['instrument']}" in done.out
    page = files["html"].read_text()
    noise = {row[0]: row[2] for row in _table(page, "noise-assumed")[1:]}
    assert float(noise["leg"]) == pytest.approx(0.005) and float(noise["orientation"]) == pytest.approx(2e-4)
    assert dict(_table(page, "selection"))["measured by"] == body["instrument"]
    inputs = page.split('id="inputs"')[1]
    assert "targets-start.yaml" in inputs and "paper-hmt" in inputs
