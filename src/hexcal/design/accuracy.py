"""Predicted accuracy of a pose set, before measuring.

- the covariance of the least-squares estimator that :func:`hexcal.estimation.identify`
  actually uses (:func:`least_squares_covariance`), beside the Cramér–Rao bound of
  :func:`hexcal.estimation.cramer_rao_covariance`, and its mean absolute error
  (:func:`mean_abs_error`);
- the first-order map from parameter errors to platform pose errors and the predicted
  pose error after calibration are the one formula of :mod:`hexcal.calibration.accuracy`
  (``pose_error_map``, ``predicted_pose_errors``), which the verdict uses too;
- all of it for one pose set in :mod:`hexcal.design.analysis`.

Imports :mod:`hexcal.core`, :mod:`hexcal.estimation`, :mod:`hexcal.calibration` and
:mod:`hexcal.design.identifiability`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core import (
    Geometry,
    NoiseModel,
    as_poses,
    gram_pinv,
    inverse_kinematics,
    scaled_svd,
)
from hexcal.core.parameters import PARAMETER_UNITS, select_parameters
from hexcal.design.identifiability import planning_jacobian
from hexcal.estimation import residual_covariances

#: Factor from a standard deviation to the mean absolute value of a normal variable.
MEAN_ABS_FACTOR = float(np.sqrt(2.0 / np.pi))


def length_mean_abs(std: NDArray[np.float64], units: Sequence[str]) -> float:
    """``sqrt(2/π) · mean_k σ_k`` over the length parameters (``units`` mm: gains and other
    units left out), mm.

    >>> round(length_mean_abs(np.array([1.0, 3.0, 1e-3]), ("mm", "mm", "1")), 4)
    1.5958
    """
    lengths = np.array([u == "mm" for u in units], dtype=bool)
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
    units = np.asarray(PARAMETER_UNITS)[select_parameters() if mask is None else np.asarray(mask, dtype=bool)]
    return length_mean_abs(np.sqrt(np.clip(np.diag(cov), 0.0, None)), tuple(units))
