"""Scale figures of issue 12, as ratios to baselines timed in the same run.

Run ``python benchmarks/scale.py`` (a few minutes; ``--quick`` for a smoke run, not judged).

- ``scale.paper``: wall time of ``hexcal paper --trials 1000 --quiet`` (all its rows: 4
  identifications per trial, with simulation, validation and bounds; a subprocess of the
  console script, default ``--jobs`` and ``--jobs 1``) against straightforward scipy code
  (:mod:`scipy_baseline`: finite differences, a loop per pose and trial) timed on a sample of
  the same kind of data and scaled to the same number of identifications; the ML rows are
  counted at the cost of the baseline's paper estimator, which favours the baseline.
  Target >= 50x.
- ``scale.dask``: a study (:func:`hexcal.simulation.run_study`, paper and length
  estimators, interior and corner poses, 10 and 15 poses, 1000 trials) on a local Dask cluster of one,
  then two single-threaded worker processes, and in this process: the same numbers
  everywhere (compared bit for bit), and the throughput of two workers over one.
  Target >= 1.6x.

Batched identification rates: ``benchmarks/batched.py``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from batched import simulated_trials
from hexcal.core import preset
from hexcal.estimation import estimate_batch
from hexcal.simulation import run_study
from hexcal.simulation.dask_executor import dask_executor
from scipy_baseline import identify_all


def load() -> str:
    return ", ".join(f"{v:.2f}" for v in os.getloadavg())


def hexcal_executable() -> str:
    return str(Path(sys.executable).with_name("hexcal"))


def children_cpu() -> float:
    """CPU seconds of the finished child processes (and their waited-for descendants)."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def time_baseline(sample: int) -> tuple[float, float, float]:
    """``(wall, cpu, max difference)`` per identification of the scipy baseline."""
    nominal = preset("paper-hmt")
    readings, poses = simulated_trials(sample, seed=sample)
    c0, w0 = time.process_time(), time.perf_counter()
    values = identify_all(nominal, poses, readings)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    diff = float(np.max(np.abs(values - estimate_batch(nominal, readings, poses, "paper").values)))
    return wall / sample, cpu / sample, diff


def bench_paper(trials: int, sample: int) -> None:
    identifications = 4 * trials  # interior, boundary, boundary_ml, selected_ml
    # the baseline before and after the hexcal runs: the load of a shared machine drifts
    before = time_baseline(sample)
    runs = {}
    for label, extra in (("default --jobs", []), ("--jobs 1", ["--jobs", "1"])):
        cmd = [hexcal_executable(), "paper", "--trials", str(trials), "--quiet", *extra]
        c0, w0 = children_cpu(), time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True)
        runs[label] = (time.perf_counter() - w0, children_cpu() - c0)
    after = time_baseline(sample)
    wall, cpu = (before[0] + after[0]) / 2, (before[1] + after[1]) / 2
    print(
        f"scale.baseline: scipy {wall * 1e3:.0f} ms wall, {cpu * 1e3:.0f} ms CPU per identification "
        f"({2 * sample} timed, before and after; max |scipy - hexcal| {max(before[2], after[2]):.1e} mm) "
        f"-> {wall * identifications:.0f} s wall, {cpu * identifications:.0f} s CPU for {identifications}"
    )
    for label, (run_wall, run_cpu) in runs.items():
        ratio, cpu_ratio = wall * identifications / run_wall, cpu * identifications / run_cpu
        verdict = "PASS" if ratio >= 50 else "MISS"
        print(
            f"scale.paper ({label}): hexcal paper --trials {trials} {run_wall:.1f} s wall, "
            f"{run_cpu:.1f} s CPU | ratio {ratio:.0f}x wall (baseline one process), {cpu_ratio:.0f}x CPU "
            f"| target >= 50x: {verdict}"
        )


def bench_dask(trials: int, repeats: int) -> None:
    from distributed import LocalCluster

    nominal, true = preset("paper-hmt"), preset("paper-hmt-true")
    study = {"methods": ("paper", "length"), "pose_counts": (10, 15), "trials": trials, "rng": 1}
    start = time.perf_counter()
    local = json.dumps(run_study(nominal, true, jobs=1, **study).to_dict())
    local_wall = time.perf_counter() - start
    print(f"scale.dask.local: this process {local_wall:.1f} s ({trials} trials, 8 cells)")
    options = {"threads_per_worker": 1, "processes": True, "dashboard_address": ":0", "silence_logs": 50}
    walls: dict[int, list[float]] = {1: [], 2: []}
    same = True
    with (
        LocalCluster(n_workers=1, **options) as one,
        LocalCluster(n_workers=2, **options) as two,
        dask_executor(one.scheduler_address) as on_one,
        dask_executor(two.scheduler_address) as on_two,
    ):
        warm_up = {**study, "trials": 8}  # the workers import hexcal and numpy once
        for executor, n in ((on_one, 1), (on_two, 2)):
            executor.client.wait_for_workers(n)
            run_study(nominal, true, executor=executor, **warm_up)
        # alternate the runs and keep each one's best: the load of a shared machine drifts
        for _ in range(repeats):
            for workers, executor in ((1, on_one), (2, on_two)):
                start = time.perf_counter()
                remote = json.dumps(run_study(nominal, true, executor=executor, **study).to_dict())
                walls[workers].append(time.perf_counter() - start)
                same &= remote == local
    for workers, times in walls.items():
        print(
            f"scale.dask.{workers}_worker: best {min(times):.1f} s of {len(times)} "
            f"({', '.join(f'{t:.1f}' for t in times)}), {trials / min(times):.1f} trials/s"
        )
    speedup = min(walls[1]) / min(walls[2])
    verdict = "PASS" if speedup >= 1.6 else "MISS"
    print(
        "scale.dask.same_numbers: JSON of every cluster run "
        f"{'identical' if same else 'DIFFERENT'} to the local run"
    )
    print(f"scale.dask.speedup: two workers / one {speedup:.2f}x | target >= 1.6x: {verdict}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes (a smoke run, not judged)")
    parser.add_argument("--only", choices=("paper", "dask"), help="one group")
    args = parser.parse_args()
    print(f"load average {load()} on {os.cpu_count()} cores; BLAS threads pinned to 1 in this process")
    if args.only in (None, "paper"):
        bench_paper(50 if args.quick else 1000, 2 if args.quick else 8)
    if args.only in (None, "dask"):
        bench_dask(40 if args.quick else 1000, 1 if args.quick else 3)
    print(f"load average {load()} at the end")


if __name__ == "__main__":
    main()
