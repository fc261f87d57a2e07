"""Monte Carlo of the learned noise (issue 22): the variance components against the truth.

Run ``python benchmarks/noise_learning.py`` (``--trials N``, default 200 per cell; ``--quick``
for 20). For each cell (a machine, a campaign size, a noise ratio) it simulates ``N``
campaigns with normal noise (hexcal's protocol, :func:`hexcal.simulation.simulate_campaigns`:
leg sensor errors, then the true machine's forward kinematics, then the pose measurement
errors), learns the noise of every group with
:func:`hexcal.estimation.noise_estimation.estimate_noise` (the default of ``hexcal identify``)
and prints, per group, the ratio learned / true σ: its mean, the standard error of that mean,
its spread (standard deviation and the 5-95 % range), and the share of the trials that did not
converge and that kept a start value (too little redundancy for the group), or failed.

Machines: the seed paper's (``paper-hmt`` nominal, ``paper-hmt-true`` real) and an irregular
6-6 machine (the tests' ``tracker_cases.general_machines``: paper-hmt's joints moved ~20 mm at
random with seed 7, the real machine ~1 mm from it). Campaigns: 15 and 20 distinct random
corners of the workspace box (the seed paper's campaign), 100 random workspace poses. Noise
(σ, normal): ``leg`` dominated (legs 0.02 mm, position 2 µm, angles 2e-5 rad), ``balanced``
(0.01 mm, 0.01 mm, 1e-4 rad: each about 0.01 mm at the legs) and ``pose`` dominated, the seed
paper's noise as standard deviations (0.01/√3 mm, 0.025/√3 mm, 0.001/√3 rad).

The figures are statistics, not timings; the wall time per fit is printed for scale only.
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

from hexcal.core.geometry import Geometry
from hexcal.core.noise import NoiseModel
from hexcal.core.presets import preset
from hexcal.core.workspace import random_poses, workspace_corners
from hexcal.errors import HexcalError
from hexcal.estimation.noise_estimation import estimate_noise
from hexcal.estimation.problem import Problem
from hexcal.instruments.data import Measurements
from hexcal.simulation.protocol import MachineBatch, simulate_campaigns

# the tests' irregular 6-6 machine (one definition for tests and benchmark)
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from tracker_cases import general_machines

GROUPS = ("leg", "position", "orientation")
NOISES = {
    "leg": NoiseModel(0.02, 0.002, 2e-5, distribution="normal"),
    "balanced": NoiseModel(0.01, 0.01, 1e-4, distribution="normal"),
    "pose": NoiseModel(0.01 / np.sqrt(3), 0.025 / np.sqrt(3), 0.001 / np.sqrt(3), distribution="normal"),
}
POSES = (15, 20, 100)


def machines() -> dict[str, tuple[Geometry, Geometry]]:
    """The machines of the study: name -> (nominal, real)."""
    return {"paper-hmt": (preset("paper-hmt"), preset("paper-hmt-true")), "irregular": general_machines(7)}


def commanded(nominal: Geometry, n: int, trials: int, rng: np.random.Generator) -> np.ndarray:
    """Commanded poses ``(trials, n, 6)``: ``n`` distinct random corners (n <= 20), else random
    workspace poses."""
    if n <= 20:
        corners = workspace_corners(nominal)
        idx = np.argsort(rng.random((trials, len(corners))), axis=1)[:, :n]
        return corners[idx]
    return random_poses(nominal, trials * n, rng).reshape(trials, n, 6)


def run_cell(
    nominal: Geometry, real: Geometry, n: int, noise: NoiseModel, trials: int, seed: int
) -> dict[str, object]:
    """Learned / true σ of every trial of one cell, and the trials' flags."""
    rng = np.random.default_rng(seed)
    poses = commanded(nominal, n, trials, rng)
    machine = MachineBatch.from_geometry(real)
    sensor = noise.leg_errors(rng, (trials, n))
    campaign = simulate_campaigns(nominal, machine, poses, sensor, noise.pose_errors(rng, (trials, n)))
    truth = np.array(noise.sigmas)
    ratio = np.full((trials, 3), np.nan)
    converged = np.zeros(trials, dtype=bool)
    estimated = np.zeros((trials, 3), dtype=bool)
    failed = 0
    start = time.perf_counter()
    for t in range(trials):  # estimate_noise is one fit: a loop over trials
        data = Measurements(campaign.measured[t], campaign.readings[t])
        try:
            est, _ = estimate_noise(Problem(nominal, data))
        except (HexcalError, np.linalg.LinAlgError):
            failed += 1
            continue
        ratio[t] = est.sigmas / truth
        converged[t], estimated[t] = est.converged, est.estimated
    wall = (time.perf_counter() - start) / trials
    return {"ratio": ratio, "converged": converged, "estimated": estimated, "failed": failed, "wall": wall}


def summary(cell: dict[str, object]) -> list[str]:
    """One line per group: mean ± standard error, std, 5-95 %, shares not estimated."""
    ratio = cell["ratio"]
    estimated = cell["estimated"]
    lines = []
    for g, name in enumerate(GROUPS):
        ok = np.isfinite(ratio[:, g]) & estimated[:, g]
        r = ratio[ok, g]
        if r.size < 2:
            lines.append(f"    {name:<12s} (estimated in {r.size} trials)")
            continue
        lo, hi = np.percentile(r, [5, 95])
        lines.append(
            f"    {name:<12s} mean {r.mean():.3f} ± {r.std(ddof=1) / np.sqrt(r.size):.3f}"
            f"   std {r.std(ddof=1):.3f}   5-95 % {lo:.3f}-{hi:.3f}"
            f"   not estimated {1 - ok.mean():.1%}"
        )
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=200)
    parser.add_argument("--quick", action="store_true", help="20 trials per cell (smoke run)")
    parser.add_argument("--seed", type=int, default=22)
    parser.add_argument("--machine", choices=("paper-hmt", "irregular"), action="append")
    parser.add_argument("--poses", type=int, action="append", help=f"campaign sizes (default {POSES})")
    parser.add_argument("--noise", choices=tuple(NOISES), action="append")
    args = parser.parse_args(argv)
    trials = 20 if args.quick else args.trials
    seeds = np.random.SeedSequence(args.seed)
    print(f"learned / true noise σ, {trials} trials per cell, normal noise, seed {args.seed}")
    for mname, (nominal, real) in machines().items():
        for n in POSES:
            for kname, noise in NOISES.items():
                seed = seeds.spawn(1)[0]  # spawned in a fixed order: a cell's draw needs no other cell
                if (args.machine and mname not in args.machine) or (args.poses and n not in args.poses):
                    continue
                if args.noise and kname not in args.noise:
                    continue
                cell = run_cell(nominal, real, n, noise, trials, seed)
                conv = float(np.mean(cell["converged"]))
                print(
                    f"{mname} {n} poses, {kname} noise: not converged {1 - conv:.1%}, "
                    f"failed {cell['failed']}, {cell['wall'] * 1e3:.0f} ms per fit"
                )
                print("\n".join(summary(cell)))
                sys.stdout.flush()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
