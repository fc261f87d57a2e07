"""Predicted accuracy of a pose set, before measuring, and everything about one pose set.

- the covariance of the least-squares estimator that :func:`hexcal.estimation.identify`
  actually uses (:func:`least_squares_covariance`), beside the Cramér–Rao bound of
  :func:`hexcal.estimation.cramer_rao_covariance`, and its mean absolute error
  (:func:`mean_abs_error`);
- the first-order map from parameter errors to platform pose errors
  (:func:`pose_error_map`) and, through it, the predicted pose error after calibration
  at test poses (:func:`predicted_pose_errors`);
- indices, identifiability and predicted accuracy of one pose set (:func:`analyse_poses`,
  :class:`PoseSetAnalysis`).

Imports :mod:`hexcal.core`, :mod:`hexcal.estimation` and the design modules
:mod:`~hexcal.design.identifiability` and :mod:`~hexcal.design.indices`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core import (
    PARAMETER_SCALE,
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
from hexcal.design.identifiability import as_mask, format_combination, null_space, planning_jacobian
from hexcal.design.indices import ObservabilityIndices, observability_indices
from hexcal.estimation import cramer_rao_covariance, residual_covariances, whitened_jacobian

#: Factor from a standard deviation to the mean absolute value of a normal variable.
MEAN_ABS_FACTOR = float(np.sqrt(2.0 / np.pi))


def _length_mean_abs(std: NDArray[np.float64], names: tuple[str, ...]) -> float:
    """``sqrt(2/π) · mean_k σ_k`` over the length parameters (gains left out), mm.

    >>> round(_length_mean_abs(np.array([1.0, 3.0, 1e-3]), ("u1.x", "l0_1", "g1")), 4)
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
    return _length_mean_abs(np.sqrt(np.clip(np.diag(cov), 0.0, None)), parameter_names(mask))


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


@dataclass(frozen=True)
class PoseSetAnalysis:
    """Observability and predicted accuracy of one measurement pose set.

    Attributes
    ----------
    names : tuple of str
        Parameters considered (n).
    n_poses : int
    indices : ObservabilityIndices
    unidentifiable : list of str
        Lost parameter combinations by name (empty when the rank is full).
    not_identifiable : ndarray of bool, shape (n,)
        Parameters that take part in a lost combination.
    std_bound, std_estimator : ndarray, shape (n,)
        Predicted standard deviation of every parameter: Cramér–Rao bound and the
        unweighted least-squares estimator of :func:`hexcal.estimation.identify`
        (``method``); inf where not identifiable.
    mean_error_bound, mean_error_estimator : float
        :func:`mean_abs_error` of the two, mm (inf when any length parameter is lost).
    test_position_rms, test_orientation_rms : ndarray, shape (t,)
        Predicted RMS pose error after calibration (estimator covariance) at the test
        poses, mm and rad; inf where a lost combination moves the platform.
    method : str
    noise : NoiseModel
    weighted : bool
        Whether the indices are of the noise-whitened Jacobian.
    """

    names: tuple[str, ...]
    n_poses: int
    indices: ObservabilityIndices
    unidentifiable: list[str]
    not_identifiable: NDArray[np.bool_]
    std_bound: NDArray[np.float64]
    std_estimator: NDArray[np.float64]
    mean_error_bound: float
    mean_error_estimator: float
    test_position_rms: NDArray[np.float64]
    test_orientation_rms: NDArray[np.float64]
    method: str
    noise: NoiseModel
    weighted: bool

    @property
    def rank(self) -> int:
        """Numerical rank of the identification Jacobian (:attr:`indices`)."""
        return self.indices.rank

    def to_dict(self) -> dict[str, Any]:
        """Plain-Python form (for JSON), the schema of ``hexcal observability --json``.

        Non-finite values (not identifiable) stay ``inf``; the report layer writes them as
        null. ``test_poses`` is present only when test poses were analysed.
        """
        out: dict[str, Any] = {
            "n_poses": self.n_poses,
            "n_parameters": len(self.names),
            "rank": self.rank,
            **self.indices.to_dict(),
            "weighted": self.weighted,
            "unidentifiable": list(self.unidentifiable),
            "method": self.method,
            "noise": {
                "leg": self.noise.leg,
                "position": self.noise.position,
                "orientation": self.noise.orientation,
                "distribution": self.noise.distribution,
                "sigmas": [float(s) for s in self.noise.sigmas],
            },
            "predicted_mean_abs_error_mm": {
                "estimator": float(self.mean_error_estimator),
                "bound": float(self.mean_error_bound),
            },
            "parameters": {
                name: {"std_estimator": float(se), "std_bound": float(sb)}
                for name, se, sb in zip(self.names, self.std_estimator, self.std_bound, strict=True)
            },
        }
        out["condition_number"] = float(self.indices.condition_number)
        pos, rot = self.test_position_rms, self.test_orientation_rms
        if pos.size:
            out["test_poses"] = {
                "n": int(pos.size),
                "position_rms_mm": pos.tolist(),
                "orientation_rms_rad": rot.tolist(),
                "position_rms_mean_mm": float(np.mean(pos)),
                "position_rms_max_mm": float(np.max(pos)),
                "orientation_rms_mean_rad": float(np.mean(rot)),
                "orientation_rms_max_rad": float(np.max(rot)),
            }
        return out


