"""Issue 22, limits and options: one memory budget for every command with ``--trials``, one
limited YAML reader for every YAML file (setups too), list options and ``--noise`` without
repeated values. Each is refused up front in one line, before any work."""

from __future__ import annotations

import os

import pytest

from hexcal.cli import main
from hexcal.io.inputs import MAX_YAML_BYTES


def _run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hexcal: error: ") and "Traceback" not in err, err
    return lines[0]


@pytest.fixture
def no_work(monkeypatch):
    """Every command loads a geometry first: refusing before that is refusing before any work."""
    import hexcal.io

    def boom(*_args, **_kw):
        raise AssertionError("the command started its work")

    monkeypatch.setattr(hexcal.io, "load_geometry", boom)


@pytest.mark.parametrize(
    "argv",
    [
        ["study", "selection", "--trials", "1000000000"],
        ["study", "selection", "--trials", "2000000", "--poses", "8,10,15,20,30,45,64"],
        ["paper", "--trials", "1000000000"],
        ["simulate", "--trials", "1000000000"],
    ],
)
def test_every_command_with_trials_has_the_one_memory_budget(capsys, tmp_path, no_work, argv):
    status, out, err = _run(capsys, *argv, "--out", tmp_path / "res")
    line = _one_line(err)
    assert status == 1 and out == "" and "--trials" in line and "memory budget" in line
    assert not (tmp_path / "res").exists()


def test_a_study_within_the_budget_is_not_refused_by_it(capsys, tmp_path):
    # 100,000 trials of 3 kinds: 0.6 GB, under the 2 GiB budget (refused later for another reason)
    status, _, err = _run(
        capsys, "study", "selection", "--trials", "100000", "--poses", "8", "--geometry", "x"
    )
    assert status == 1 and "memory budget" not in err and "no such geometry file" in _one_line(err)


@pytest.mark.parametrize(
    ("argv", "option", "value"),
    [
        (["study", "selection", "--poses", "8,8"], "--poses", "8"),
        (["study", "selection", "--poses", "8,10,08"], "--poses", "08"),
        (["simulate", "--poses", "15,30,15"], "--poses", "15"),
        (["simulate", "--methods", "ml,paper,ml"], "--methods", "ml"),
        (["simulate", "--strategies", "corners, corners"], "--strategies", "corners"),
        (["simulate", "--noise-levels", "1,1.0"], "--noise-levels", "1.0"),
    ],
)
def test_a_value_repeated_in_a_list_option_is_refused(capsys, tmp_path, no_work, argv, option, value):
    status, out, err = _run(capsys, *argv, "--trials", "2", "--out", tmp_path / "res")
    line = _one_line(err)
    assert status == 1 and out == ""
    assert line.startswith(f"hexcal: error: {option}: {value} is given twice")
    assert not (tmp_path / "res").exists()


@pytest.mark.parametrize(
    "argv",
    [
        ["simulate", "--noise", "leg=0.01,leg=0.5"],
        ["paper", "--noise", "pos=0.02, leg=0.01,pos=0.02"],
        ["study", "selection", "--noise", "ang=0.001,ang=0.002"],
    ],
)
def test_a_repeated_noise_key_is_refused(capsys, tmp_path, argv):
    status, out, err = _run(capsys, *argv, "--trials", "2", "--out", tmp_path / "res")
    line = _one_line(err)
    assert status == 1 and out == "" and "--noise:" in line and "given twice" in line
    assert not (tmp_path / "res").exists()


# -- setup files: the limited YAML reader ------------------------------------------------------
SELECT = ["select", "--geometry", "paper-hmt", "--candidates", "corners", "--n", "40"]


def _alias_bomb(levels: int = 9, width: int = 10) -> str:
    """A valid setup whose free-form ``calibration`` mapping stands for 10^9 values."""
    lines = ["units: mm", "instrument_frame: auto", "targets: {t1: [0, 0, 60], t2: [100, 0, 60]}"]
    lines += ["calibration:", "  a0: &a0 [" + ", ".join(["1"] * width) + "]"]
    for k in range(1, levels):
        lines.append(f"  a{k}: &a{k} [" + ", ".join([f"*a{k - 1}"] * width) + "]")
    return "\n".join(lines) + "\n"


def test_an_alias_bomb_in_a_setup_is_refused_at_once(capsys, tmp_path):
    (tmp_path / "bomb.yaml").write_text(_alias_bomb())
    status, out, err = _run(capsys, *SELECT, "--setup", tmp_path / "bomb.yaml", "--out", tmp_path / "p.csv")
    line = _one_line(err)
    assert status == 1 and out == ""
    assert line.split("bomb.yaml: ", 1)[1].startswith("line ") and "(an alias bomb?)" in line
    assert not (tmp_path / "p.csv").exists()


def test_a_setup_over_the_size_limit_is_refused_before_reading(capsys, tmp_path):
    path = tmp_path / "big.yaml"
    text = (
        "units: mm\ninstrument_frame: auto\ntargets: {t1: [0, 0, 60], t2: [100, 0, 60], t3: [0, 100, 60]}\n"
    )
    with open(path, "w") as fh:
        fh.write(text)
        fh.write(("# " + "x" * 1022 + "\n") * (MAX_YAML_BYTES // 1024 + 1))
    assert os.path.getsize(path) > MAX_YAML_BYTES
    status, out, err = _run(capsys, *SELECT, "--setup", path, "--out", tmp_path / "p.csv")
    line = _one_line(err)
    assert status == 1 and out == "" and "big.yaml" in line and "over the limit" in line
    assert not (tmp_path / "p.csv").exists()


def test_a_fifo_as_a_setup_is_refused_at_once(capsys, tmp_path):
    os.mkfifo(tmp_path / "fifo.yaml")
    status, _, err = _run(capsys, *SELECT, "--setup", tmp_path / "fifo.yaml", "--out", tmp_path / "p.csv")
    assert status == 1 and "FIFO" in _one_line(err)


def test_a_linuxcnc_configuration_over_the_size_limit_is_refused_before_reading(capsys, tmp_path):
    from hexcal.cli.linuxcnc import MAX_CONFIG_BYTES

    path = tmp_path / "big.ini"
    with open(path, "w") as fh:
        fh.write("[TRAJ]\nLINEAR_UNITS = mm\n")
        fh.write(("# " + "x" * 1022 + "\n") * (MAX_CONFIG_BYTES // 1024 + 1))
    (tmp_path / "m.hal").write_text("loadrt genhexkins\n")
    argv = ["import", "linuxcnc", "--hal", tmp_path / "m.hal", "--ini", path, "--out", tmp_path / "g.yaml"]
    status, out, err = _run(capsys, *argv)
    line = _one_line(err)
    assert status == 1 and out == "" and "big.ini" in line and "over the limit" in line
    assert not (tmp_path / "g.yaml").exists()
