"""Faults of issue 11 through the command line: each ends in one line, no output left, no input
changed (or 128 + the signal for signals: 130, 143, 129).

The commands run through :func:`hexcal.cli.main` (in this process) or as a subprocess where
the fault is the process's own (encoding, ``/dev/full``, FIFOs, signals). A fault-injection
layer (patched ``fsync``: a full disk; a failing figure writer; signals at defined moments)
checks that nothing is left and nothing changed.
"""

from __future__ import annotations

import errno
import hashlib
import os
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


def test_the_documented_signal_statuses_are_those_of_the_code():
    from hexcal.cli.main import EPILOG
    from hexcal.cli.safety import SIGNALS

    # the exit statuses are documented on the command-line page of the docs (docs/commands.md)
    page = " ".join((SRC.parent / "docs" / "commands.md").read_text(encoding="utf-8").split())
    for sig, word in SIGNALS.items():
        name = signal.Signals(sig).name
        assert f"{128 + sig} {word} ({name}" in EPILOG
        assert f"{128 + sig} after {name}" in page and f"`hexcal: {word}`" in page


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
    ("sig", "status", "word"),
    [
        (signal.SIGINT, 130, "interrupted"),
        (signal.SIGTERM, 143, "terminated"),
        (signal.SIGHUP, 129, "hung up"),
    ],
)
def test_signals_stop_paper_at_once_with_no_orphans_or_output(tmp_path, sig, status, word):
    """A signal in the middle of the computation (once the first chunk has completed: its
    progress line is read, not waited for by a clock) ends paper --jobs 2 with one line, the
    workers gone and nothing written. The time it took is printed (-s), not asserted."""
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "hexcal", "paper", "--trials", "500", "--jobs", "2", "--out", "res"],
        cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=_default_signals,
    )  # fmt: skip
    seen = []
    while not any("identifications:" in line for line in seen):
        line = proc.stderr.readline()
        assert line, "".join(seen)  # paper ended before its first progress line
        seen.append(line)
    workers = _children(proc.pid)
    sent = time.monotonic()
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    print(f"{word}: ended {time.monotonic() - sent:.2f} s after the signal")
    assert proc.returncode == status, err
    assert err.strip().splitlines()[-1] == f"hexcal: {word}" and "Traceback" not in "".join(seen) + err
    deadline = time.monotonic() + 60
    while [pid for pid in workers if _alive(pid)] and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not [pid for pid in workers if _alive(pid)]
    assert not list(tmp_path.iterdir())  # no results folder, no staged file


def _caught(pid: int) -> int:
    """The mask of signals a process catches (``SigCgt`` of ``/proc/PID/status``), 0 once gone."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return 0
    return int(next(line for line in status.splitlines() if line.startswith("SigCgt:")).split()[1], 16)


def _ignored(pid: int) -> int:
    """The mask of signals a process ignores (``SigIgn`` of ``/proc/PID/status``), 0 once gone."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return 0
    return int(next(line for line in status.splitlines() if line.startswith("SigIgn:")).split()[1], 16)


def _default_signals() -> None:
    """In the child: the three signals at their defaults, whatever the test runner ignores."""
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_DFL)


def start_hexcal(
    tmp_path: Path, *argv: str, hangup_ignored: bool = False, session: bool = False
) -> subprocess.Popen:
    """``python -m hexcal ARGV`` in ``tmp_path``, stopped (SIGSTOP) as soon as hexcal's own
    start-up handlers catch SIGTERM: what happens next no longer depends on timing."""

    def prepare() -> None:
        _default_signals()
        if hangup_ignored:  # as under nohup
            signal.signal(signal.SIGHUP, signal.SIG_IGN)

    env = {**os.environ, "PYTHONPATH": str(SRC)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "hexcal", *argv], cwd=tmp_path, env=env, preexec_fn=prepare,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=session,
    )  # fmt: skip
    bit = 1 << (signal.SIGTERM - 1)  # Python itself catches SIGINT, never SIGTERM
    while not _caught(proc.pid) & bit and proc.poll() is None:
        time.sleep(0.001)  # polling a condition, not waiting for time to pass
    proc.send_signal(signal.SIGSTOP)
    return proc


@pytest.mark.parametrize(
    ("sig", "status", "word"),
    [
        (signal.SIGINT, 130, "interrupted"),
        (signal.SIGTERM, 143, "terminated"),
        (signal.SIGHUP, 129, "hung up"),
    ],
)
def test_sigint_during_start_up_prints_no_traceback(tmp_path, sig, status, word):
    """A signal during the start-up, once hexcal's first line has run (before it, the
    interpreter's own start-up is Python's), ends with one line and 128 + the signal. The child
    is stopped at that point, signalled, and continued: deterministic on any machine."""
    proc = start_hexcal(tmp_path, "preset", "paper-hmt", "--out", "g.yaml")
    proc.send_signal(sig)
    proc.send_signal(signal.SIGCONT)
    _, err = proc.communicate(timeout=60)
    assert "Traceback" not in err
    if proc.returncode == 0:  # it ended before the SIGSTOP (not seen on any machine so far)
        return
    assert proc.returncode == status and err.strip().splitlines() == [f"hexcal: {word}"], err
    assert not (tmp_path / "g.yaml").exists()


