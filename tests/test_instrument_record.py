"""A new instrument is one module and one registration, and takes part in every command.

``toy_extensions`` writes a ball bar (``toybar``: one distance per pose between a base pivot and
a platform ball) with its setup class, data files and planner, all outside ``src``, and
registers it with one record (``TOYBAR``, :class:`hexcal.instruments.InstrumentKind`). With it
registered, the command line, which knows nothing of it, does the whole campaign in this
process: ``candidates`` and ``select`` plan through its planner, ``synthesize`` writes its data
files through its writer, ``identify --leg-model auto --html --json`` reads them through its
reader and its setup files by their ``toybar:`` key, ``simulate`` runs a Monte Carlo study of
it. A data file read without its setup is named as the toy's by its column, and a unit row is
checked against the unit its record gives that column.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hexcal.core import preset
from hexcal.instruments import INSTRUMENTS, MODELS
from hexcal.instruments.registry import SETUP_KINDS
from hexcal.io import READERS, WRITERS, load_setup, save_geometry
from instrument_campaigns import run
from toy_extensions import TOYBAR, BallBar, BarSetup, registered

PIVOTS = ([150.0, 60.0, 30.0], [-150.0, -90.0, 20.0])
BALL = [10.0, -20.0, -30.0]
NOISE = ("--noise", "leg=0.001,pos=0.001,ang=1e-6", "--noise-dist", "normal")


def _setup(path: Path, pivot, ball, fixed: str = "") -> Path:
    pivot, ball = ([float(v) for v in p] for p in (pivot, ball))
    path.write_text(f"units: mm\ntoybar: {{pivot: {pivot}, ball: {ball}}}\n{fixed}")
    return path


@pytest.fixture
def toy():
    with registered():
        yield


def test_one_record_registers_every_seam(toy):
    assert (
        INSTRUMENTS["toybar"] is TOYBAR and MODELS["toybar"] is BallBar and SETUP_KINDS["toybar"] == "toybar"
    )
    assert READERS["toybar"] is TOYBAR.reader and WRITERS["toybar"] is TOYBAR.writer


def test_after_the_registration_nothing_of_it_is_left():
    with registered():
        assert "toybar" in MODELS
    assert "toybar" not in MODELS and "toybar" not in READERS and "toybar" not in SETUP_KINDS


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """The toy's campaign planned and measured from the command line: ``candidates`` and
    ``select`` through its planner, ``synthesize`` through its writer; the ``identify`` options
    of its two sessions (one per pivot, the start setups off by 0.5 mm)."""
    tmp = tmp_path_factory.mktemp("toybar")
    with registered():
        nominal = preset("paper-hmt")
        vector = nominal.machine_vector()
        vector[:42] += np.random.default_rng(4).uniform(-0.5, 0.5, 42)
        save_geometry(nominal.with_machine_vector(vector), tmp / "true.yaml")
        true_setups = [_setup(tmp / f"true{k}.yaml", p, BALL) for k, p in enumerate(PIVOTS)]
        start = np.add(BALL, 0.5)
        start_setups = [_setup(tmp / f"start{k}.yaml", np.add(p, 0.5), start) for k, p in enumerate(PIVOTS)]
        assert isinstance(load_setup(true_setups[0]), BarSetup)  # by its key, toybar:
        done = run("candidates", "--geometry", "paper-hmt", "--setup", true_setups[0], "--out", tmp / "c.csv")
        assert done.code == 0, done.err
        assert "toybar pose(s) of" in done.out and "bar1," in (tmp / "c.csv").read_text()
        data = []
        for k in range(2):
            sel = tmp / f"sel{k}.csv"
            done = run("select", "--geometry", "paper-hmt", "--setup", true_setups[k], "--circles", 100,
                       "--out", sel, "--json", tmp / f"sel{k}.json")  # fmt: skip
            assert done.code == 0, done.err
            assert "100 toybar pose(s) chosen" in done.out
            assert len(json.loads((tmp / f"sel{k}.json").read_text())["ids"]) == 100
            out = tmp / f"bar{k}.csv"
            done = run("synthesize", "--nominal", "paper-hmt", "--true", tmp / "true.yaml", "--setup",
                       true_setups[k], "--poses", sel, "--out", out, *NOISE, "--seed", k)  # fmt: skip
            assert done.code == 0, done.err
            assert out.read_text().splitlines()[-101].endswith(",bar")  # the header: its column
            data += ["--data", out, "--setup", start_setups[k]]
    return tmp, true_setups, data


def _identify(tmp: Path, data: list, leg_model: str) -> tuple[dict, str]:
    html, js = tmp / f"{leg_model}.html", tmp / f"{leg_model}.json"
    done = run("identify", "--geometry", "paper-hmt", *data, "--leg-model", leg_model, *NOISE,
               "--html", html, "--json", js, "--out", tmp / f"{leg_model}.yaml", "--force")  # fmt: skip
    assert done.code == 0, done.err
    result = json.loads(js.read_text())
    assert result["units"]["session1.pivot.x"] == "mm" and "session2.ball.z" in result["names"]
    page = html.read_text()
    assert "ball bar between a base pivot and a platform ball" in page and "session2.pivot.x" in page
    return result, page


def test_it_is_planned_measured_identified_reported_and_simulated(toy, campaign):
    tmp, true_setups, data = campaign
    result, _ = _identify(tmp, data, "linear")
    assert result["verdict"] in ("pass", "warn")
    done = run("simulate", "--geometry", "paper-hmt", "--setup", true_setups[0], "--poses", 40, "--trials", 2,
               "--strategies", "interior", "--methods", "ml", *NOISE, "--jobs", 1, "--quiet")  # fmt: skip
    assert done.code == 0, done.err
    assert "interior" in done.out


@pytest.mark.slow
def test_it_takes_part_in_the_leg_model_choice(toy, campaign):
    """``--leg-model auto``: the cross-validation (leave one pivot out, and the strokes' ends) of
    every candidate leg model on the toy's sessions, its scores in the JSON and on the page
    (about 4 minutes: some 30 errors-in-variables fits of 200 bar poses)."""
    tmp, _, data = campaign
    result, page = _identify(tmp, data, "auto")
    choice = result["leg_model_choice"]
    assert choice["choice"] in choice["scores"] and len(choice["scores"]) > 1  # linear and stroke ones
    assert 'id="leg-model"' in page and "(chosen)" in page  # the cross-validation's scores


def test_its_file_without_its_setup_is_named_and_its_unit_row_checked(toy, tmp_path: Path):
    bar = BallBar(BarSetup(PIVOTS[0], BALL))
    rows = "\n".join(f"{k},0,0,0,0,0,0,{700 + k}" for k in range(12))
    (tmp_path / "bar.csv").write_text(f"id,dl1,dl2,dl3,dl4,dl5,dl6,bar\n{rows}\n")
    done = run(
        "identify", "--geometry", "paper-hmt", "--data", tmp_path / "bar.csv", "--out", tmp_path / "g.yaml"
    )
    assert done.code == 1
    assert (
        "looks like ball-bar lengths (column bar), not poses: --setup is missing (a toybar setup)" in done.err
    )
    (tmp_path / "m.csv").write_text(f"id,dl1,dl2,dl3,dl4,dl5,dl6,bar\n,mm,mm,mm,mm,mm,mm,m\n{rows}\n")
    with pytest.raises(Exception, match="mm here"):
        TOYBAR.reader(tmp_path / "m.csv", bar, "xyz", None, None)
