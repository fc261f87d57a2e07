"""Filtering a 10^6-line G-code program (issue 20, item 3): lines per second and peak memory,
as ratios to the kinematics alone, measured in one run.

``python benchmarks/gcode.py [--lines N] [--quick]`` writes a CAM-like program of N lines
(default 1,000,000: a smooth 6-axis path of 0.16 mm steps written with 4 decimals, a comment
every 100 lines, a 1 mm full circle G2 every 500) and then, each in a fresh child process so
that the peak resident memory is its own:

- ``filter``: ``hexcal compensate --gcode`` (paper-hmt-true calibrated, paper-hmt nominal,
  default tolerances), in-process through :func:`hexcal.cli.main.main`;
- ``filter, tenth``: the same on the program's first tenth, to show that the memory does not
  grow with the program (blocks of :data:`hexcal.io.gcode.BLOCK_LINES` lines);
- ``kinematics``: :func:`hexcal.core.compensate` of every target of the program (the corrected
  poses the filter cannot do without), in blocks of the same size, on arrays made in memory;
- ``path``: :func:`hexcal.core.correct_path` of the program's moves (the kinematics plus the
  midpoint checks and subdivision, no text), blocks read beforehand;
- ``read``: :func:`hexcal.io.read_program` alone (parsing, no kinematics);
- ``import``: importing hexcal, numpy and scipy (the floor of the peak memory).

Printed: wall and CPU seconds, lines per second, peak RSS, and the ratios filter / kinematics
(time) and filter / import, filter / filter-tenth (memory). On a shared machine the times vary
by tens of per cent between runs; the ratios within one run are the figures to read.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = r"""
import json, resource, sys, time
kind, program, out, lines = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
import numpy as np

def path(n):
    t = np.arange(n) * 0.004
    x = 200 * np.sin(t * 0.05) * np.cos(t * 0.3)
    y = 200 * np.sin(t * 0.05) * np.sin(t * 0.3)
    z = 800 + 50 * np.sin(t * 0.02)
    a, b, c = 3 * np.sin(t * 0.01), 3 * np.cos(t * 0.013), 2 * np.sin(t * 0.007)
    return np.round(np.stack([x, y, z, a, b, c], axis=1), 4)

if kind == "make":
    p = path(lines)
    with open(program, "w") as fh:
        fh.write("%\n(benchmark program)\nG21 G90 G17 G94\nG0 X0 Y0 Z800 A0 B0 C0\nG1 F1000\n")
        for lo in range(0, lines, 10_000):
            parts = []
            for k in range(lo, min(lo + 10_000, lines - 7)):
                if k % 500 == 499:
                    parts.append("G2 I0.5 J0 (circle)\n")
                elif k % 100 == 99:
                    parts.append("(a comment between moves)\n")
                else:
                    parts.append("G1 X%.4f Y%.4f Z%.4f A%.4f B%.4f C%.4f\n" % tuple(p[k]))
            fh.write("".join(parts))
        fh.write("M2\n%\n")
    print(json.dumps({}))
    sys.exit()

def begin():
    global start, cpu0
    start, cpu0 = time.perf_counter(), sum(resource.getrusage(resource.RUSAGE_SELF)[:2])

