"""Faults of issue 11 through the command line: each ends in one line, no output left, no input
changed (or 130/143 for signals).

The commands run through :func:`hexcal.cli.main` (in this process) or as a subprocess where
the fault is the process's own (encoding, ``/dev/full``, FIFOs, signals). A fault-injection
layer (patched ``fsync``: a full disk; a failing figure writer; signals at random moments)
checks that nothing is left and nothing changed.
"""

from __future__ import annotations

import errno
import hashlib
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from hexcal.cli import main
from hexcal.cli.safety import error_line

SRC = Path(__file__).resolve().parents[1] / "src"


def run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("hexcal: error: ") and "Traceback" not in err
    return lines[0]


def snapshot(folder: Path) -> dict[str, tuple[str, int]]:
    """Every file of ``folder``: content digest and mode (to assert nothing changed)."""
    out = {}
    for path in sorted(folder.rglob("*")):
        if path.is_file() and not path.is_symlink():
            out[str(path.relative_to(folder))] = (
                hashlib.sha256(path.read_bytes()).hexdigest(),
                path.stat().st_mode,
            )
        else:
            out[str(path.relative_to(folder))] = ("-", 0)
    return out


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> Path:
    """A folder with a geometry, poses, legs and measurements made by hexcal itself."""
    d = tmp_path_factory.mktemp("faults")
    assert main(["preset", "paper-hmt", "--out", str(d / "g.yaml")]) == 0
    assert (
        main(
            [
                "candidates",
                "--geometry",
                str(d / "g.yaml"),
                "--candidates",
                "random:20",
                "--out",
                str(d / "p.csv"),
            ]
        )
        == 0
    )
    assert (
        main(["ik", "--geometry", str(d / "g.yaml"), "--poses", str(d / "p.csv"), "--out", str(d / "l.csv")])
        == 0
    )
    argv = ["synthesize", "--nominal", d / "g.yaml", "--true", "paper-hmt-true", "--poses", d / "p.csv"]
    assert main([str(a) for a in argv] + ["--out", str(d / "m.csv")]) == 0
    return d


@pytest.fixture
def work(files, tmp_path) -> Path:
    for name in ("g.yaml", "p.csv", "l.csv", "m.csv"):
        (tmp_path / name).write_bytes((files / name).read_bytes())
    return tmp_path


def refused(capsys, work: Path, *argv) -> str:
    """Run a command that must fail: one line, exit 1, the folder unchanged."""
    before = snapshot(work)
    status, _, err = run(capsys, *argv)
    assert status == 1, err
    assert snapshot(work) == before
    assert not [p for p in work.iterdir() if ".tmp" in p.name]
    return one_line(err)


# -- data loss: outputs naming inputs or each other ---------------------------------------------
@pytest.mark.parametrize(
    "argv",
    [
        ["identify", "--geometry", "g.yaml", "--data", "m.csv", "--out", "r.yaml", "--report", "m.csv"],
        ["ik", "--geometry", "g.yaml", "--poses", "p.csv", "--out", "p.csv"],
        ["validate", "--geometry", "g.yaml", "--data", "m.csv", "--out", "m.csv"],
        ["identify", "--geometry", "g.yaml", "--data", "m.csv", "--out", "g.yaml"],
        ["fk", "--geometry", "g.yaml", "--legs", "l.csv", "--out", "l.csv"],
        [
            "synthesize",
            "--nominal",
            "g.yaml",
            "--true",
            "paper-hmt-true",
            "--poses",
            "p.csv",
            "--out",
            "g.yaml",
        ],
    ],
)
def test_an_output_naming_an_input_is_refused(capsys, work, monkeypatch, argv):
    monkeypatch.chdir(work)
    assert "also an input" in refused(capsys, work, *argv)


def test_an_output_naming_an_input_through_a_link_is_refused(capsys, work, monkeypatch):
    monkeypatch.chdir(work)
    os.symlink("p.csv", work / "alias.csv")
    assert "also an input" in refused(
        capsys, work, "ik", "--geometry", "g.yaml", "--poses", "p.csv", "--out", "alias.csv"
    )


