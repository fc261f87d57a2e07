"""Benchmark of ballbar calibration (issue 21): planning, speed, Monte Carlo against the bound.

Run ``python benchmarks/ballbar.py`` (``--trials N``, default 200; ``--quick`` for 40). The
campaigns are those of ``tests/ballbar_cases.py``: a 150 mm bar, its ball 50 mm under the
platform, circles of 12 points chosen by ``select_circles`` (24 calibration circles, the next
6 at the same pivots held out), legs σ 2 µm and the bar's reading σ 1 µm (normal), on the
seed paper's machine (presets paper-hmt / paper-hmt-true) and on an irregular 6-6 machine.
It prints

1. planning: for 6 to 36 circles chosen on each machine, the pivots used, the rank beyond the
   gauges and the predicted platform pose error after calibration (the README's question:
   how many circles and pivots for a given accuracy);
2. speed: one ballbar identification of the paper campaign (24 circles, 288 poses), best of
   3, as a ratio to the full-pose maximum-likelihood fit of the same commanded poses timed in
   this run;
3. Monte Carlo over ``--trials`` noise draws per machine: the RMS error of the held-out
   circles' bar readings predicted from the leg readings (forward kinematics with the
   identified machine and bar) against their true values, as a ratio to what the Cramér–Rao
   bound at the truth predicts for it, with the ratio's Monte Carlo standard error (target:
   within a few percent of 1).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # single core, set before numpy loads

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from hexcal.design.ballbar_plan import ballbar_circles
from hexcal.design.ballbar_selection import circle_accuracy, select_circles
from hexcal.simulation import simulate_session

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from ballbar_cases import NOISE, SETUP, TILT, campaign, fit, machines, monte_carlo, sessions

CIRCLE_COUNTS = (6, 12, 18, 24, 36)


def planning() -> None:
    print("planning (legs σ 2 µm, bar σ 1 µm; predicted after calibration, up to the frames):")
    print(f"  {'machine':8} {'circles':>7} {'poses':>5} {'pivots':>6} {'identifiable':>12} "
          f"{'position RMS mm':>15} {'worst mm':>8} {'orient. RMS mrad':>16}")  # fmt: skip
    for kind in ("paper", "general"):
        nominal, _ = machines(kind)
        candidates, dropped = ballbar_circles(nominal, SETUP, tilt=TILT, points=12)
        for n in CIRCLE_COUNTS:
            chosen = select_circles(nominal, candidates, n, NOISE)
            acc = circle_accuracy(nominal, chosen.circles, NOISE)
            ok = "yes" if acc["identifiable"] else "NO"
            print(f"  {kind:8} {n:7d} {acc['circle_poses']:5d} {acc['pivots']:6d} {ok:>12} "
                  f"{acc['position_rms_mm']:15.4f} {acc['position_max_mm']:8.4f} "
                  f"{1e3 * acc['orientation_rms_rad']:16.3f}")  # fmt: skip
        print(
            f"  ({kind}: {candidates.n_circles} feasible candidate circles at 7 pivots, {dropped} infeasible)"
        )


def best_of(n: int, call) -> float:
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        call()
        times.append(time.perf_counter() - t0)
    return min(times)


def speed() -> None:
    c = campaign("paper")
    data = sessions(c, c.circles, NOISE, 1)
    full = simulate_session(c.nominal, c.true, None, c.circles.poses, NOISE, 2)
    fit(c, data)  # warm up (imports)
    bar = best_of(3, lambda: fit(c, data))
    base = best_of(3, lambda: fit(c, [full]))
    print(f"speed: ballbar identification, {len(c.circles.poses)} poses at {len(c.pivots)} pivot(s): "
          f"{bar:.3f} s; full-pose ml of the same poses {base:.3f} s (ratio {bar / base:.1f})")  # fmt: skip


def report(kind: str, trials: int) -> None:
    t0 = time.perf_counter()
    out = monte_carlo(kind, trials)
    print(
        f"{kind}: {len(out['ms'])} trials ({out['failed']} failed), {out['circles']} circles at "
        f"{out['pivots']} pivot(s), {out['held']} held out, {out['parameters']} parameters, "
        f"{time.perf_counter() - t0:.0f} s\n"
        f"  held-out bar readings predicted from the legs: RMS {1e3 * np.sqrt(out['ms'].mean()):.3f} µm, "
        f"Cramér–Rao {1e3 * np.sqrt(out['bound']):.3f} µm, ratio {out['ratio']:.3f} ± {out['ratio_se']:.3f} "
        f"(target: within a few percent of 1)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=200)
    parser.add_argument("--quick", action="store_true", help="40 trials")
    args = parser.parse_args()
    trials = 40 if args.quick else args.trials
    planning()
    speed()
    for kind in ("paper", "general"):
        report(kind, trials)


if __name__ == "__main__":
    main()
