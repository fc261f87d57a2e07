"""Information, covariance and observability of kinematic parameters for a pose set.

The measurement model of one pose ``j`` is the six leg equations
``|o_j + R_j s_i - u_i| - (l0_i + g_i dl_ij) = 0`` with a measured pose
``pose_j + e_pose`` (covariance ``Σ_pose``) and leg readings whose lengths carry a
sensor error of variance ``σ_leg²``. Linearised, the residual of pose ``j`` is

    r_j = A_j δθ + J_j e_pose + e_leg,

with ``A_j`` (6 × n) the identification Jacobian (``identification_jacobian``)
and ``J_j`` (6 × 6) the pose Jacobian (:func:`hexcal.core.kinematics.pose_jacobian`). Its
covariance is ``C_j = J_j Σ_pose J_jᵀ + σ_leg² I``, and the Fisher information of the
parameters, with the six true pose values of every measurement eliminated as
nuisance parameters (errors in variables), is

    F = Σ_j A_jᵀ C_j⁻¹ A_j.

Its inverse is the Cramér–Rao bound of any unbiased estimator and the covariance of
the generalised least-squares estimate; it is also the noise-weighted information
matrix on which optimal pose selection works.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import inverse_kinematics, leg_readings, pose_jacobian
from hexcal.core.linalg import gram_pinv, gram_pinv_diagonal, scaled_svd, whitening
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import select_parameters
from hexcal.estimation.problem import identification_jacobian
from hexcal.instruments.pose import Measurements

#: Smallest leg sensor σ used in the likelihood (mm): a zero σ makes the legs exact
#: constraints, which this floor approximates without dividing by zero.
LEG_SIGMA_FLOOR = 1e-7

#: Smallest pose error variance used in the likelihood (mm², rad²), for the same reason.
POSE_VARIANCE_FLOOR = 1e-18


def planned_measurements(geometry: Geometry, poses: ArrayLike) -> Measurements:
    """Noise-free measurements of poses on ``geometry`` (readings from its inverse kinematics)."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 6)
    return Measurements(poses, leg_readings(geometry, inverse_kinematics(geometry, poses)))


def residual_covariances(
    geometry: Geometry, poses: ArrayLike, noise: NoiseModel | None = None
) -> NDArray[np.float64]:
    """Covariance ``C_j = J_j Σ_pose J_jᵀ + σ_leg² I`` of the six leg residuals of each pose.

    Returns
    -------
    ndarray, shape (m, 6, 6), mm²
    """
    noise = NoiseModel() if noise is None else noise
    s_leg = noise.sigmas[0]
    jac = pose_jacobian(geometry, np.asarray(poses, dtype=float).reshape(-1, 6))
    return np.einsum("mik,kl,mjl->mij", jac, noise.pose_cov(), jac) + s_leg**2 * np.eye(6)


def whitened_jacobian(
    geometry: Geometry,
    poses: ArrayLike,
    noise: NoiseModel | None = None,
    mask: ArrayLike | None = None,
    readings: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Noise-whitened identification Jacobian ``W_j A_j`` stacked over poses, shape (6 m, n).

    ``readings`` default to the geometry's own inverse kinematics (planning: the
    Jacobian does not depend on them except through gain columns).
    """
    poses = np.asarray(poses, dtype=float).reshape(-1, 6)
    mask = select_parameters() if mask is None else np.asarray(mask, dtype=bool)
    if readings is None:
        data = planned_measurements(geometry, poses)
    else:
        data = Measurements(poses, readings)
    a = identification_jacobian(geometry, data, "length", mask).reshape(len(poses), 6, -1)
    w = whitening(residual_covariances(geometry, poses, noise))
    return np.einsum("mij,mjk->mik", w, a).reshape(6 * len(poses), -1)


def fisher_information(
    geometry: Geometry,
    poses: ArrayLike,
    noise: NoiseModel | None = None,
    mask: ArrayLike | None = None,
    readings: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Errors-in-variables Fisher information of the parameters, shape (n, n).

    See the module docstring; units are those of the parameters (mm⁻², and mm⁻²
    times the gain scale for gains).
    """
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
    mask : array_like of bool, shape (48,), optional

    Returns
    -------
    ndarray, shape (T,), mm
    """
    sets = np.asarray(pose_sets, dtype=float)
    t, n = sets.shape[:2]
    wa = whitened_jacobian(geometry, sets.reshape(-1, 6), noise, mask).reshape(t, 6 * n, -1)
    variances = gram_pinv_diagonal(scaled_svd(wa))
    return np.sqrt(2 / np.pi) * np.sqrt(variances).mean(axis=1)


def bound_stderr(
    geometry: Geometry, measurements: Measurements, noise: NoiseModel | None, mask: ArrayLike
) -> NDArray[np.float64]:
    """Cramér–Rao σ of each varied parameter of ``geometry`` for the measured poses.

    Zero where the noise model has no noise at all (the bound is then zero).
    """
    noise = NoiseModel() if noise is None else noise
    if not noise.has_pose_noise and noise.sigmas[0] == 0:
        return np.zeros(int(np.sum(mask)))
    cov = cramer_rao_covariance(
        geometry, measurements.poses, noise, np.asarray(mask, dtype=bool), measurements.readings
    )
    return np.sqrt(np.diag(cov))