@pytest.mark.parametrize(
    "argv",
    [
        [
            "identify",
            "--geometry",
            "g.yaml",
            "--data",
            "m.csv",
            "--out",
            "r.yaml",
            "--report",
            "r.yaml",
            "--json",
            "r.yaml",
        ],
        [
            "compensate",
            "--geometry",
            "g.yaml",
            "--poses",
            "p.csv",
            "--out",
            "x.csv",
            "--corrected-poses",
            "x.csv",
        ],
    ],
)
def test_two_outputs_on_one_path_are_refused(capsys, work, monkeypatch, argv):
    monkeypatch.chdir(work)
    assert "two outputs" in refused(capsys, work, *argv)


# -- special files, modes, links --------------------------------------------------------------
def test_special_files_are_refused_as_outputs_and_inputs(capsys, work, monkeypatch):
    monkeypatch.chdir(work)
    os.mkfifo(work / "fifo")
    assert "FIFO" in refused(capsys, work, "ik", "--geometry", "g.yaml", "--poses", "p.csv", "--out", "fifo")
    # a FIFO as input is refused at once (never opened for a blocking read)
    start = time.monotonic()
    assert "FIFO" in refused(capsys, work, "ik", "--geometry", "g.yaml", "--poses", "fifo", "--out", "x.csv")
    assert "FIFO" in refused(capsys, work, "ik", "--geometry", "fifo", "--poses", "p.csv", "--out", "x.csv")
    assert time.monotonic() - start < 10
    status, _, err = run(capsys, "ik", "--geometry", "g.yaml", "--poses", "p.csv", "--out", "/dev/null")
    assert status == 1 and "device" in one_line(err)


def test_a_replaced_file_keeps_its_mode_and_a_link_stays_a_link(capsys, work, monkeypatch):
    monkeypatch.chdir(work)
    (work / "legs.csv").write_text("old\n")
    os.chmod(work / "legs.csv", 0o640)
    os.symlink("legs.csv", work / "link.csv")
    status, _, err = run(capsys, "ik", "--geometry", "g.yaml", "--poses", "p.csv", "--out", "link.csv")
    assert status == 0, err
    assert (work / "link.csv").is_symlink()
    assert (work / "legs.csv").read_text().startswith("id,l1")
    assert (work / "legs.csv").stat().st_mode & 0o777 == 0o640


def test_standard_output_as_the_table(capsys, work, monkeypatch):
    monkeypatch.chdir(work)
    status, out, err = run(capsys, "ik", "--geometry", "g.yaml", "--poses", "p.csv", "--out", "-")
    assert status == 0, err
    assert out.startswith("id,l1,") and len(out.splitlines()) == 21


# -- half results ------------------------------------------------------------------------------
def test_a_full_disk_at_the_last_output_leaves_nothing(capsys, work, monkeypatch):
    """Fault injection: the second fsync fails with ENOSPC (the first file was fine)."""
    import hexcal.io.outputs as outputs

    monkeypatch.chdir(work)
    calls = []
    real = os.fsync

    def full(fd):
        calls.append(fd)
        if len(calls) >= 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        real(fd)

    monkeypatch.setattr(outputs.os, "fsync", full)
    line = refused(
        capsys,
        work,
        "identify",
        "--geometry",
        "g.yaml",
        "--data",
        "m.csv",
        "--out",
        "r.yaml",
        "--report",
        "rep.txt",
    )
    assert "No space left on device" in line and ("rep.txt" in line or "r.yaml" in line)
    assert ".tmp" not in line


