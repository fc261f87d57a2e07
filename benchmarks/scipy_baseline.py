"""Straightforward scipy code for the seed paper's identification: the baseline of issue 12.

What one would write without hexcal: the paper's residual (squared leg length from the pose
minus squared leg length from the reading) in a Python loop over the poses,
``scipy.optimize.least_squares`` with its default finite-difference Jacobian (2-point), and a
loop over trials. ``python benchmarks/scipy_baseline.py`` identifies a few simulated trials
(15 noisy random corners of paper-hmt measured on paper-hmt-true, the paper's noise) and
prints the time per identification and the largest difference to hexcal's batched solver;
``benchmarks/scale.py`` times it beside ``hexcal paper``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse
import time

import numpy as np
from scipy.optimize import least_squares

from hexcal.core.geometry import Geometry
from hexcal.core.presets import preset


def rotation(a: float, b: float, c: float) -> np.ndarray:
    """The rotation of intrinsic x-y-z Euler angles (paper-hmt's ``XYZ``)."""
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    rz = np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]])
    return rx @ ry @ rz


def paper_residuals(x: np.ndarray, poses: np.ndarray, readings: np.ndarray) -> np.ndarray:
    """``|o + R s_i - u_i|^2 - (l0_i + q_i)^2`` of every pose and leg, a loop over the poses.

    ``x`` holds ``u1..u6`` (18), ``s1..s6`` (18) and ``l0_1..l0_6`` (6), gains 1.
    """
    u, s, l0 = x[:18].reshape(6, 3), x[18:36].reshape(6, 3), x[36:42]
    out = np.empty((len(poses), 6))
    for k, (pose, q) in enumerate(zip(poses, readings, strict=True)):
        rot = rotation(*pose[3:])
        legs = pose[:3] + s @ rot.T - u
        out[k] = np.sum(legs**2, axis=1) - (l0 + q) ** 2
    return out.ravel()


def identify(nominal: Geometry, poses: np.ndarray, readings: np.ndarray) -> np.ndarray:
    """The 42 joint and ``l0`` parameters of one data set, from the nominal values."""
    if nominal.euler != "XYZ":
        raise ValueError(f"the baseline implements the XYZ Euler sequence, not {nominal.euler}")
    x0 = nominal.to_vector()[:42]
    fit = least_squares(paper_residuals, x0, args=(poses, readings), method="lm")
    return fit.x


def identify_all(nominal: Geometry, poses: np.ndarray, readings: np.ndarray) -> np.ndarray:
    """A loop over trials: ``(T, 42)``."""
    return np.array([identify(nominal, p, q) for p, q in zip(poses, readings, strict=True)])


def main() -> None:
    import sys

    sys.path.insert(0, os.path.dirname(__file__))
    from batched import simulated_trials
    from hexcal.estimation.batched import estimate_batch

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=20)
    args = parser.parse_args()
    nominal = preset("paper-hmt")
    readings, poses = simulated_trials(args.trials)
    start = time.perf_counter()
    values = identify_all(nominal, poses, readings)
    per = (time.perf_counter() - start) / args.trials
    batched = estimate_batch(nominal, readings, poses, "paper").values
    print(
        f"scipy baseline: {per * 1e3:.1f} ms per identification ({args.trials} trials); "
        f"max |baseline - hexcal batched| {np.max(np.abs(values - batched)):.1e} mm"
    )


if __name__ == "__main__":
    main()
