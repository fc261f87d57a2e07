"""Cramér–Rao bound of any measurement model, with the true poses eliminated.

For observation ``j`` the whitened errors-in-variables equations ``e_j`` of
:meth:`hexcal.estimation.problem.Problem.observation_equations` have the Jacobians ``A_j``
(parameters) and ``B_j`` (the pose, a nuisance). Eliminating the pose projects ``A_j`` onto
the orthogonal complement of ``B_j``'s columns, so the Fisher information of the parameters is

    F = Σ_j A_jᵀ (I - Q_j Q_jᵀ) A_j,        Q_j an orthonormal basis of B_j,

(the same projected Jacobian the maximum-likelihood fit works with). Its pseudo-inverse is
the bound; with gauge freedoms, it is the bound of the gauge-fixed parameters
(:mod:`hexcal.estimation.gauge`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hexcal.core.linalg import floored_whitener, gram_pinv, scaled_svd
from hexcal.core.noise import NoiseModel
from hexcal.estimation.bounds import LEG_SIGMA_FLOOR, POSE_VARIANCE_FLOOR
from hexcal.estimation.gauge import Gauge, gauge_freedoms, gauge_projector
from hexcal.estimation.problem import Problem


def projected_jacobian(
    problem: Problem, noise: NoiseModel, full: NDArray[np.float64], poses: NDArray[np.float64]
) -> NDArray[np.float64]:
    """``(I - Q Qᵀ) A`` stacked over observations, ``(m (6 + k), n_free)``, solver units."""
    sigma = max(noise.sigmas[0], LEG_SIGMA_FLOOR)
    w = floored_whitener(problem.model.covariance(noise), POSE_VARIANCE_FLOOR)
    _, b, a, _ = problem.observation_equations(full, poses, sigma, w, True)
    q, _ = np.linalg.qr(b)
    proj = a - np.matmul(q, np.matmul(q.transpose(0, 2, 1), a))
    return proj.reshape(-1, a.shape[-1])


def gauge_fixed_covariance(
    problem: Problem, jac: NDArray[np.float64], gauge: Gauge, variance: float = 1.0
) -> NDArray[np.float64]:
    """``variance · P (JᵀJ)⁺ Pᵀ`` in parameter units (``jac`` in solver units)."""
    proj = gauge_projector(gauge)
    cov = proj @ gram_pinv(scaled_svd(jac)) @ proj.T
    return variance * cov * np.outer(problem.scale, problem.scale)


def model_cramer_rao(
    problem: Problem,
    noise: NoiseModel,
    full: NDArray[np.float64] | None = None,
    poses: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """Cramér–Rao covariance ``(n_free, n_free)`` of the varied parameters (parameter units),
    gauge-fixed by the convention of :mod:`hexcal.estimation.gauge`.

    Parameters
    ----------
    problem : Problem
    noise : NoiseModel
    full : ndarray, shape (n_all,), optional
        Parameter values (default the problem's start values).
    poses : ndarray, shape (m, 6), optional
        True poses (default the model's start poses).
    """
    full = problem.full0 if full is None else full
    if poses is None:
        poses = problem.model.start_poses(problem.start, problem.setup(full), problem.data)
    jac = projected_jacobian(problem, noise, full, poses)
    return gauge_fixed_covariance(problem, jac, gauge_freedoms(problem, full))


def information_blocks(
    problem: Problem, noise: NoiseModel, full: NDArray[np.float64], poses: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Per-observation Fisher information ``A_jᵀ (I - Q_j Q_jᵀ) A_j``, shape ``(m, n_free, n_free)``
    (solver units; their sum is the information of the whole set, for pose selection)."""
    jac = projected_jacobian(problem, noise, full, poses).reshape(len(poses), -1, problem.n_free)
    return np.einsum("mri,mrj->mij", jac, jac)
