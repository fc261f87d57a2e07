"""Issue 28 at the command line: a bumped tracker's file, split; each session counted once; the
command line and Python judging alike (one workflow, ``hexcal.calibrate``).

Every test runs ``hexcal`` in-process on a simulated tracker session (tests/test_model_error.py
makes it: the seed paper's machine, three targets, the tracker bumped 2 mm and 0.1° before pose
``p30`` of 60) written by hexcal's own writer.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
import yaml

import hexcal
from hexcal.cli import main
from hexcal.io import read_sessions, write_session_data
from test_model_error import NOMINAL, START, campaign


def run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("bump")
    (folder / "tracker.yaml").write_text(yaml.safe_dump(START.to_dict()))
    write_session_data(folder / "run.csv", campaign(bump_at=30, seed=1), NOMINAL.euler)
    write_session_data(folder / "clean.csv", campaign(m=40, seed=3), NOMINAL.euler)
    return folder


def identify(capsys, folder: Path, *extra) -> tuple[int, str, str]:
    return run(capsys, "identify", "--geometry", "paper-hmt", "--setup", folder / "tracker.yaml", *extra)


def test_a_bumped_session_fails_naming_the_step_and_writes_nothing(capsys, files, tmp_path):
    status, out, err = identify(capsys, files, "--data", files / "run.csv", "--out", tmp_path / "cal.yaml")
    assert status == 1 and "Traceback" not in err
    line = err.strip().splitlines()[-1]
    assert line.startswith("hexcal: error: verdict fail: run.csv: a step between poses p29 and p30")
    assert "--split run.csv:p30" in line
    assert "fail  run.csv: a step between poses p29 and p30" in out  # the report is shown
    assert not (tmp_path / "cal.yaml").exists()


def test_split_auto_writes_one_setup_per_part_and_says_what_it_wrote(capsys, files, tmp_path):
    out_files = [tmp_path / n for n in ("cal.yaml", "r.txt", "r.json", "r.html")]
    status, out, err = identify(
        capsys,
        files,
        "--data",
        files / "run.csv",
        "--split",
        "auto",
        "--out",
        out_files[0],
        "--setup-out",
        tmp_path / "setups",
        "--report",
        out_files[1],
        "--json",
        out_files[2],
        "--html",
        out_files[3],
    )
    assert status == 0, err
    assert out.startswith("Verdict: PASS")
    assert "sessions split before run.csv:p30" in out and "as given: verdict fail" in out
    written = [line for line in out.splitlines() if line.startswith("wrote ")]
    assert written == [
        f"wrote the calibrated geometry to {out_files[0]}",
        f"wrote the calibrated setup to {tmp_path / 'setups' / 'run-1-setup.yaml'}",
        f"wrote the calibrated setup to {tmp_path / 'setups' / 'run-2-setup.yaml'}",
        f"wrote the report to {out_files[1]}",
        f"wrote the JSON result to {out_files[2]}",
        f"wrote the HTML report to {out_files[3]}",
    ]
    assert all(p.exists() for p in out_files)
    body = json.loads(out_files[2].read_text())
    assert body["splits"] == ["run.csv:p30"] and body["before_split"]["verdict"] == "fail"
    assert hexcal.load_geometry(out_files[0]).calibration["splits"] == ["run.csv:p30"]
    assert 'id="splits"' in out_files[3].read_text()


def test_the_same_session_twice_is_one_line_naming_both(capsys, files, tmp_path):
    (tmp_path / "link.csv").symlink_to(files / "clean.csv")
    (tmp_path / "copy.csv").write_bytes((files / "clean.csv").read_bytes())
    # the same observations in another file: the columns in reverse order
    rows = [
        line.split(",") for line in (files / "clean.csv").read_text().splitlines() if not line.startswith("#")
    ]
    (tmp_path / "bare.csv").write_text("".join(",".join(row[::-1]) + "\n" for row in rows))
    clean = files / "clean.csv"
    for other, words in (
        (clean, f"{clean} given twice"),
        (tmp_path / "link.csv", "link.csv is a link to"),
        (tmp_path / "copy.csv", "have the same bytes"),
        (tmp_path / "bare.csv", "hold the same observations"),
    ):
        status, _, err = identify(
            capsys, files, "--data", clean, "--data", other, "--out", tmp_path / "x.yaml"
        )
        assert status == 1 and len(err.strip().splitlines()) == 1, err
        assert "the same session twice" in err and words in err
        assert not (tmp_path / "x.yaml").exists()


def test_python_and_the_command_line_judge_alike(capsys, files, tmp_path):
    path = files / "clean.csv"
    status, _, err = identify(
        capsys, files, "--data", path, "--out", tmp_path / "cal.yaml", "--json", tmp_path / "r.json"
    )
    assert status == 0, err
    cli = json.loads((tmp_path / "r.json").read_text())
    sessions = read_sessions([path], [files / "tracker.yaml"], NOMINAL.euler)
    python = json.loads(hexcal.calibrate(NOMINAL, sessions).report("json"))
    for key in ("verdict", "reasons", "parameters", "stderr", "bound", "noise", "accuracy", "leg_model"):
        assert python[key] == cli[key], key
    # the same defaults: the command line passes no limit of its own
    assert cli["verdict"] == "pass"


def test_a_setup_that_declares_its_noise_is_the_reference_of_the_verdict(capsys, files, tmp_path):
    declared = START.to_dict() | {"noise": {"position": 0.003}}  # the tracker claims 3 µm; it has 15
    (tmp_path / "optimistic.yaml").write_text(yaml.safe_dump(declared))
    status, out, err = run(
        capsys,
        "identify",
        "--geometry",
        "paper-hmt",
        "--setup",
        tmp_path / "optimistic.yaml",
        "--data",
        files / "clean.csv",
        "--out",
        tmp_path / "cal.yaml",
    )
    assert status == 0, err
    assert "warn  the model does not describe the data: targets σ" in out
    assert "what the setup declares (0.003 mm)" in out
    assert os.path.exists(tmp_path / "cal.yaml")  # a warn writes
