"""Start-up time of the ``hexcal`` command, against a bare interpreter in the same run.

Times, as subprocesses of the same interpreter and with the caller's environment:

- ``python -c pass`` (the bare interpreter: the reference of the ratios);
- ``hexcal --help`` (target 0.3 s wall);
- ``hexcal ik`` on a 100-row pose file of the paper-hmt workspace (target 0.6 s wall).

Each is run ``--repeats`` times (after one warm-up run) and the median wall time is
printed in seconds and as a ratio to the bare interpreter, with its target and PASS/MISS
(the target is on wall time), and the median CPU time of the process (user + system),
which a loaded machine inflates less than the wall time.
The ``hexcal`` console script next to the interpreter is used if there is one, else
``python -m hexcal``. Also prints which heavy modules each command imported.

Run ``.venv/bin/python benchmarks/startup.py`` (``--repeats 15`` for steadier figures).
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: Wall-time targets of the issue, seconds.
TARGETS = {"hexcal --help": 0.3, "hexcal ik (100 poses)": 0.6}

#: Modules whose import start-up should avoid, reported per command.
HEAVY = ("numpy", "scipy", "scipy.optimize", "matplotlib", "yaml")

#: Prints which heavy modules a command imported, after it ran (via ``python -c``).
_PROBE = """
import runpy, sys
sys.argv = ["hexcal", *sys.argv[1:]]
try:
    runpy.run_module("hexcal", run_name="__main__")
except SystemExit:
    pass
print(",".join(m for m in {heavy!r} if m in sys.modules), file=sys.stderr)
"""


def hexcal_command() -> list[str]:
    """The console script next to the interpreter, else ``python -m hexcal``."""
    script = Path(sys.executable).parent / "hexcal"
    return [str(script)] if script.exists() else [sys.executable, "-m", "hexcal"]


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_times(command: list[str], repeats: int, cwd: str) -> tuple[list[float], list[float]]:
    """Wall and CPU times (s) of ``repeats`` runs after one warm-up; fails if a run fails."""
    walls, cpus = [], []
    for k in range(repeats + 1):
        cpu, start = _children_cpu(), time.perf_counter()
        subprocess.run(command, cwd=cwd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        if k:
            walls.append(time.perf_counter() - start)
            cpus.append(_children_cpu() - cpu)
    return walls, cpus


def imported(args: list[str], cwd: str) -> str:
    """The heavy modules that ``hexcal ARGS`` imports."""
    probe = _PROBE.format(heavy=HEAVY)
    run = subprocess.run(
        [sys.executable, "-c", probe, *args], cwd=cwd, capture_output=True, text=True, check=False
    )
    return run.stderr.strip().splitlines()[-1] if run.stderr.strip() else ""


def write_pose_file(path: Path, n: int = 100) -> None:
    """``n`` random poses of the paper-hmt workspace box (seed 0)."""
    from hexcal.core import preset, random_poses
    from hexcal.io import write_poses

    poses = random_poses(preset("paper-hmt"), n, rng=0)
    write_poses(path, poses, [f"p{k:03d}" for k in range(n)])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=9, help="timed runs of each command (median)")
    args = parser.parse_args(argv)
    hexcal = hexcal_command()
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    print(f"python {sys.version.split()[0]} at {sys.executable}; command {' '.join(hexcal)}")
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}; median of {args.repeats} runs each")
    with tempfile.TemporaryDirectory() as tmp:
        write_pose_file(Path(tmp) / "poses.csv")
        ik_args = ["ik", "--geometry", "paper-hmt", "--poses", "poses.csv", "--out", "legs.csv"]
        runs = {
            "python -c pass": ([sys.executable, "-c", "pass"], None),
            "hexcal --help": ([*hexcal, "--help"], ["--help"]),
            "hexcal ik (100 poses)": ([*hexcal, *ik_args], ik_args),
        }
        bare = None
        failed = False
        for name, (command, probe_args) in runs.items():
            walls, cpus = run_times(command, args.repeats, tmp)
            median, cpu = statistics.median(walls), statistics.median(cpus)
            bare = bare or median
            target = TARGETS.get(name)
            status = "" if target is None else ("PASS" if median <= target else "MISS")
            failed |= status == "MISS"
            target_text = "" if target is None else f"target {target:.1f} s ({target / bare:.1f}x)"
            heavy = "" if probe_args is None else f"imports: {imported(probe_args, tmp) or 'none of them'}"
            figures = f"{median:7.3f} s  {median / bare:5.1f}x bare  (cpu {cpu:.3f} s)"
            print(f"{name:<24} {figures}  {target_text:<24} {status:<4}  {heavy}".rstrip())
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
