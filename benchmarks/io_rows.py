"""Reading and writing 10^6 rows (issue 11): time and peak memory of the io layer.

``python benchmarks/io_rows.py [--rows N]`` writes a pose file of N rows (default
1,000,000) and then, each in a fresh subprocess so that the peak resident memory is its own:

- ``ik-style``: the pose file read in blocks (:func:`hexcal.io.iter_poses`), inverse
  kinematics per block, the leg file written block by block (:func:`write_table_blocks`)
  through an :class:`OutputSet`;
- ``fk-style read``: that leg file read in blocks (:func:`hexcal.io.iter_legs`);
- ``whole read``: the pose file read at once (:func:`hexcal.io.read_poses`, identify-style).

Targets (issue 11): ik/fk on 10^6 rows under 20 s and 1 GB. Figures are printed one a line
with PASS/MISS (on the wall time); the CPU time is printed too, as a loaded machine stretches
the wall time.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = r"""
import json, resource, sys, time
import numpy as np
from hexcal.core.presets import preset
from hexcal.core.kinematics import inverse_kinematics, leg_readings
from hexcal.io import OutputSet, iter_legs, iter_poses, read_poses, write_table_blocks
from hexcal.io.measurement_files import LEG_LENGTH_COLUMNS, LEG_READING_COLUMNS

kind, poses_path, legs_path = sys.argv[1:4]
if kind == "make":  # the input, made in a child so that no figure inherits its memory
    from hexcal.io import write_poses
    n = int(sys.argv[4])
    low = np.array([-250, -250, 700, -0.17, -0.17, -0.17])
    poses = np.random.default_rng(0).uniform(low, -low * [1, 1, -9 / 7, 1, 1, 1], (n, 6))
    start = time.perf_counter()
    write_poses(poses_path, poses, ids=[f"p{k}" for k in range(n)])
    print(json.dumps({"seconds": time.perf_counter() - start}))
    sys.exit()
start = time.perf_counter()
cpu0 = sum(resource.getrusage(resource.RUSAGE_SELF)[:2])
rows = 0
if kind == "ik":
    g = preset("paper-hmt")
    def blocks():
        for poses, ids in iter_poses(poses_path, g.euler):
            lengths = inverse_kinematics(g, poses)
            yield np.concatenate([lengths, leg_readings(g, lengths)], axis=1), ids
    with OutputSet([legs_path], inputs=[poses_path]) as out:
        out.check()
        rows = write_table_blocks(legs_path, LEG_LENGTH_COLUMNS + LEG_READING_COLUMNS, blocks(), outputs=out)
elif kind == "baseline":  # a bare pass of the csv module over the file, converting nothing
    import csv
    with open(poses_path, newline="") as fh:
        for row in csv.reader(fh):
            rows += 1
elif kind == "fk":
    for block in iter_legs(legs_path):
        rows += len(block.ids)
else:
    poses, ids = read_poses(poses_path, "XYZ")
    rows = len(ids)
seconds = time.perf_counter() - start
usage = resource.getrusage(resource.RUSAGE_SELF)
cpu = usage.ru_utime + usage.ru_stime - cpu0
print(json.dumps({"rows": rows, "seconds": seconds, "cpu": cpu, "peak_bytes": usage.ru_maxrss * 1024}))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=1_000_000)
    args = parser.parse_args()
    # the parent imports nothing heavy and each figure runs in a fresh child: Linux keeps
    # the peak resident size of a process across exec, so it must stay small here
    with tempfile.TemporaryDirectory() as tmp:
        poses_path, legs_path = Path(tmp) / "poses.csv", Path(tmp) / "legs.csv"
        made = subprocess.run(
            [sys.executable, "-c", CHILD, "make", str(poses_path), str(legs_path), str(args.rows)],
            check=True,
            capture_output=True,
            text=True,
        )
        seconds = json.loads(made.stdout.strip().splitlines()[-1])["seconds"]
        print(f"write {args.rows:,} poses with ids (whole, write_poses): {seconds:.1f} s wall")
        base = None
        for kind, label, limit_s, limit_gb in (
            ("baseline", "baseline: csv.reader pass over the pose file", None, 10.0),
            ("ik", "ik-style blocks read+compute+write", 20, 1.0),
            ("fk", "fk-style blocks read (legs)", 20, 1.0),
            ("whole", "whole read_poses (identify-style)", None, 2.0),
        ):
            done = subprocess.run(
                [sys.executable, "-c", CHILD, kind, str(poses_path), str(legs_path)],
                check=True,
                capture_output=True,
                text=True,
            )
            fig = json.loads(done.stdout.strip().splitlines()[-1])
            gb = fig["peak_bytes"] / 1e9
            base = base or fig["cpu"]
            ratio = f", {fig['cpu'] / base:.1f} x the baseline's CPU"
            ok = gb < limit_gb and (limit_s is None or fig["seconds"] < limit_s)
            target = f"< {limit_s} s and < {limit_gb} GB" if limit_s else f"< {limit_gb} GB"
            print(
                f"{label}: {fig['rows']:,} rows in {fig['seconds']:.1f} s wall ({fig['cpu']:.1f} s CPU), "
                f"peak RSS {gb:.2f} GB{ratio} "
                f"(target {target}): {'PASS' if ok else 'MISS'}"
            )


if __name__ == "__main__":
    main()
