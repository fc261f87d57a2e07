"""The Cramér–Rao bound of any identification problem, with the true poses eliminated.

For observation ``j`` the whitened errors-in-variables equations ``e_j`` of
:meth:`hexcal.estimation.problem.Problem.observation_equations` have the Jacobians ``A_j``
(parameters) and ``B_j`` (the pose, a nuisance). Eliminating the pose projects ``A_j`` onto
the orthogonal complement of ``B_j``'s columns, so the Fisher information of the parameters is

    F = Σ_j A_jᵀ (I - Q_j Q_jᵀ) A_j,        Q_j an orthonormal basis of B_j,

(the same projected Jacobian the maximum-likelihood fit works with). Where the instrument's
observation determines the pose (the full pose, or a pose instrument with frame and tool
fixed), the elimination has a closed form: the six leg residuals ``r_j = A_j δθ + J_j e_P +
e_leg`` at the measured pose have the covariance ``C_j = J_j Σ_P J_jᵀ + σ_leg² I`` and
``F = Σ_j A_jᵀ C_j⁻¹ A_j`` (the same information, computed from 6 × 6 blocks; it is also the
covariance of the generalised least-squares estimate). :func:`information_rows` gives the
square root of each observation's share of ``F`` either way; the bound is the pseudo-inverse
of ``F`` (the rule of :mod:`hexcal.core.linalg`), with gauge freedoms the bound of the
gauge-fixed parameters (:mod:`hexcal.estimation.gauge`).

The planning functions (:func:`whitened_jacobian`, :func:`fisher_information`,
:func:`cramer_rao_covariance`, :func:`bound_mean_abs_error`) are this bound for the full
pose at poses a geometry reaches exactly.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import inverse_kinematics, leg_readings, pose_jacobian
from hexcal.core.linalg import floored_whitener, gram_pinv, gram_pinv_diagonal, scaled_svd, whitening
from hexcal.core.machine import check_variant
from hexcal.core.noise import NoiseModel
from hexcal.estimation.equations import LEG_SIGMA_FLOOR, POSE_VARIANCE_FLOOR
from hexcal.estimation.gauge import gauge_freedoms, gauge_projector
from hexcal.estimation.problem import Problem
from hexcal.instruments.base import MeasurementModel, Session
from hexcal.instruments.data import Measurements
from hexcal.instruments.registry import full_pose


def planned_measurements(geometry: Geometry, poses: ArrayLike) -> Measurements:
    """Noise-free measurements of poses on ``geometry`` (readings from its inverse kinematics)."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 6)
    return Measurements(poses, leg_readings(geometry, inverse_kinematics(geometry, poses)))


def planned_session(geometry: Geometry, instrument: MeasurementModel, poses: ArrayLike) -> Session:
    """The noise-free session an instrument records at poses ``geometry`` reaches exactly
    (planning: the machine is the nominal one; an unknown frame at its start value)."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 6)
    readings = leg_readings(geometry, inverse_kinematics(geometry, poses))
    setup = instrument.parameters().values
    data = instrument.simulate(setup, poses, readings, geometry.euler, None, np.random.default_rng(0))
    return Session(data, instrument)


def residual_covariances(
    geometry: Geometry, poses: ArrayLike, noise: NoiseModel | None = None
) -> NDArray[np.float64]:
    """Covariance ``C_j = J_j Σ_pose J_jᵀ + σ_leg² I`` of the six leg residuals of each pose
    measured in full, ``(m, 6, 6)`` mm²."""
    noise = NoiseModel() if noise is None else noise
    s_leg = noise.sigmas[0]
    jac = pose_jacobian(geometry, np.asarray(poses, dtype=float).reshape(-1, 6))
    return np.einsum("mik,kl,mjl->mij", jac, noise.pose_cov(), jac) + s_leg**2 * np.eye(6)


def _noises(problem: Problem, noise: NoiseModel | Sequence[NoiseModel] | None) -> tuple[NoiseModel, ...]:
    noise = NoiseModel() if noise is None else noise
    if isinstance(noise, NoiseModel):
        return (noise,) * len(problem.parts)
    return tuple(noise)


def information_rows(
    problem: Problem,
    noise: NoiseModel | Sequence[NoiseModel] | None = None,
    full: NDArray[np.float64] | None = None,
    poses: NDArray[np.float64] | None = None,
) -> list[NDArray[np.float64]]:
    """Each session's square-root information rows ``(m_s, r, n_free)`` (solver units): the
    whitened leg rows at the measured poses where the instrument determines the pose
    (``r = 6``), else the projected errors-in-variables rows (``r = 6 + k``). The Fisher
    information is the sum of ``rowsᵀ rows`` over all observations.

    ``full`` defaults to the problem's start values, ``poses`` (true poses, all sessions) to
    the instruments' start poses.
    """
    full = problem.full0 if full is None else full
    noises = _noises(problem, noise)
    out = []
    for part, n in zip(problem.parts, noises, strict=True):
        own = None if poses is None else poses[part.rows]
        inst = part.instrument
        if inst.determines_pose and own is None:
            own = inst.platform_poses(full[part.block], part.data, problem.euler)
            a = problem.leg_rows(part, full, own)
            jac = pose_jacobian(problem.geometry(full), own)
            cov_p = inst.platform_covariance(full[part.block], own, n, problem.euler)
            c = np.einsum("mik,mkl,mjl->mij", jac, cov_p, jac) + n.sigmas[0] ** 2 * np.eye(6)
            out.append(np.matmul(whitening(c), a))
            continue
        if own is None:
            own = inst.start_poses(problem.start, full[part.block], part.data)
        sigma = max(n.sigmas[0], LEG_SIGMA_FLOOR)
        w = floored_whitener(inst.covariance(n), POSE_VARIANCE_FLOOR)
        _, b, a, _ = problem.observation_equations(part, full, own, sigma, w, True)
        q, _ = np.linalg.qr(b)
        out.append(a - np.matmul(q, np.matmul(q.transpose(0, 2, 1), a)))
    return out


def projected_jacobian(
    problem: Problem,
    noise: NoiseModel | Sequence[NoiseModel] | None,
    full: NDArray[np.float64] | None = None,
    poses: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """All sessions' information rows stacked, ``(rows, n_free)``, solver units."""
    return np.concatenate(
        [r.reshape(-1, problem.n_free) for r in information_rows(problem, noise, full, poses)]
    )


