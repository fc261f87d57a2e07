"""Everything about one measurement pose set: indices, identifiability, predicted accuracy.

:func:`analyse_poses` gathers the observability indices (:mod:`hexcal.design.indices`),
the lost parameter combinations (:mod:`hexcal.design.identifiability`) and the predicted
parameter and pose errors (:mod:`hexcal.design.accuracy`) of a pose set into one
:class:`PoseSetAnalysis`, whose :meth:`~PoseSetAnalysis.to_dict` is the content of
``hexcal observability --json``. Imports :mod:`hexcal.core`, :mod:`hexcal.estimation` and
those design modules.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.calibration.accuracy import pose_error_map, predicted_pose_errors
from hexcal.core import PARAMETER_SCALE, Geometry, NoiseModel, as_poses, parameter_names
from hexcal.design.accuracy import least_squares_covariance, length_mean_abs
from hexcal.design.identifiability import as_mask, format_combination, null_space, planning_jacobian
from hexcal.design.indices import ObservabilityIndices, observability_indices
from hexcal.estimation import cramer_rao_covariance, whitened_jacobian


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
        mean_error_bound=length_mean_abs(std_bound, names),
        mean_error_estimator=length_mean_abs(std_est, names),
        test_position_rms=pos_rms,
        test_orientation_rms=rot_rms,
        method=method,
        noise=noise,
        weighted=weighted,
    )
