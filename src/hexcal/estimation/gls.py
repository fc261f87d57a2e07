"""Generalised least squares (``"gls"``): leg residuals whitened by their propagated covariance.

The leg residuals at the measured platform poses, whitened by
``C_j = J_j Σ_P,j J_jᵀ + σ_leg² I`` (``J_j`` the pose Jacobian of the legs, ``Σ_P,j`` the
covariance of the platform pose the instrument gives: its noise mapped through the inverse
of its pose Jacobian, the noise itself for the full pose), recomputed once at the first
estimate. To first order it is the same estimator as maximum likelihood
(:mod:`hexcal.estimation.likelihood`), and five times cheaper. It needs instruments whose
observation determines the pose. The fits are the one least-squares solver's
(:func:`hexcal.estimation.least_squares.solve_whitened`, a stack of one).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.kinematics import pose_jacobian_from_arrays
from hexcal.core.linalg import whitening
from hexcal.core.noise import NoiseModel
from hexcal.estimation.covariance import finish_result
from hexcal.estimation.equations import LEG_SIGMA_FLOOR
from hexcal.estimation.least_squares import converged_or_raise, fit_least_squares, solve_legs, solve_whitened
from hexcal.estimation.levenberg import (
    STATUS_CONVERGED,
    STATUS_MAX_ITER,
    STATUS_NONFINITE,
    STATUS_RANK_DEFICIENT,
    Convergence,
)
from hexcal.estimation.problem import Problem, session_noises
from hexcal.estimation.result import IdentificationResult, rms
from hexcal.estimation.stacked import Stack


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


def leg_weights(
    joints: NDArray[np.float64],
    poses: NDArray[np.float64],
    pose_covariance: NDArray[np.float64],
    leg_sigma: NDArray[np.float64],
    euler: str,
) -> NDArray[np.float64]:
    """Whitening matrices ``(..., m, 6, 6)`` of the leg residuals at measured ``poses``
    ``(..., m, 6)`` of pose covariance ``(..., m, 6, 6)`` for joint blocks ``(..., 36)`` and the
    leg σ ``(..., m)``: ``W`` with ``Wᵀ W = (J Σ_P Jᵀ + σ_leg² I)⁻¹`` (batch-first)."""
    lead = np.shape(joints)[:-1]
    u = joints[..., :18].reshape(*lead, *(1,) * (poses.ndim - 1 - len(lead)), 6, 3)
    s = joints[..., 18:36].reshape(u.shape)
    _, jac = pose_jacobian_from_arrays(u, s, poses, euler)
    cov = jac @ pose_covariance @ np.swapaxes(jac, -1, -2)
    return whitening(cov + leg_sigma[..., None, None] ** 2 * np.eye(6))


def _leg_sigmas(parts: Sequence[Any], noises: Sequence[NoiseModel]) -> NDArray[np.float64]:
    return np.concatenate(
        [np.full(len(p), max(n.sigmas[0], LEG_SIGMA_FLOOR)) for p, n in zip(parts, noises, strict=True)]
    )


def residual_weights(problem: Problem, full: NDArray[np.float64], noises: Sequence[NoiseModel]) -> NDArray:
    """Whitening matrices ``(m, 6, 6)`` of the leg residuals at the parameters ``full``."""
    legs = _leg_sigmas(problem.parts, noises)
    return leg_weights(
        full[problem.joints], problem.measured_poses(), pose_covariances(problem, noises), legs, problem.euler
    )


def stack_weights(stack: Stack, full: NDArray[np.float64], noises: Sequence[NoiseModel]) -> NDArray:
    """Whitening matrices ``(T, m, 6, 6)`` of every trial's leg residuals at ``full`` ``(T, N)``."""
    poses, covariances, legs = [], [], []
    for part, noise in zip(stack.parts, noises, strict=True):
        setup = stack.full0[:, part.block]
        measured = part.instrument.platform_from(setup, part.observed, stack.euler)
        poses.append(measured)
        covariances.append(part.instrument.platform_covariance(setup, measured, noise, stack.euler))
        legs.append(np.full(part.readings.shape[:2], max(noise.sigmas[0], LEG_SIGMA_FLOOR)))
    return leg_weights(
        full[:, stack.joints],
        np.concatenate(poses, axis=1),
        np.concatenate(covariances, axis=1),
        np.concatenate(legs, axis=1),
        stack.euler,
    )


def solve_stack_gls(
    stack: Stack,
    noises: Sequence[NoiseModel],
    alive: NDArray[np.bool_] | None = None,
    rounds: int = 2,
    xtol: float = 1e-10,
    max_iter: int = 100,
) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray, NDArray | None]:
    """Generalised least squares of every trial of a stack (``rounds`` fits, the weights at each
    estimate): ``(full, status, iterations, cost, rank, the last fit's weights)``; ``length``
    (and no weights) where there is no noise."""
    from hexcal.estimation.least_squares import leg_rank

    if not any(n.has_pose_noise or n.sigmas[0] != 0 for n in noises):
        return (*solve_legs(stack, "length", alive, xtol, max_iter), None)
    t = len(stack)
    alive = np.ones(t, dtype=bool) if alive is None else np.asarray(alive, dtype=bool)
    rank = leg_rank(stack)
    alive = alive & (rank >= stack.mask[stack.machine].sum())
    full = np.array(stack.full0)
    status = np.where(alive, STATUS_MAX_ITER, STATUS_NONFINITE)
    status[~alive & (rank < stack.mask[stack.machine].sum())] = STATUS_RANK_DEFICIENT
    iterations, cost = np.zeros(t, dtype=int), np.full(t, np.nan)
    for _ in range(max(1, rounds)):
        weights = stack_weights(stack, full, noises)
        solved, round_status, used, cost = solve_whitened(stack, weights, full, alive, xtol, max_iter)
        full = np.where(alive[:, None], solved, full)
        status = np.where(alive, round_status, status)
        iterations += np.where(alive, used, 0)
        alive &= round_status == STATUS_CONVERGED
    return full, status, iterations, cost, rank, weights


def solve_gls(
    problem: Problem,
    noise: NoiseModel | Sequence[NoiseModel] | None,
    rounds: int = 2,
    xtol: float = 1e-10,
    check: bool = True,
    max_iter: int = 100,
) -> tuple[NDArray[np.float64], Convergence, float, NDArray[np.float64]]:
    """The GLS iterations: ``(x, the last solve, RMS before, the last weights)``."""
    noises = _noises(problem, noise)
    stack = Stack.of_problem(problem)
    full = np.array(problem.full0)
    x = np.zeros(problem.n_free)
    sol, rms_before, w = None, 0.0, None
    for k in range(max(1, rounds)):
        w = residual_weights(problem, full, noises)
        if k == 0:
            fun, jac = problem.least_squares_functions("length", weights=w)
            if check:
                problem.check_rank(jac(x))
            rms_before = rms(fun(x))
        solved, status, iterations, cost = solve_whitened(
            stack, w[None], full[None], xtol=xtol, max_iter=max_iter
        )
        converged_or_raise(int(status[0]))
        full = solved[0]
        sol = Convergence(status[0], iterations[0], cost[0])
        x = (full[problem.mask] - problem.full0[problem.mask]) / problem.scale
    return x, sol, rms_before, w


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
    x, sol, rms_before, w = solve_gls(problem, noises, rounds, xtol, check=True)
    fun, jac = problem.least_squares_functions("length", weights=w)  # the last fit's weights
    return finish_result(problem, "gls", problem.unpack(x), fun(x), jac(x), rms_before, sol, noises=noises)
