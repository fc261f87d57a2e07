"""Generalised least squares (``"gls"``): leg residuals whitened by their propagated covariance.

The leg residuals at the measured platform poses, whitened by
``C_j = J_j Σ_P,j J_jᵀ + σ_leg² I`` (``J_j`` the pose Jacobian of the legs, ``Σ_P,j`` the
covariance of the platform pose the instrument gives: its noise mapped through the inverse
of its pose Jacobian, the noise itself for the full pose), recomputed once at the first
estimate. To first order it is the same estimator as maximum likelihood
(:mod:`hexcal.estimation.likelihood`), and five times cheaper. It needs instruments whose
observation determines the pose.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.kinematics import pose_jacobian
from hexcal.core.linalg import whitening
from hexcal.core.noise import NoiseModel
from hexcal.estimation.covariance import finish_result
from hexcal.estimation.least_squares import fit_least_squares, solve_least_squares
from hexcal.estimation.problem import Problem, session_noises
from hexcal.estimation.result import IdentificationResult, rms
from hexcal.estimation.uncertainty import LEG_SIGMA_FLOOR


def _noises(problem: Problem, noise: NoiseModel | Sequence[NoiseModel] | None) -> tuple[NoiseModel, ...]:
    return session_noises(problem, noise)  # the one rule of per-session noise


def pose_covariances(problem: Problem, noises: Sequence[NoiseModel]) -> NDArray[np.float64]:
    """Covariance ``(m, 6, 6)`` of each measured platform pose (the instrument's noise through
    its inverse pose Jacobian; the noise itself for the full pose)."""
    poses = problem.measured_poses()
    return np.concatenate(
        [
            p.instrument.platform_covariance(problem.full0[p.block], poses[p.rows], n, problem.euler)
            for p, n in zip(problem.parts, noises, strict=True)
        ]
    )


def residual_weights(problem: Problem, full: NDArray[np.float64], noises: Sequence[NoiseModel]) -> NDArray:
    """Whitening matrices ``(m, 6, 6)`` of the leg residuals at the parameters ``full``."""
    poses = problem.measured_poses()
    jac = pose_jacobian(problem.geometry(full), poses)
    legs = np.concatenate(
        [
            np.full(len(p), max(n.sigmas[0], LEG_SIGMA_FLOOR))
            for p, n in zip(problem.parts, noises, strict=True)
        ]
    )
    cov = np.einsum("mik,mkl,mjl->mij", jac, pose_covariances(problem, noises), jac)
    return whitening(cov + legs[:, None, None] ** 2 * np.eye(6))


def solve_gls(
    problem: Problem,
    noise: NoiseModel | Sequence[NoiseModel] | None,
    rounds: int = 2,
    xtol: float = 1e-10,
    check: bool = True,
) -> tuple[NDArray[np.float64], Any, float]:
    """The GLS iterations: ``(x, last solver result, RMS before)``."""
    noises = _noises(problem, noise)
    x = np.zeros(problem.n_free)
    sol, rms_before = None, 0.0
    for k in range(max(1, rounds)):
        w = residual_weights(problem, problem.unpack(x), noises)
        fun, jac = problem.least_squares_functions("length", weights=w)
        if k == 0:
            if check:
                problem.check_rank(jac(x))
            rms_before = rms(fun(x))
        sol = solve_least_squares(fun, jac, x, xtol=xtol)
        x = sol.x
    return x, sol, rms_before


def fit_gls(
    problem: Problem,
    noise: NoiseModel | Sequence[NoiseModel] | None = None,
    rounds: int = 2,
    xtol: float = 1e-10,
    **_: Any,
) -> IdentificationResult:
    """Generalised least squares; ``rounds`` fits, the weights recomputed at each estimate.

    Returns an :class:`~hexcal.estimation.result.IdentificationResult` with whitened
    residuals of shape ``(m, 6)``.
    """
    problem.check_size()
    noises = _noises(problem, noise)
    if not any(n.has_pose_noise or n.sigmas[0] != 0 for n in noises):
        return fit_least_squares(problem, "length").replace(method="gls")
    x, sol, rms_before = solve_gls(problem, noises, rounds, xtol, check=True)
    return finish_result(problem, "gls", problem.unpack(x), sol.fun, sol.jac, rms_before, sol, noises=noises)