def test_a_figure_failing_after_the_computation_leaves_no_file(capsys, work, monkeypatch):
    import hexcal.report.figures as figures

    monkeypatch.chdir(work)

    def broken(*_args, **_kw):
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(figures, "plot_error_angles", broken)
    status, _, err = run(
        capsys,
        "errormap",
        "--geometry",
        "paper-hmt",
        "--out",
        "maps",
        "--levels",
        "2",
        "--points",
        "3",
        "--grid",
        "3",
        "--draws",
        "3",
    )
    assert status == 1 and "Input/output error" in one_line(err)
    assert not (work / "maps").exists()  # the folder it created is gone again


@pytest.mark.parametrize("how", ["ascii", "full"])
def test_stdout_failing_leaves_no_file(work, how):
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    argv = [
        sys.executable,
        "-m",
        "hexcal",
        "identify",
        "--geometry",
        "g.yaml",
        "--data",
        "m.csv",
        "--out",
        "r.yaml",
    ]
    if how == "ascii":
        env["PYTHONIOENCODING"] = "ascii"
        proc = subprocess.run(argv, cwd=work, env=env, capture_output=True, text=True, timeout=120)
    else:
        with open("/dev/full", "w") as full:
            proc = subprocess.run(
                argv, cwd=work, env=env, stdout=full, stderr=subprocess.PIPE, text=True, timeout=120
            )
    assert proc.returncode == 1
    assert one_line(proc.stderr) and "no output file was written" in proc.stderr
    assert not (work / "r.yaml").exists()


def test_output_folders_are_checked_before_the_computation(capsys, work, monkeypatch):
    monkeypatch.chdir(work)
    (work / "afile").write_text("x")
    start = time.monotonic()
    line = refused(capsys, work, "paper", "--trials", "100000", "--out", "afile", "--jobs", "1")
    assert "not a folder" in line and time.monotonic() - start < 5


# -- options --------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["paper", "--trials", "0"], "--trials"),
        (["paper", "--trials", "1000000000"], "--trials"),
        (["simulate", "--trials", "1000000000"], "--trials"),
        (["simulate", "--trials", "-1"], "--trials"),
        (["simulate", "--jobs", "-3"], "--jobs"),
        (["select", "--geometry", "g.yaml", "--n", "0", "--out", "s.csv"], "--n"),
        (["errormap", "--geometry", "g.yaml", "--out", "e", "--draws", "0"], "--draws"),
        (["errormap", "--geometry", "g.yaml", "--out", "e", "--grid", "3000"], "--grid"),
        (
            ["candidates", "--geometry", "g.yaml", "--candidates", "random:1000000000", "--out", "c.csv"],
            "--candidates",
        ),
        (
            ["select", "--geometry", "g.yaml", "--candidates", "random:2000000", "--out", "c.csv"],
            "--candidates",
        ),
        (["select", "--geometry", "g.yaml", "--candidates", "grid:12", "--out", "c.csv"], "--candidates"),
        (["fk", "--geometry", "g.yaml", "--legs", "l.csv", "--out", "f.csv", "--tol", "inf"], "--tol"),
        (["fk", "--geometry", "g.yaml", "--legs", "l.csv", "--out", "f.csv", "--tol", "100"], "--tol"),
        (["fk", "--geometry", "g.yaml", "--legs", "l.csv", "--out", "f.csv", "--tol", "0"], "--tol"),
        (["simulate", "--geometry", "g.yaml", "--true", "paper-hmt-true", "--poses", "3"], "--poses"),
        (
            ["identify", "--geometry", "g.yaml", "--data", "m.csv", "--out", "r.yaml", "--max-rows", "5"],
            "--max-rows",
        ),
    ],
)
def test_nonsense_options_are_refused_up_front(capsys, work, monkeypatch, argv, words):
    monkeypatch.chdir(work)
    start = time.monotonic()
    line = refused(capsys, work, *argv)
    assert words in line and time.monotonic() - start < 10
    assert "out of reach" not in line