def test_an_ignored_sighup_stays_ignored_as_under_nohup(tmp_path):
    proc = start_hexcal(tmp_path, "preset", "paper-hmt", "--out", "g.yaml", hangup_ignored=True)
    proc.send_signal(signal.SIGHUP)
    proc.send_signal(signal.SIGCONT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0 and err == ""
    assert (tmp_path / "g.yaml").exists()


@pytest.mark.parametrize("group", [False, True], ids=["to-hexcal", "to-its-process-group"])
def test_sighup_stops_paper_with_no_orphans_or_output(tmp_path, group):
    """SIGHUP during ``paper --jobs 2``: one line, 129, the workers gone, nothing written; sent
    to hexcal alone (``kill -HUP``) or to its whole process group, workers included (a closed
    terminal). The signal is sent once both workers are ready: they exist and ignore SIGHUP
    (their start-up has run: a readiness marker read from /proc, polled, never a sleep), so
    the parent alone stops the pool whatever the machine's load."""
    argv = ("paper", "--trials", "400", "--jobs", "2", "--quiet", "--out", "res")
    proc = start_hexcal(tmp_path, *argv, session=group)
    proc.send_signal(signal.SIGCONT)
    deadline = time.monotonic() + 120
    hup = 1 << (signal.SIGHUP - 1)

    def ready() -> set[int]:
        return {pid for pid in _children(proc.pid) if _ignored(pid) & hup}

    while len(ready()) < 2 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)  # polling a condition, not waiting for time to pass
    workers = ready()
    assert len(workers) >= 2 and proc.poll() is None, "paper --jobs 2 started no workers"
    if group:
        os.killpg(proc.pid, signal.SIGHUP)
    else:
        proc.send_signal(signal.SIGHUP)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 129, err
    assert err.strip().splitlines()[-1] == "hexcal: hung up" and "Traceback" not in err
    while [pid for pid in workers if _alive(pid)] and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not [pid for pid in workers if _alive(pid)]
    assert not list(tmp_path.iterdir())  # no results folder, no staged file


def test_zero_noise_has_one_meaning_and_negative_seeds_are_named(capsys, work, monkeypatch):
    """A zero noise is refused where bounds and weights come from it (identify, observability,
    select), as --noise or as an all-zero pose covariance with zero leg noise; a simulation may
    be noise-free (it says its bounds are 0)."""
    monkeypatch.chdir(work)
    (work / "zero.txt").write_text("\n".join(["0 0 0 0 0 0"] * 6) + "\n")
    for noise in (["--noise", "leg=0,pos=0,ang=0"], ["--noise", "leg=0", "--pose-covariance", "zero.txt"]):
        line = refused(
            capsys, work, "identify", "--geometry", "g.yaml", "--data", "m.csv", "--out", "z.yaml", *noise
        )
        assert "every noise is 0" in line and "leave --noise out" in line
    assert not (work / "z.yaml").exists()
    line = refused(capsys, work, "observability", "--geometry", "g.yaml", "--poses", "p.csv",
                   "--noise", "leg=0,pos=0,ang=0")  # fmt: skip
    assert "every noise is 0" in line
    _status, _, err = run(capsys, "simulate", "--geometry", "g.yaml", "--trials", "2", "--poses", "10",
                          "--out", "sim", "--noise", "leg=0,pos=0,ang=0")  # fmt: skip
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


_BLOCKED_POOL = r"""
import os, sys, threading
from hexcal.simulation import map_trials

def blocked(definition, idx):
    os.write(1, f"{os.getpid()}\n".encode())  # one write: the two workers' lines never mix
    threading.Event().wait()

map_trials(blocked, None, 2, jobs=2, chunk_size=1)
"""


def _no_core_dump() -> None:
    import resource

    _default_signals()
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGQUIT, signal.SIGUSR1])
def test_pool_workers_end_when_their_parent_dies_of_a_signal_it_cannot_handle(tmp_path, sig):
    """A parent killed by SIGKILL (an out-of-memory kill, ``timeout -s KILL``) or by a signal
    hexcal does not handle cannot stop its pool: its workers, each blocked in a chunk for ever,
    end all the same (they were re-parented and computed on before). The workers' pids are
    read from the chunks, the parent is killed, and /proc is polled until they are gone."""
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    proc = subprocess.Popen(
        [sys.executable, "-c", _BLOCKED_POOL], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL, text=True, preexec_fn=_no_core_dump,
    )  # fmt: skip
    workers = {int(proc.stdout.readline()) for _ in range(2)}
    assert len(workers) == 2 and proc.pid not in workers
    proc.send_signal(sig)
    assert proc.wait(timeout=60) == -sig
    deadline = time.monotonic() + 60
    while [pid for pid in workers if _alive(pid)] and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not [pid for pid in workers if _alive(pid)]
