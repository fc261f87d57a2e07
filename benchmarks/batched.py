"""Batched identification throughput (issue 12): identifications per second per core.

Run ``python benchmarks/batched.py`` (``--quick`` for a smoke run). For the ``paper``
estimator (15 noisy random corners of paper-hmt, 42 parameters; target >= 2,000/s/core) and
maximum likelihood (``ml``, the paper's noise; target >= 500/s/core) it prints the batched
rate beside the one-at-a-time rate (``estimate(..., with_bound=False)`` per data set, the same
data) measured in the same run, and their ratio; also the largest difference of the values.

Rates are per CPU second of this process (``time.process_time``), with BLAS/OpenMP pinned to
one thread (set below, before numpy is imported): on a shared, loaded machine the wall-clock
rate falls with the load while the CPU rate measures the code. Both are printed, with the
load average and ``cpu/wall``; the ratios are the figures to judge.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse
import gc
import time
from collections.abc import Callable

import numpy as np

from hexcal.calibration.identify import estimate
from hexcal.core.kinematics import inverse_kinematics, leg_readings
from hexcal.core.noise import NoiseModel
from hexcal.core.presets import preset
from hexcal.core.workspace import workspace_corners
from hexcal.estimation.batched import estimate_batch
from hexcal.instruments.pose import Measurements

SEED = 20261130
TARGETS = {"paper": 2000.0, "ml": 500.0}  # identifications per second per core


def simulated_trials(trials: int, m: int = 15, seed: int = SEED) -> tuple[np.ndarray, np.ndarray]:
    """Readings and measured poses ``(T, m, 6)``: ``m`` random corners of paper-hmt per trial,
    measured on paper-hmt-true with the paper's noise (leg readings of the true machine at the
    reached pose plus the sensor error, the pose plus the measurement error)."""
    rng = np.random.default_rng(seed)
    nominal, true = preset("paper-hmt"), preset("paper-hmt-true")
    noise = NoiseModel()
    corners = workspace_corners(nominal)
    poses = corners[np.argsort(rng.random((trials, len(corners))), axis=1)[:, :m]]
    readings = leg_readings(true, inverse_kinematics(true, poses)) + noise.leg_errors(rng, (trials, m))
    return readings, poses + noise.pose_errors(rng, (trials, m))


def timed(fn: Callable[[], object]) -> tuple[object, float, float]:
    """``(result, cpu seconds, wall seconds)`` of one call, the garbage collector off."""
    gc.collect()
    gc.disable()
    try:
        c0, w0 = time.process_time(), time.perf_counter()
        out = fn()
        return out, time.process_time() - c0, time.perf_counter() - w0
    finally:
        gc.enable()


def bench(method: str, batched_trials: int, single_trials: int) -> None:
    nominal = preset("paper-hmt")
    readings, poses = simulated_trials(batched_trials)
    estimate_batch(nominal, readings[:20], poses[:20], method)  # warm-up
    batch, b_cpu, b_wall = timed(lambda: estimate_batch(nominal, readings, poses, method))

    def one_at_a_time() -> np.ndarray:
        return np.array(
            [
                estimate(nominal, Measurements(poses[k], readings[k]), method, with_bound=False).values
                for k in range(single_trials)
            ]
        )

    estimate(nominal, Measurements(poses[0], readings[0]), method, with_bound=False)  # warm-up
    single, s_cpu, s_wall = timed(one_at_a_time)
    rate_b, rate_s = batched_trials / b_cpu, single_trials / s_cpu
    diff = float(np.max(np.abs(batch.values[:single_trials] - single)))
    verdict = "PASS" if rate_b >= TARGETS[method] else "MISS"
    print(
        f"batched.{method}: {rate_b:,.0f} /s/core batched ({batched_trials} trials, "
        f"{batched_trials / b_wall:,.0f} /s wall, cpu/wall {b_cpu / b_wall:.2f}; "
        f"{int(batch.converged.sum())} converged, iterations {int(np.median(batch.iterations))} median) | "
        f"{rate_s:,.0f} /s/core one at a time ({single_trials} trials, cpu/wall {s_cpu / s_wall:.2f}) | "
        f"ratio {rate_b / rate_s:.1f}x | target >= {TARGETS[method]:,.0f} /s/core: {verdict} | "
        f"max |batched - one at a time| {diff:.1e} (one-at-a-time default tolerances)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes (a smoke run, not judged)")
    args = parser.parse_args()
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"load average {load} on {os.cpu_count()} cores; BLAS threads pinned to 1")
    sizes = {"paper": (200, 20), "ml": (50, 10)} if args.quick else {"paper": (4000, 300), "ml": (1000, 100)}
    for method, (batched_trials, single_trials) in sizes.items():
        bench(method, batched_trials, single_trials)
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"load average {load} at the end")


if __name__ == "__main__":
    main()
