"""Issue 11 figures: ik/fk on 10^6 rows (time, peak memory) and how fast signals stop ``paper``.

Prints, for ``ik`` and ``fk`` on ROWS rows, the wall time and the peak resident memory of the
process (the targets: under 20 s and 1 GB), with ``preset`` (start-up and one geometry) as
the baseline timed in the same run; and for SIGINT and SIGTERM sent to ``paper --trials 500
--jobs 2`` at a random moment, the exit status and the seconds from the signal to the exit.

    python benchmarks/bench_reliability.py [ROWS]
"""

from __future__ import annotations

import argparse
import os
import random
import resource
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from hexcal.io import read_poses

SRC = Path(__file__).resolve().parents[1] / "src"
ENV = {**os.environ, "PYTHONPATH": str(SRC)}
HEXCAL = [sys.executable, "-m", "hexcal"]


def timed(argv: list[str], cwd: Path) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB) of one hexcal run (a fresh child each time)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    start = time.perf_counter()
    subprocess.run(HEXCAL + argv, cwd=cwd, env=ENV, check=True, stdout=subprocess.DEVNULL)
    took = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return took, max(peak, before) / 1024


def stop_time(sig: int, folder: Path, seed: int) -> tuple[int, float]:
    proc = subprocess.Popen(
        HEXCAL + ["paper", "--trials", "500", "--jobs", "2", "--out", "res"],
        cwd=folder, env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    time.sleep(random.Random(seed).uniform(1.0, 5.0))
    sent = time.perf_counter()
    proc.send_signal(sig)
    proc.wait(timeout=60)
    return proc.returncode, time.perf_counter() - sent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rows", nargs="?", type=int, default=1_000_000, help="rows for ik and fk")
    rows = parser.parse_args().rows
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        base, _ = timed(["preset", "paper-hmt", "--out", "g.yaml"], d)
        spec = ["candidates", "--geometry", "g.yaml", "--candidates", "random:50", "--out", "p.csv"]
        subprocess.run(HEXCAL + spec, cwd=d, env=ENV, check=True, stdout=subprocess.DEVNULL)
        poses, _ = read_poses(d / "p.csv", "XYZ")
        big = poses[np.random.default_rng(0).integers(0, len(poses), rows)]
        with (d / "big.csv").open("w") as fh:
            fh.write("id,x,y,z,a,b,c\n")
            np.savetxt(fh, np.column_stack([np.arange(rows), big]), fmt=["%d"] + ["%.12g"] * 6, delimiter=",")
        print(f"baseline (preset): {base:.2f} s")
        for name, argv in (
            ("ik", ["ik", "--geometry", "g.yaml", "--poses", "big.csv", "--out", "legs.csv"]),
            ("fk", ["fk", "--geometry", "g.yaml", "--legs", "legs.csv", "--out", "back.csv"]),
        ):
            took, peak = timed(argv, d)
            print(
                f"{name} {rows:,} rows: {took:.1f} s ({took / base:.1f} x baseline), peak RSS {peak:.0f} MB"
            )
        for k, sig in enumerate((signal.SIGINT, signal.SIGTERM)):
            status, took = stop_time(sig, d, k)
            print(f"{signal.Signals(sig).name} to paper: exit {status} after {took:.2f} s")


if __name__ == "__main__":
    main()
