"""Generalised least squares (``"gls"``): leg residuals whitened by their propagated covariance.

The leg residuals at the measured poses, whitened by ``C_j = J_j Σ_pose J_jᵀ + σ_leg² I``
(:func:`hexcal.estimation.bounds.residual_covariances`), recomputed once at the first
estimate. To first order it is the same estimator as maximum likelihood
(:mod:`hexcal.estimation.likelihood`), and five times cheaper.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.linalg import whitening
from hexcal.core.noise import NoiseModel
from hexcal.estimation.bounds import LEG_SIGMA_FLOOR, residual_covariances
from hexcal.estimation.least_squares import fit_least_squares, solve_least_squares
from hexcal.estimation.problem import Problem
from hexcal.estimation.result import IdentificationResult, finish_result, rms


def solve_gls(
    problem: Problem, noise: NoiseModel, rounds: int = 2, xtol: float = 1e-10, check: bool = True
) -> tuple[NDArray[np.float64], Any, float]:
    """The GLS iterations: ``(x, last solver result, RMS before)``."""
    floor = NoiseModel(
        leg=max(noise.sigmas[0], LEG_SIGMA_FLOOR), distribution="normal", pose_covariance=noise.pose_cov()
    )
    poses = problem.measured_poses()
    x = np.zeros(problem.n_free)
    sol, rms_before = None, 0.0
    for k in range(max(1, rounds)):
        w = whitening(residual_covariances(problem.geometry(problem.unpack(x)), poses, floor))
        fun, jac = problem.least_squares_functions("length", weights=w)
        if k == 0:
            if check:
                problem.check_rank(jac(x))
            rms_before = rms(fun(x))
        sol = solve_least_squares(fun, jac, x, xtol=xtol)
        x = sol.x
    return x, sol, rms_before


def fit_gls(
    problem: Problem, noise: NoiseModel | None = None, rounds: int = 2, xtol: float = 1e-10, **_: Any
) -> IdentificationResult:
    """Generalised least squares; ``rounds`` fits, the weights recomputed at each estimate.

    Returns an :class:`~hexcal.estimation.result.IdentificationResult` with whitened
    residuals of shape ``(m, 6)``.
    """
    noise = NoiseModel() if noise is None else noise
    problem.check_size()
    if not noise.has_pose_noise and noise.sigmas[0] == 0:
        return fit_least_squares(problem, "length").replace(method="gls")
    x, sol, rms_before = solve_gls(problem, noise, rounds, xtol, check=True)
    return finish_result(problem, "gls", problem.unpack(x), sol.fun, sol.jac, rms_before, sol)