begin()
count = 0
if kind in ("filter", "tenth"):
    from hexcal.cli.main import main
    from hexcal.io import gcode
    if kind == "tenth":
        with open(program) as fh, open(out + ".in", "w") as part:
            for k, line in zip(range(lines // 10), fh):
                part.write(line)
            part.write("M2\n")
        program = out + ".in"
        begin()
    status = main(["compensate", "--geometry", "paper-hmt-true", "--nominal", "paper-hmt",
                   "--gcode", program, "--out", out, "--quiet"])
    assert status == 0
    with open(program) as fh:
        count = sum(1 for _ in fh)
elif kind in ("kinematics", "path", "read"):
    from hexcal.core import compensate, correct_path, correct_poses, preset
    from hexcal.io import read_program
    from hexcal.io.gcode import BLOCK_LINES
    real, nominal = preset("paper-hmt-true"), preset("paper-hmt")
    home = np.array([0.0, 0.0, 800.0, 0.0, 0.0, 0.0])
    if kind == "kinematics":
        targets = path(lines)
        targets[:, 3:] = np.radians(targets[:, 3:])
        begin()
        for lo in range(0, lines, BLOCK_LINES):
            compensate(real, targets[lo : lo + BLOCK_LINES], nominal=nominal)
        count = lines
    else:
        blocks = list(read_program(program, home)) if kind == "path" else None
        begin()
        if kind == "read":
            for block in read_program(program, home):
                count += len(block.lines)
        else:
            last = correct_poses(real, nominal, home[None], np.array([0]))[0]
            for block in blocks:
                result = correct_path(real, nominal, block.moves, last, 1e-3, 1e-5)
                last = result.corrected[-1] if len(result.corrected) else last
                count += len(block.lines)
else:  # import: the floor of the memory
    import scipy.spatial.transform  # noqa: F401
    import hexcal.core, hexcal.io  # noqa: F401
seconds = time.perf_counter() - start
usage = resource.getrusage(resource.RUSAGE_SELF)
cpu = usage.ru_utime + usage.ru_stime - cpu0
print(json.dumps({"lines": count, "seconds": seconds, "cpu": cpu, "peak_bytes": usage.ru_maxrss * 1024}))
"""


def _child(kind: str, program: Path, out: Path, lines: int) -> dict:
    done = subprocess.run(
        [sys.executable, "-c", CHILD, kind, str(program), str(out), str(lines)],
        check=True,
        capture_output=True,
        text=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lines", type=int, default=1_000_000)
    parser.add_argument("--quick", action="store_true", help="100,000 lines, a smoke run")
    args = parser.parse_args()
    lines = 100_000 if args.quick else args.lines
    print(f"load average {os.getloadavg()[0]:.1f}; {lines:,} lines")
    with tempfile.TemporaryDirectory() as tmp:
        program, out = Path(tmp) / "program.ngc", Path(tmp) / "filtered.ngc"
        _child("make", program, out, lines)
        figures = {}
        for kind, label in (
            ("filter", "hexcal compensate --gcode (whole command)"),
            ("tenth", "the same, first tenth of the program"),
            ("kinematics", "kinematics alone: compensate() of every target"),
            ("path", "correct_path(): kinematics + midpoint checks"),
            ("read", "read_program(): parsing alone"),
            ("import", "import hexcal, numpy, scipy"),
        ):
            fig = figures[kind] = _child(kind, program, out, lines)
            if kind == "filter":
                written = sum(1 for _ in out.open())
                fig["written"] = written
            rate = f"{fig['lines'] / fig['seconds']:,.0f} lines/s, " if fig.get("lines") else ""
            print(
                f"{label}: {fig['seconds']:.1f} s wall ({fig['cpu']:.1f} s CPU), {rate}"
                f"peak RSS {fig['peak_bytes'] / 2**20:.0f} MiB"
            )
    f, k = figures["filter"], figures["kinematics"]
    print(f"output: {f['written']:,} lines for {f['lines']:,} read")
    print(
        f"ratios (one run): filter time / kinematics time {f['cpu'] / k['cpu']:.2f} (CPU), "
        f"{f['seconds'] / k['seconds']:.2f} (wall); filter / path {f['cpu'] / figures['path']['cpu']:.2f}; "
        f"parsing / filter {figures['read']['cpu'] / f['cpu']:.2f}"
    )
    print(
        f"memory: filter peak / import peak {f['peak_bytes'] / figures['import']['peak_bytes']:.2f}, "
        f"filter peak / first-tenth peak {f['peak_bytes'] / figures['tenth']['peak_bytes']:.2f} "
        "(1.0: bounded by a block, not by the program)"
    )


if __name__ == "__main__":
    main()