def gauge_fixed_covariance(
    problem: Problem, jac: NDArray[np.float64], gauge: Any, variance: float = 1.0
) -> NDArray[np.float64]:
    """``variance · P (JᵀJ)⁺ Pᵀ`` in parameter units (``jac`` in solver units; ``P`` the
    gauge projector, the identity without gauges)."""
    cov = gram_pinv(scaled_svd(jac))
    if gauge.size:
        proj = gauge_projector(gauge)
        cov = proj @ cov @ proj.T
    return variance * cov * np.outer(problem.scale, problem.scale)


def cramer_rao(
    problem: Problem,
    noise: NoiseModel | Sequence[NoiseModel] | None = None,
    full: NDArray[np.float64] | None = None,
    poses: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """Cramér–Rao covariance ``(n_free, n_free)`` of the varied parameters (parameter units),
    gauge-fixed by the convention of :mod:`hexcal.estimation.gauge`.

    Parameters
    ----------
    problem : Problem
    noise : NoiseModel or one per session
    full : ndarray, optional
        Parameter values (default the problem's start values).
    poses : ndarray, shape (m, 6), optional
        True poses (default: measured where the instrument gives them, else its start poses).
    """
    full = problem.full0 if full is None else full
    jac = projected_jacobian(problem, noise, full, poses)
    return gauge_fixed_covariance(problem, jac, gauge_freedoms(problem, full))


def information_blocks(
    problem: Problem, noise: NoiseModel | Sequence[NoiseModel] | None, full: Any = None, poses: Any = None
) -> NDArray[np.float64]:
    """Per-observation Fisher information ``(m, n_free, n_free)`` (solver units; their sum is
    the information of the whole set, for pose selection)."""
    return np.concatenate(
        [np.einsum("mri,mrj->mij", r, r) for r in information_rows(problem, noise, full, poses)]
    )


def bound_stderr(
    problem: Problem,
    noise: NoiseModel | Sequence[NoiseModel] | None,
    full: NDArray[np.float64] | None = None,
    poses: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """Cramér–Rao σ of each varied parameter (parameter units) at ``full`` (default the
    start) and true ``poses`` (default as :func:`cramer_rao`); zero where the noise model has
    no noise at all."""
    noises = _noises(problem, noise)
    if not any(n.has_pose_noise or n.sigmas[0] != 0 for n in noises):
        return np.zeros(problem.n_free)
    return np.sqrt(np.clip(np.diag(cramer_rao(problem, noises, full, poses)), 0.0, None))


# -- planning: the full pose at poses a geometry reaches ------------------------------------
def measurements_problem(geometry: Geometry, measurements: Any, mask: ArrayLike | None = None) -> Problem:
    """A full-pose :class:`Problem` (the form most of hexcal's planning code uses)."""
    return Problem(geometry, measurements, full_pose(), mask)


def identification_residuals(
    geometry: Geometry, measurements: Any, method: str = "length"
) -> NDArray[np.float64]:
    """Leg residuals of every measured pose for ``geometry``, shape ``(m, 6)``.

    Units: mm for ``"length"``, mm² for ``"paper"``.
    """
    check_variant(method)
    problem = measurements_problem(geometry, measurements)
    return problem.leg_residuals(problem.full0, method)


def identification_jacobian(
    geometry: Geometry,
    measurements: Any,
    method: str = "length",
    mask: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Analytic Jacobian of the leg residuals at the measured poses, parameter units.

    Parameters
    ----------
    geometry : Geometry
        Parameters at which to evaluate.
    measurements : Measurements
    method : {"length", "paper"}
    mask : array_like of bool, optional
        Machine parameters to keep (columns); default the joints and ``l0``.

    Returns
    -------
    ndarray, shape (6 m, n_selected)
        Row ``6 j + i`` is pose ``j``, leg ``i``; columns in parameter order.
    """
    check_variant(method)
    problem = measurements_problem(geometry, measurements, mask)  # None: the leg model's default
    return problem.leg_jacobian(problem.full0, method, scaled=False)


def whitened_jacobian(
    geometry: Geometry,
    poses: ArrayLike,
    noise: NoiseModel | None = None,
    mask: ArrayLike | None = None,
    readings: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Noise-whitened identification Jacobian ``W_j A_j`` stacked over poses, shape (6 m, n),
    parameter units (the square-root information of the full pose, see the module).

    ``readings`` default to the geometry's own inverse kinematics (planning: the
    Jacobian does not depend on them except through gain columns).
    """
    poses = np.asarray(poses, dtype=float).reshape(-1, 6)
    mask = None if mask is None else np.asarray(mask, dtype=bool)  # None: the leg model's default
    data = planned_measurements(geometry, poses) if readings is None else Measurements(poses, readings)
    problem = Problem(geometry, data, mask=mask)
    rows = information_rows(problem, noise)[0]
    return (rows / problem.scale).reshape(6 * len(poses), -1)


def fisher_information(
    geometry: Geometry,
    poses: ArrayLike,
    noise: NoiseModel | None = None,
    mask: ArrayLike | None = None,
    readings: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Errors-in-variables Fisher information of the parameters, shape (n, n), parameter
    units (mm⁻², and mm⁻² times the gain scale for gains)."""
    wa = whitened_jacobian(geometry, poses, noise, mask, readings)
    return wa.T @ wa


def cramer_rao_covariance(
    geometry: Geometry,
    poses: ArrayLike,
    noise: NoiseModel | None = None,
    mask: ArrayLike | None = None,
    readings: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Cramér–Rao bound: the inverse Fisher information (pseudo-inverse by SVD), shape (n, n)."""
    return gram_pinv(scaled_svd(whitened_jacobian(geometry, poses, noise, mask, readings)))


def bound_mean_abs_error(
    geometry: Geometry,
    pose_sets: ArrayLike,
    noise: NoiseModel | None = None,
    mask: ArrayLike | None = None,
    rows: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Cramér–Rao bound of the mean absolute parameter error of each pose set.

    ``sqrt(2/π) · mean_i σ_i`` with ``σ_i`` the bound's standard deviation of parameter
    ``i``: the mean absolute error of an unbiased, normally distributed estimator that
    attains the bound (no unbiased estimator's errors have a smaller variance).

    Parameters
    ----------
    geometry : Geometry
        The true machine.
    pose_sets : array_like, shape (T, n, 6)
        ``T`` sets of ``n`` measurement poses each.
    noise : NoiseModel, optional
    mask : array_like of bool, optional
        The identified machine parameters (one flag per parameter of the geometry's leg
        model, 48 for linear legs); default the joints and ``l0``.
    rows : array_like of bool, optional
        Which of the identified parameters the mean is over (default all): the bound of the
        joints while the leg model's terms are identified too.

    Returns
    -------
    ndarray, shape (T,), mm
    """
    sets = np.asarray(pose_sets, dtype=float)
    t, n = sets.shape[:2]
    wa = whitened_jacobian(geometry, sets.reshape(-1, 6), noise, mask).reshape(t, 6 * n, -1)
    variances = gram_pinv_diagonal(scaled_svd(wa))
    if rows is not None:
        variances = variances[..., np.asarray(rows, dtype=bool)]
    return np.sqrt(2 / np.pi) * np.sqrt(variances).mean(axis=1)
