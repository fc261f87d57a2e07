"""Issue 10 at the command line: the traps of a new user end refused or ``fail`` (nothing
written without ``--force``, the likely cause named), the noise is learned from the data by
default, and the defaults of simulate, select, fk and compensate say what they do.

Every test runs ``hexcal`` in-process on small simulated files (fixed seeds).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

from hexcal.cli import main
from hexcal.core import NoiseModel, preset
from hexcal.core.workspace import random_poses
from hexcal.io import write_measurements
from hexcal.simulation import simulate_measurements

NOMINAL = preset("paper-hmt")
TRUE = preset("paper-hmt-true")
NOISE = NoiseModel(leg=0.01, position=0.05, orientation=5e-4, distribution="normal")


def run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def one_error(status: int, err: str) -> str:
    assert status == 1 and "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hexcal: error:"), err
    return lines[0]


def measurements(tmp_path: Path, name: str, poses=None, true=TRUE, seed=7, n=60):
    poses = random_poses(NOMINAL, n, seed) if poses is None else poses
    ids = [f"p{k:03d}" for k in range(len(poses))]
    data = simulate_measurements(NOMINAL, true, poses, NOISE, seed + 1, ids)
    path = tmp_path / f"{name}.csv"
    write_measurements(path, data, NOMINAL.euler, "rad")
    return path, data


def identify(capsys, tmp_path: Path, data: Path, *extra) -> tuple[int, str, str, Path, Path]:
    out, js = tmp_path / "cal.yaml", tmp_path / "cal.json"
    status, stdout, err = run(
        capsys, "identify", "--geometry", "paper-hmt", "--data", data, "--out", out, "--json", js, *extra
    )
    return status, stdout, err, out, js


def assert_refused(capsys, tmp_path: Path, data: Path, *words: str) -> str:
    """Exit 1, one line naming ``words``, nothing written; ``--force`` then writes."""
    status, _, err, out, js = identify(capsys, tmp_path, data)
    line = one_error(status, err)
    for w in words:
        assert w in line, line
    assert not out.exists() and not js.exists()
    status, _stdout, err, out, js = identify(capsys, tmp_path, data, "--force")
    assert status == 0 and out.exists() and json.loads(js.read_text())["verdict"] == "fail"
    assert "verdict fail" in err
    return line


def test_default_noise_is_learned_and_said(capsys, tmp_path):
    path, _ = measurements(tmp_path, "clean", n=80)
    status, out, err, _cal, js = identify(capsys, tmp_path, path)
    assert status == 0, err
    assert out.startswith("Verdict: PASS")
    assert "estimated from the data (--noise auto: the default without --noise)" in out
    result = json.loads(js.read_text())
    for key in ("verdict", "reasons", "parameters", "stderr", "bound", "reduced_chi_square", "noise"):
        assert key in result
    assert set(result["bound"]) == set(result["parameters"]) and result["rank"] == 42
    noise = result["noise"]
    assert noise["source"] == "estimated" and result["outliers"] == []
    # each σ within 4 of its standard errors of the simulated σ (80 poses)
    for group, sigma in zip(("leg", "position", "orientation"), NOISE.sigmas, strict=True):
        assert abs(noise[group] - sigma) < 4 * noise["stderr"][group]
    assert result["noise_implied"]["option"].startswith("--noise leg=")


def test_given_noise_names_the_groups_that_disagree(capsys, tmp_path):
    path, _ = measurements(tmp_path, "clean", n=80)
    status, out, err, _, js = identify(
        capsys, tmp_path, path, "--noise", "leg=0.01,pos=0.5,ang=5e-4", "--noise-dist", "normal"
    )
    assert status == 0, err
    noise_section = out.split("[[Noise]]", 1)[1].split("[[", 1)[0]
    assert (
        "disagrees: position" in noise_section
        and "leg" not in noise_section.split("given:")[1].split("disagrees")[1]
    )
    assert json.loads(js.read_text())["noise"]["source"] == "given"


def test_radians_in_degree_columns_are_refused(capsys, tmp_path):
    path, _ = measurements(tmp_path, "rad")
    text = path.read_text().replace("x,y,z,a,b,c", "x,y,z,a_deg,b_deg,c_deg")
    bad = tmp_path / "deg.csv"
    bad.write_text(text)
    assert_refused(capsys, tmp_path, bad, "radians in degree columns")


def test_poses_that_barely_rotate_are_refused_naming_the_combinations(capsys, tmp_path):
    poses = random_poses(NOMINAL, 60, 3)
    poses[:, 3:] = np.random.default_rng(4).normal(0.0, 2e-4, (60, 3))  # a real machine's wobble
    path, _ = measurements(tmp_path, "flat", poses=poses)
    line = assert_refused(capsys, tmp_path, path, "determined by these data")
    assert "·" in line  # a named combination


def test_unfitted_gains_name_the_fit_option(capsys, tmp_path):
    true = TRUE.replace(leg_gains=np.array([1.004, 0.997, 1.003, 0.996, 1.002, 0.995]))
    path, _ = measurements(tmp_path, "gains", true=true, n=80)
    status, out, err, _, _ = identify(capsys, tmp_path, path)
    assert "--fit joints,l0,gains" in out + err
    # scale errors of 0.2-0.5 %: fitting the gains more than halves the leg residual, so the
    # default fit is refused (no geometry written) and the hint names the option
    assert status == 1 and "verdict fail" in err
    status, out, err, _, js = identify(capsys, tmp_path, path, "--fit", "joints,l0,gains")
    assert status == 0, err
    assert json.loads(js.read_text())["verdict"] != "fail"


def test_one_typing_error_fails_naming_the_pose(capsys, tmp_path):
    path, _data = measurements(tmp_path, "typo")
    lines = path.read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if line.startswith("p017,"))
    cells = lines[k].split(",")
    cells[7] = repr(float(cells[7]) + 100.0)  # x off by 100 mm
    lines[k] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    line = assert_refused(capsys, tmp_path, path, "p017", "--robust")
    assert "outlier" in line or "beyond the robust scale" in line
    status, _out, err, _, js = identify(capsys, tmp_path, path, "--robust")
    assert status == 0, err
    assert json.loads(js.read_text())["outliers"] == ["p017"]


# -- defaults that match ----------------------------------------------------------------------------


def test_simulate_without_true_announces_random_machines_and_records_both(capsys, tmp_path):
    nominal = tmp_path / "my.yaml"
    assert run(capsys, "preset", "paper-hmt", "--out", nominal)[0] == 0
    out = tmp_path / "study"
    status, _, err = run(
        capsys,
        "simulate",
        "--geometry",
        nominal,
        "--methods",
        "length",
        "--strategies",
        "corners",
        "--poses",
        "15",
        "--trials",
        "2",
        "--jobs",
        "1",
        "--quiet",
        "--out",
        out,
    )
    assert status == 0, err
    assert "random errors around the nominal" in err
    study = json.loads((out / "study.json").read_text())
    assert study["nominal_geometry"]["base_joints"][0] == [305.4001, 111.1565, 0.0]
    assert study["true_geometry"].startswith("random")
    assert study["noise_sigmas"]["leg"] == pytest.approx(0.01 / 3**0.5)
    status, _, err = run(
        capsys,
        "simulate",
        "--true",
        "paper-hmt-true",
        "--methods",
        "length",
        "--strategies",
        "corners",
        "--poses",
        "15",
        "--trials",
        "2",
        "--jobs",
        "1",
        "--quiet",
        "--out",
        out,
    )
    assert status == 0 and "random" not in err
    assert json.loads((out / "study.json").read_text())["true_geometry"]["name"] == "paper-hmt-true"


def test_fk_with_lengths_and_readings_uses_the_readings(capsys, tmp_path):
    from hexcal.core import inverse_kinematics, leg_readings
    from hexcal.io import read_poses, write_legs

    poses = random_poses(NOMINAL, 3, 5)
    lengths = inverse_kinematics(NOMINAL, poses)
    readings = leg_readings(NOMINAL, lengths)
    legs = tmp_path / "legs.csv"
    write_legs(legs, lengths + 1.0, readings, ["a", "b", "c"])  # l disagrees with dl by 1 mm
    status, _, err = run(capsys, "fk", "--geometry", "paper-hmt", "--legs", legs, "--out", tmp_path / "p.csv")
    assert status == 0, err
    assert "using dl (the controller's readings)" in err
    back, _ = read_poses(tmp_path / "p.csv", NOMINAL.euler)
    np.testing.assert_allclose(back, poses, atol=1e-6)


def test_compensate_warns_about_targets_outside_the_box(capsys, tmp_path):
    from hexcal.io import write_poses

    poses = random_poses(NOMINAL, 4, 6)
    poses[2, 0] = 300.0  # x beyond the box's 250 mm, still within the leg limits
    targets = tmp_path / "t.csv"
    write_poses(targets, poses, ["t0", "t1", "t2", "t3"])
    status, _, err = run(
        capsys,
        "compensate",
        "--geometry",
        "paper-hmt-true",
        "--nominal",
        "paper-hmt",
        "--poses",
        targets,
        "--out",
        tmp_path / "legs.csv",
        "--corrected-poses",
        tmp_path / "c.csv",
    )
    assert status == 0, err
    lines = [line for line in err.splitlines() if "outside the workspace box" in line]
    assert lines and lines[0].endswith("t2") and "1 target(s)" in lines[0]


def test_planning_headlines_ml_and_select_defaults_to_a(capsys, tmp_path):
    plan, js = tmp_path / "plan.csv", tmp_path / "plan.json"
    status, out, err = run(
        capsys, "select", "--geometry", "paper-hmt", "--n", "10", "--out", plan, "--json", js
    )
    assert status == 0, err
    data = json.loads(js.read_text())
    assert data["criterion"] == "A" and "identify (method ml)" in out
    selected = data["predicted_mean_abs_error_mm"]["selected"]
    assert selected["estimator"] == selected["bound"] < selected["length"]
    status, out, err = run(capsys, "observability", "--geometry", "paper-hmt", "--poses", plan)
    assert status == 0, err
    assert "(identify, method ml)" in out


def test_every_option_shows_its_default(capsys):
    from hexcal.cli.main import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name in ("identify", "fk", "select", "observability", "simulate", "paper", "compensate"):
        for action in sub.choices[name]._actions:
            if action.option_strings and action.dest != "help" and not action.required:
                assert "default" in (action.help or ""), (name, action.dest)