def test_usage_errors_are_one_line_with_the_documented_status(capsys):
    with pytest.raises(SystemExit) as info:
        main(["paper", "--trials", "many"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert one_line(err) and "--trials" in err and "usage:" not in err
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "Exit status" in capsys.readouterr().out


def test_identify_on_a_million_rows_is_refused_naming_the_limit(capsys, tmp_path, files):
    big = tmp_path / "big.csv"
    lines = (files / "m.csv").read_text().splitlines()
    header, rows = lines[0], [r for r in lines[1:] if not r.startswith("#")]
    with big.open("w") as fh:
        fh.write(header + "\n")
        for k in range(100_001 // len(rows) + 1):
            fh.write("".join(f"{k}-{r}\n" for r in rows))
    line = refused(
        capsys,
        tmp_path,
        "identify",
        "--geometry",
        files / "g.yaml",
        "--data",
        big,
        "--out",
        tmp_path / "r.yaml",
    )
    assert "100,000" in line and "--max-rows" in line


# -- messages -------------------------------------------------------------------------------------
def test_messages_name_the_problem_not_temporary_files():
    err = OSError(errno.ENOSPC, "No space left on device", "/data/.legs.k2j4h5g6.tmp.csv")
    assert error_line(err) == "hexcal: error: /data/legs.csv: No space left on device"
    assert "numerically" in error_line(np.linalg.LinAlgError("Matrix is not positive definite"))


def test_numpy_warnings_do_not_leak(capsys, work, monkeypatch):
    import hexcal.cli.kinematics as kinematics

    monkeypatch.chdir(work)
    real = kinematics.load_geometry

    def noisy(*args):
        np.ones(1) / np.zeros(1)  # "divide by zero encountered in divide"
        return real(*args)

    monkeypatch.setattr(kinematics, "load_geometry", noisy)
    status, _, err = run(capsys, "ik", "--geometry", "g.yaml", "--poses", "p.csv", "--out", "x.csv")
    assert status == 0 and "encountered" not in err


# -- signals --------------------------------------------------------------------------------------
def _children(pid: int) -> set[int]:
    out = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                out.add(int(entry.name))
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.slow
@pytest.mark.parametrize(
    ("sig", "status", "word"), [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")]
)
def test_signals_stop_paper_at_once_with_no_orphans_or_output(tmp_path, sig, status, word):
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "hexcal", "paper", "--trials", "500", "--jobs", "2", "--out", "res"],
        cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    time.sleep(random.Random(sig).uniform(2.0, 6.0))
    workers = _children(proc.pid)
    sent = time.monotonic()
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=30)
    took = time.monotonic() - sent
    assert proc.returncode == status, err
    assert err.strip().splitlines()[-1] == f"hexcal: {word}" and "Traceback" not in err
    assert took < 2.0, took
    time.sleep(0.5)
    assert not [pid for pid in workers if _alive(pid)]
    assert not list(tmp_path.iterdir())  # no results folder, no staged file


@pytest.mark.parametrize("delay", [0.0, 0.05, 0.15])
def test_sigint_during_start_up_prints_no_traceback(tmp_path, delay):
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "hexcal", "preset", "paper-hmt", "--out", "g.yaml"],
        cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert "Traceback" not in err
    assert proc.returncode in (0, 130, -signal.SIGINT)
    if proc.returncode != 0:
        assert not (tmp_path / "g.yaml").exists()


def test_zero_noise_is_said_and_negative_seeds_are_named(capsys, work, monkeypatch):
    monkeypatch.chdir(work)
    _status, _, err = run(
        capsys,
        "identify",
        "--geometry",
        "g.yaml",
        "--data",
        "m.csv",
        "--out",
        "z.yaml",
        "--noise",
        "leg=0,pos=0,ang=0",
    )
    assert "--noise is zero" in err
    line = refused(
        capsys,
        work,
        "synthesize",
        "--nominal",
        "g.yaml",
        "--true",
        "paper-hmt-true",
        "--poses",
        "p.csv",
        "--out",
        "q.csv",
        "--seed",
        "-1",
    )
    assert "--seed" in line