def analyse_poses(
    geometry: Geometry,
    poses: ArrayLike,
    noise: NoiseModel | None = None,
    mask: ArrayLike | None = None,
    test_poses: ArrayLike | None = None,
    scaling: str = "norm",
    method: str = "length",
    weighted: bool = False,
) -> PoseSetAnalysis:
    """Observability indices, identifiability and predicted accuracy of a pose set.

    Parameters
    ----------
    geometry : Geometry
        Nominal geometry (the Jacobians are evaluated on it).
    poses : array_like, shape (m, 6)
        Planned measurement poses.
    noise : NoiseModel, optional
        Default the seed paper's.
    mask : array_like of bool, shape (48,), optional
        Parameters to identify (default joints and ``l0``).
    test_poses : array_like, shape (t, 6), optional
        Where to predict the pose error after calibration (default none).
    scaling : {"norm", "parameter", "none"}
        Column scaling of the indices (:func:`column_scales`).
    method : {"length", "paper"}
        Residual of the estimator whose covariance is predicted.
    weighted : bool
        Compute the indices on the noise-whitened Jacobian instead of the plain one.

    Returns
    -------
    PoseSetAnalysis

    Examples
    --------
    >>> from hexcal.core import preset, workspace_corners
    >>> machine = preset("paper-hmt")
    >>> corners = workspace_corners(machine)
    >>> analysis = analyse_poses(machine, corners[:15], test_poses=corners)
    >>> analysis.rank, analysis.unidentifiable, analysis.to_dict()["test_poses"]["n"]
    (42, [], 64)
    >>> flat = corners.copy()
    >>> flat[:, 3:] = 0.0  # never rotating: moving u_i and s_i together is invisible
    >>> analyse_poses(machine, flat).rank
    24
    """
    noise = NoiseModel() if noise is None else noise
    mask = as_mask(mask)
    poses = as_poses(poses).reshape(-1, 6)
    names = parameter_names(mask)
    scale = PARAMETER_SCALE[mask]
    jac = (
        whitened_jacobian(geometry, poses, noise, mask)
        if weighted
        else planning_jacobian(geometry, poses, mask)
    )
    indices = observability_indices(jac, scaling, scale)
    lost = null_space(jac)
    not_identifiable = np.any(np.abs(lost) > 0, axis=0) if lost.size else np.zeros(len(names), dtype=bool)
    std_bound = np.sqrt(np.clip(np.diag(cramer_rao_covariance(geometry, poses, noise, mask)), 0, None))
    cov_est = least_squares_covariance(geometry, poses, noise, mask, method)
    std_est = np.sqrt(np.clip(np.diag(cov_est), 0, None))
    std_bound[not_identifiable] = np.inf
    std_est[not_identifiable] = np.inf
    if test_poses is None:
        pos_rms = rot_rms = np.empty(0)
    else:
        tp = as_poses(test_poses, "test poses").reshape(-1, 6)
        pos_rms, rot_rms = predicted_pose_errors(geometry, tp, cov_est, mask)
        if lost.size:
            # a lost combination that moves the platform at a test pose makes its error unbounded
            e = pose_error_map(geometry, tp, mask)
            moved = np.einsum("tip,kp->tik", e, lost / np.linalg.norm(lost, axis=1, keepdims=True))
            unbounded = np.max(np.abs(moved), axis=(1, 2)) > 1e-6
            pos_rms = np.where(unbounded, np.inf, pos_rms)
            rot_rms = np.where(unbounded, np.inf, rot_rms)
    return PoseSetAnalysis(
        names=names,
        n_poses=int(poses.shape[0]),
        indices=indices,
        unidentifiable=[format_combination(row, names) for row in lost],
        not_identifiable=not_identifiable,
        std_bound=std_bound,
        std_estimator=std_est,
        mean_error_bound=_length_mean_abs(std_bound, names),
        mean_error_estimator=_length_mean_abs(std_est, names),
        test_position_rms=pos_rms,
        test_orientation_rms=rot_rms,
        method=method,
        noise=noise,
        weighted=weighted,
    )
