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
  estimators, interior and corner poses, 10 and 15 poses) on a local Dask cluster of one,
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
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from batched import simulated_trials
from scipy_baseline import identify_all

from hexcal.core import preset
from hexcal.estimation import estimate_batch
from hexcal.simulation import run_study
from hexcal.simulation.dask_executor import dask_executor


def load() -> str:
    return ", ".join(f"{v:.2f}" for v in os.getloadavg())


def hexcal_executable() -> str:
    return str(Path(sys.executable).with_name("hexcal"))


def bench_paper(trials: int, sample: int) -> None:
    nominal = preset("paper-hmt")
    readings, poses = simulated_trials(sample)
    start = time.perf_counter()
    values = identify_all(nominal, poses, readings)
    per_identification = (time.perf_counter() - start) / sample
    diff = np.max(np.abs(values - estimate_batch(nominal, readings, poses, "paper").values))
    identifications = 4 * trials  # interior, boundary, boundary_ml, selected_ml
    baseline = per_identification * identifications
    print(
        f"scale.baseline: scipy, {per_identification * 1e3:.0f} ms per identification "
        f"({sample} timed; max |scipy - hexcal| {diff:.1e} mm) -> {baseline:.0f} s for "
        f"{identifications} identifications"
    )
    for label, extra in (("default --jobs", []), ("--jobs 1", ["--jobs", "1"])):
        cmd = [hexcal_executable(), "paper", "--trials", str(trials), "--quiet", *extra]
        start = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True)
        wall = time.perf_counter() - start
        ratio = baseline / wall
        verdict = "PASS" if ratio >= 50 else "MISS"
        print(
            f"scale.paper ({label}): hexcal paper --trials {trials} {wall:.1f} s | ratio {ratio:.0f}x "
            f"| target >= 50x: {verdict}"
        )


def bench_dask(trials: int) -> None:
    from distributed import LocalCluster

    nominal, true = preset("paper-hmt"), preset("paper-hmt-true")
    study = {"methods": ("paper", "length"), "pose_counts": (10, 15), "trials": trials, "rng": 1}
    start = time.perf_counter()
    local = json.dumps(run_study(nominal, true, jobs=1, **study).to_dict())
    local_wall = time.perf_counter() - start
    print(f"scale.dask.local: this process {local_wall:.1f} s ({trials} trials, 8 cells)")
    walls = {}
    for workers in (1, 2):
        with LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=50
        ) as cluster, dask_executor(cluster.scheduler_address) as executor:
            executor.submit(pow, 2, 2).result()  # workers up
            start = time.perf_counter()
            remote = json.dumps(run_study(nominal, true, executor=executor, **study).to_dict())
            walls[workers] = time.perf_counter() - start
        same = "identical" if remote == local else "DIFFERENT"
        print(
            f"scale.dask.{workers}_worker: {walls[workers]:.1f} s, "
            f"{trials / walls[workers]:.1f} trials/s; JSON {same} to the local run"
        )
    speedup = walls[1] / walls[2]
    verdict = "PASS" if speedup >= 1.6 else "MISS"
    print(f"scale.dask.speedup: two workers / one {speedup:.2f}x | target >= 1.6x: {verdict}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes (a smoke run, not judged)")
    parser.add_argument("--only", choices=("paper", "dask"), help="one group")
    args = parser.parse_args()
    print(f"load average {load()} on {os.cpu_count()} cores; BLAS threads pinned to 1 in this process")
    if args.only in (None, "paper"):
        bench_paper(50 if args.quick else 1000, 3 if args.quick else 10)
    if args.only in (None, "dask"):
        bench_dask(40 if args.quick else 400)
    print(f"load average {load()} at the end")


if __name__ == "__main__":
    main()
