"""Predicted accuracy of a pose set, before measuring.

- the covariance of the least-squares estimator that :func:`hexcal.estimation.identify`
  actually uses (:func:`least_squares_covariance`), beside the Cramér–Rao bound of
  :func:`hexcal.estimation.cramer_rao_covariance`, and its mean absolute error
  (:func:`mean_abs_error`);
- the first-order map from parameter errors to platform pose errors
  (:func:`pose_error_map`) and, through it, the predicted pose error after calibration
  at test poses (:func:`predicted_pose_errors`);
- all of it for one pose set in :mod:`hexcal.design.analysis`.

Imports :mod:`hexcal.core`, :mod:`hexcal.estimation` and
:mod:`hexcal.design.identifiability`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core import (
    Geometry,
    NoiseModel,
    as_poses,
    euler_axes,
    gram_pinv,
    inverse_kinematics,
    parameter_names,
    pose_jacobian,
    scaled_svd,
)
from hexcal.design.identifiability import planning_jacobian
from hexcal.estimation import residual_covariances

#: Factor from a standard deviation to the mean absolute value of a normal variable.
MEAN_ABS_FACTOR = float(np.sqrt(2.0 / np.pi))


def length_mean_abs(std: NDArray[np.float64], names: tuple[str, ...]) -> float:
    """``sqrt(2/π) · mean_k σ_k`` over the length parameters (gains left out), mm.

    >>> round(length_mean_abs(np.array([1.0, 3.0, 1e-3]), ("u1.x", "l0_1", "g1")), 4)
    1.5958
    """
    lengths = np.array([not n.startswith("g") for n in names])
    return MEAN_ABS_FACTOR * float(np.mean(std[lengths]))


def least_squares_covariance(
    geometry: Geometry,
    poses: ArrayLike,
    noise: NoiseModel | None = None,
    mask: ArrayLike | None = None,
    method: str = "length",
) -> NDArray[np.float64]:
    """Covariance of the unweighted least-squares estimate of ``identify``.

    Parameters
    ----------
    geometry : Geometry
    poses : array_like, shape (m, 6)
    noise : NoiseModel, optional
        Default the seed paper's.
    mask : array_like of bool, shape (48,), optional
    method : {"length", "paper"}
        The residual minimised: leg length, or squared leg length (the paper's eq. 3).

    Returns
    -------
    ndarray, shape (n, n)
        Parameter units (mm² for joints and ``l0``).

    Examples
    --------
    >>> from hexcal.core import preset, workspace_corners
    >>> machine = preset("paper-hmt")
    >>> cov = least_squares_covariance(machine, workspace_corners(machine))
    >>> cov.shape, round(mean_abs_error(cov), 3)
    ((42, 42), 0.149)

    Notes
    -----
    The estimator minimises ``Σ |r_j|²`` without weights while the residual of pose
    ``j`` has covariance ``C_j = J_j Σ_pose J_jᵀ + σ_leg² I``
    (:func:`hexcal.estimation.residual_covariances`): its first-order covariance is
    the sandwich ``H⁻¹ (Σ_j A_jᵀ C_j A_j) H⁻¹`` with ``H = Σ_j A_jᵀ A_j``. For the paper's
    residual ``|v|² - l²`` every row of leg ``i`` is the leg-length row times ``2 l_ij``.
    The Cramér–Rao bound (:func:`hexcal.estimation.cramer_rao_covariance`) is what a
    noise-weighted estimator would reach; it is never larger.

    Evaluated at the poses the machine really reaches, it predicts the Monte Carlo error
    of :func:`hexcal.estimation.identify` within its standard error; at planning
    time only the commanded poses and the nominal geometry are known, and on the seed
    paper's machine (parameter errors up to 5 mm, reached poses up to 63 mm and 0.11 rad
    off) that prediction is 3-6 % high (``docs/observability.md``).
    """
    poses = as_poses(poses).reshape(-1, 6)
    m = poses.shape[0]
    a = planning_jacobian(geometry, poses, mask).reshape(m, 6, -1)
    cov = residual_covariances(geometry, poses, noise)
    if method == "paper":
        w = 2.0 * inverse_kinematics(geometry, poses)
        a = a * w[..., None]
        cov = cov * w[:, :, None] * w[:, None, :]
    elif method != "length":
        raise ValueError(f"unknown method {method!r}; choose from length, paper")
    h_inv = gram_pinv(scaled_svd(a.reshape(6 * m, -1)))
    meat = np.einsum("mip,mij,mjq->pq", a, cov, a)
    return h_inv @ meat @ h_inv


def mean_abs_error(covariance: ArrayLike, mask: ArrayLike | None = None) -> float:
    """Predicted mean absolute error of the length parameters, mm.

    ``sqrt(2/π) · mean_k σ_k`` over the selected joints and ``l0`` (gains left out: they
    have no length unit), with ``σ_k`` from the covariance: the mean absolute error of a
    normally distributed unbiased estimate, comparable with the seed paper's Table I.

    >>> round(mean_abs_error(np.eye(42) * 0.01), 4)  # σ = 0.1 mm for every parameter
    0.0798
    """
    cov = np.asarray(covariance, dtype=float)
    return length_mean_abs(np.sqrt(np.clip(np.diag(cov), 0.0, None)), parameter_names(mask))


def pose_error_map(
    geometry: Geometry, poses: ArrayLike, mask: ArrayLike | None = None
) -> NDArray[np.float64]:
    """First-order map from parameter errors to platform pose errors, shape (..., 6, n).

    Parameters
    ----------
    geometry : Geometry
        The controller's (nominal) geometry.
    poses : array_like, shape (..., 6)
        Commanded poses.
    mask : array_like of bool, shape (48,), optional
        Parameters with errors (default joints and ``l0``).

    Returns
    -------
    ndarray, shape (..., 6, n)
        ``E`` with ``δpose = E δθ`` (mm and rad per parameter unit).

    Notes
    -----
    The controller commands the nominal leg readings of a pose; a machine whose
    parameters differ by ``δθ`` reaches the pose where its leg equations
    ``r = |o + R s_i - u_i| - (l0_i + g_i dl_i) = 0`` hold. To first order
    ``J δpose + A δθ = 0``, so ``E = -J⁻¹ A`` with ``J`` the pose Jacobian and ``A`` the
    identification Jacobian of the leg length residual.

    Examples
    --------
    >>> from hexcal.core import preset
    >>> machine = preset("paper-hmt")
    >>> pose_error_map(machine, machine.home_pose).shape
    (6, 42)
    """
    poses = as_poses(poses)
    batch = poses.shape[:-1]
    flat = poses.reshape(-1, 6)
    a = planning_jacobian(geometry, flat, mask).reshape(flat.shape[0], 6, -1)
    jac_inv = np.linalg.inv(pose_jacobian(geometry, flat))
    out = -np.matmul(jac_inv, a)
    return out.reshape(batch + out.shape[-2:])


def rotation_vector_map(geometry: Geometry, poses: ArrayLike) -> NDArray[np.float64]:
    """Matrices ``W`` (..., 3, 3) with ``ω = W δ(a, b, c)``: small angle changes to the
    rotation vector of the orientation error, rad per rad (columns are the Euler axes).

    >>> from hexcal.core import preset
    >>> machine = preset("paper-hmt")
    >>> rotation_vector_map(machine, np.zeros(6)).shape
    (3, 3)
    """
    poses = as_poses(poses)
    return np.swapaxes(euler_axes(poses[..., 3:], geometry.euler), -1, -2)


def predicted_pose_errors(
    geometry: Geometry,
    test_poses: ArrayLike,
    covariance: ArrayLike,
    mask: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """RMS position and orientation error after calibration at test poses.

    Parameters
    ----------
    geometry : Geometry
    test_poses : array_like, shape (t, 6)
    covariance : array_like, shape (n, n)
        Covariance of the identified parameters (parameter units).
    mask : array_like of bool, shape (48,), optional

    Returns
    -------
    position : ndarray, shape (t,), mm
        ``sqrt(E[|δp|²])``.
    orientation : ndarray, shape (t,), rad
        ``sqrt(E[|ω|²])``, ``ω`` the rotation vector of the orientation error.

    Notes
    -----
    A controller with the identified parameters misses a target by
    ``δpose = E (θ̂ - θ)`` (:func:`pose_error_map`), whose covariance is ``E Σθ Eᵀ``.

    Examples
    --------
    >>> from hexcal.core import preset
    >>> machine = preset("paper-hmt")
    >>> position, orientation = predicted_pose_errors(machine, [machine.home_pose], np.zeros((42, 42)))
    >>> position.tolist(), orientation.tolist()
    ([0.0], [0.0])
    """
    tp = as_poses(test_poses).reshape(-1, 6)
    cov = np.asarray(covariance, dtype=float)
    e = pose_error_map(geometry, tp, mask)
    w = rotation_vector_map(geometry, tp)
    e_pos = e[:, :3]
    e_rot = np.einsum("tij,tjk->tik", w, e[:, 3:])
    pos = np.einsum("tip,pq,tiq->t", e_pos, cov, e_pos)
    rot = np.einsum("tip,pq,tiq->t", e_rot, cov, e_rot)
    return np.sqrt(np.clip(pos, 0, None)), np.sqrt(np.clip(rot, 0, None))
