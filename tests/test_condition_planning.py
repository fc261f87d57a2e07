"""Planning for a leg model that reads the conditions (issue 30): ``observability`` and
``select`` take the pose files' covariate columns into the design and say whether the
temperatures vary enough to determine the thermal terms (at one temperature ``kt_i`` is a
constant beside ``l0_i``: the pair is not determined; at three it is)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hexcal.cli import main
from hexcal.core import preset, workspace_corners
from hexcal.core.covariate_legs import CovariateLegs
from hexcal.core.stroke_legs import with_leg_model
from hexcal.design import analyse_poses
from hexcal.instruments import Covariates
from hexcal.io import read_poses, save_geometry

KT = np.array([0.006, 0.0066, 0.0072, 0.0078, 0.0084, 0.009])


def run(capsys, *argv):
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


@pytest.fixture
def warm():
    return with_leg_model(preset("paper-hmt"), CovariateLegs(thermal=True)).replace(leg_terms=KT[:, None])


def _write(path, poses, temperatures):
    rows = ["id,x,y,z,a,b,c,temp"]
    rows += [
        f"p{k},{','.join(repr(float(v)) for v in p)},{t}"
        for k, (p, t) in enumerate(zip(poses, temperatures, strict=True))
    ]
    path.write_text("\n".join(rows) + "\n")


@pytest.mark.parametrize(("temperatures", "determined"), [((21.0,), False), ((17.0, 21.0, 25.0), True)])
def test_analysis_says_whether_the_temperatures_determine_kt(warm, temperatures, determined):
    corners = workspace_corners(warm)[::2]
    temps = np.resize(temperatures, len(corners))
    analysis = analyse_poses(warm, corners, method="ml", covariates=Covariates(temperatures=temps))
    cover = analysis.conditions
    np.testing.assert_array_equal(cover.temperature_span, np.ptp(temps))
    assert cover.determined == {"thermal": determined} and cover.force_span is None
    kt = [k for k, n in enumerate(analysis.names) if n.startswith("kt_")]
    assert bool(np.any(analysis.not_identifiable[kt])) is not determined
    assert bool(cover.findings()) is not determined


def test_without_the_temperatures_planning_says_what_it_needs(warm):
    with pytest.raises(
        Exception, match="the planned poses: the thermal leg model needs the legs' temperatures"
    ):
        analyse_poses(warm, workspace_corners(warm)[:20], method="ml")


def test_observability_reads_the_plans_temperatures(capsys, tmp_path, warm):
    save_geometry(warm, tmp_path / "warm.yaml")
    corners = workspace_corners(warm)[::2]
    _write(tmp_path / "one.csv", corners, [21.0] * len(corners))
    _write(tmp_path / "three.csv", corners, np.resize([17.0, 21.0, 25.0], len(corners)))
    status, out, _ = run(capsys, "observability", "--geometry", tmp_path / "warm.yaml",
                         "--poses", tmp_path / "one.csv", "--json", tmp_path / "one.json")  # fmt: skip
    assert status == 0 and "thermal terms: NOT determined by these poses" in out
    assert "leg 1 0" in out and "plan poses at different temperatures" in out
    cover = json.loads((tmp_path / "one.json").read_text())["condition_coverage"]
    assert cover["determined"] == {"thermal": False} and cover["temperature_span_K"] == [0.0] * 6
    status, out, _ = run(capsys, "observability", "--geometry", tmp_path / "warm.yaml",
                         "--poses", tmp_path / "three.csv")  # fmt: skip
    assert status == 0 and "thermal terms: determined by these poses" in out and "leg 6 8" in out


def test_select_weighs_the_candidates_under_their_temperatures(capsys, tmp_path, warm):
    save_geometry(warm, tmp_path / "warm.yaml")
    corners = workspace_corners(warm)
    _write(tmp_path / "three.csv", corners, np.resize([17.0, 21.0, 25.0], len(corners)))
    _write(tmp_path / "one.csv", corners, [21.0] * len(corners))
    argv = (
        "select",
        "--geometry",
        tmp_path / "warm.yaml",
        "--n",
        24,
        "--seed",
        1,
        "--out",
        tmp_path / "s.csv",
    )
    status, out, err = run(
        capsys, *argv, "--candidates", tmp_path / "three.csv", "--json", tmp_path / "s.json"
    )
    assert status == 0, err
    assert "thermal terms: determined by these poses" in out
    assert json.loads((tmp_path / "s.json").read_text())["condition_coverage"]["determined"] == {
        "thermal": True
    }
    chosen, _, conditions = read_poses(tmp_path / "s.csv", "xyz", covariates=True)  # the selected poses' own
    temps = {
        tuple(np.round(p, 9)): t
        for p, t in zip(corners, np.resize([17.0, 21.0, 25.0], len(corners)), strict=True)
    }
    assert [temps[tuple(np.round(p, 9))] for p in chosen] == conditions.temperatures[:, 0].tolist()
    (tmp_path / "s.csv").unlink()
    status, _, err = run(capsys, *argv, "--candidates", tmp_path / "one.csv")
    assert status == 1 and "kt_1" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "s.csv").exists()
