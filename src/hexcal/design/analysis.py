"""Everything about one measurement pose set: indices, identifiability, predicted accuracy.

:func:`analyse_poses` gathers the observability indices (:mod:`hexcal.design.indices`),
the lost parameter combinations (:mod:`hexcal.design.identifiability`) and the predicted
parameter and pose errors (:mod:`hexcal.design.accuracy`) of a pose set into one
:class:`PoseSetAnalysis`, whose :meth:`~PoseSetAnalysis.to_dict` is the content of
``hexcal observability --json``. Imports :mod:`hexcal.core`, :mod:`hexcal.estimation` and
those design modules.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.calibration.accuracy import pose_error_map, predicted_pose_errors
from hexcal.core import PARAMETER_SCALE, Geometry, NoiseModel, as_poses, parameter_names
from hexcal.design.accuracy import least_squares_covariance, length_mean_abs
from hexcal.design.identifiability import as_mask, format_combination, null_space, planning_jacobian
from hexcal.design.indices import SCALINGS, ObservabilityIndices, observability_indices
from hexcal.design.stroke_coverage import StrokeCoverage, stroke_coverage
from hexcal.estimation import cramer_rao_covariance, whitened_jacobian
from hexcal.instruments.base import MeasurementModel


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
        unweighted least-squares estimator of :func:`hexcal.calibration.estimate`
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
    instrument : str
        What measures the poses.
    gauges : tuple of str
        The gauge freedoms of an instrument in its own frame (the indices, rank and σ are
        those beyond them, the σ of the gauge-fixed parameters).
    n_machine : int, optional
        Machine parameters among :attr:`names` (the rest are the instrument's).
    stroke : StrokeCoverage, optional
        For a leg model with a curve of the stroke: how much of each leg's stroke the poses'
        readings cover (:func:`hexcal.design.stroke_coverage.stroke_coverage`).
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
    instrument: str = "full pose in the base frame"
    gauges: tuple[str, ...] = ()
    n_machine: int | None = None
    stroke: StrokeCoverage | None = None

    @property
    def rank(self) -> int:
        """Numerical rank of the identification Jacobian (:attr:`indices`)."""
        return self.indices.rank

    def to_dict(self) -> dict[str, Any]:
        """Plain-Python form (for JSON), the schema of ``hexcal observability --json``.

        Non-finite values (not identifiable) stay ``inf``; the report layer writes them as
        null. ``test_poses`` is present only when test poses were analysed.
        """
        joints = [k for k, n in enumerate(self.names) if n[0] in "us" and n[1:2].isdigit()]
        l0 = [k for k, n in enumerate(self.names) if n.startswith("l0_")]
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
        out |= {
            "instrument": self.instrument,
            "n_machine_parameters": len(self.names) if self.n_machine is None else self.n_machine,
            "gauges": len(self.gauges),
            "gauge_labels": list(self.gauges),
            "identifiable": not self.unidentifiable,
            "joint_bound_mm": float(np.median(self.std_bound[joints])) if joints else None,
            "joint_bound_max_mm": float(np.max(self.std_bound[joints])) if joints else None,
            "l0_bound_mm": float(np.median(self.std_bound[l0])) if l0 else None,
        }
        if self.stroke is not None:
            out["stroke_coverage"] = self.stroke.to_dict()
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
    instrument: MeasurementModel | None = None,
    fix: Any = (),
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
    method : {"length", "paper", "ml"}
        The estimator whose covariance is predicted: the unweighted least squares of the leg
        lengths or of their squares, or maximum likelihood (``identify``'s default: its
        covariance is the Cramér–Rao bound).
    weighted : bool
        Compute the indices on the noise-whitened Jacobian instead of the plain one.
    instrument : MeasurementModel, optional
        What measures the poses (default the full pose in the base frame). An instrument that
        does not give the pose (a free frame or tool, targets) is analysed by its
        pose-eliminated, noise-whitened Jacobian beyond its gauge freedoms
        (:func:`analyse_instrument`): ``method`` must then be ``ml`` and the indices are
        weighted.
    fix : sequence of str
        Parameters or groups to hold (instrument quantities: ``frame``...).

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
    from hexcal.core.noise import require_noise
    from hexcal.design.instrument_table import planned_instrument

    noise = require_noise(NoiseModel() if noise is None else noise, "every predicted accuracy")
    through_problem = planned_instrument(geometry, instrument)
    if through_problem is not None:
        return analyse_instrument(
            geometry, through_problem, poses, noise, mask, test_poses, method, scaling, fix
        )
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
    cov_bound = cramer_rao_covariance(geometry, poses, noise, mask)
    std_bound = np.sqrt(np.clip(np.diag(cov_bound), 0, None))
    cov_est = cov_bound if method == "ml" else least_squares_covariance(geometry, poses, noise, mask, method)
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


def analyse_instrument(
    geometry: Geometry,
    instrument: MeasurementModel,
    poses: ArrayLike,
    noise: NoiseModel,
    mask: ArrayLike | None = None,
    test_poses: ArrayLike | None = None,
    method: str = "ml",
    scaling: str = "norm",
    fix: Any = (),
) -> PoseSetAnalysis:
    """:func:`analyse_poses` of an instrument that does not give the pose by itself.

    Its maximum-likelihood estimate is the only one (the predicted σ is the Cramér–Rao bound of
    the gauge-fixed parameters), and the indices are always of the noise-whitened,
    pose-eliminated Jacobian (the pose is not measured: there is no unweighted leg Jacobian),
    columns scaled by ``scaling``, in the directions orthogonal to the gauge freedoms: a single
    target, or poses that never rotate, show as a lost rank and infinite σ.
    """
    from hexcal.core.linalg import null_space as null_rows
    from hexcal.design.instrument_table import default_flags, plan_problem
    from hexcal.errors import UsageError
    from hexcal.estimation import complement_basis, gauge_fixed_covariance, gauge_freedoms, projected_jacobian
    from hexcal.estimation import unidentifiable as lost_beyond

    if method != "ml":
        why = (
            f"the {geometry.leg_model.name} leg model is planned for its maximum-likelihood estimate only"
            if instrument.determines_pose
            else f"the {instrument.describe()} does not give the platform pose"
        )
        raise UsageError(f"method {method!r}: {why}; only the maximum-likelihood estimate (ml) applies")
    machine = np.asarray(as_mask(mask), dtype=bool)
    flags = default_flags(geometry) if mask is None else machine
    problem = plan_problem(geometry, instrument, poses, fix=fix, mask=flags)
    jac = projected_jacobian(problem, noise)
    gauge = gauge_freedoms(problem, problem.full0)
    basis = complement_basis(gauge)
    if scaling not in SCALINGS:
        raise UsageError(f"unknown scaling {scaling!r}; choose from {', '.join(SCALINGS)}")
    # the rows are in solver units (the parameters' scales): "parameter" scaling as they are
    norms = {"norm": np.linalg.norm(jac, axis=0), "parameter": np.ones(jac.shape[1]), "none": problem.scale}[
        scaling
    ]
    scaled = jac / np.where(norms > 0, norms, 1.0)
    gen = gauge.generators * norms[:, None]
    reduced = scaled @ (
        complement_basis(type(gauge)(gen, gauge.labels, gauge.metric)) if gauge.size else basis
    )
    indices = dataclasses.replace(observability_indices(reduced, "none"), scaling=scaling)
    names = problem.names
    weak = lost_beyond(problem, jac, gauge)
    cov = gauge_fixed_covariance(problem, jac, gauge)
    std = np.sqrt(np.clip(np.diag(cov), 0, None))
    not_identifiable = np.zeros(len(names), dtype=bool)
    if weak:
        lost, _ = null_rows(jac @ basis)
        not_identifiable = np.any(np.abs(basis @ lost.T) > 1e-6, axis=1) if lost.size else not_identifiable
    std[not_identifiable] = np.inf
    rows = np.isin(names, geometry.machine_names())
    if test_poses is None:
        pos_rms = rot_rms = np.empty(0)
    else:
        tp = as_poses(test_poses, "test poses").reshape(-1, 6)
        names_m = tuple(np.asarray(names)[rows])
        mm = np.isin(geometry.machine_names(), names_m)
        rigid = (gauge.generators * problem.scale[:, None])[rows] if gauge.size else None
        pos_rms, rot_rms = predicted_pose_errors(geometry, tp, cov[np.ix_(rows, rows)], mm, rigid)
        if not_identifiable.any():
            pos_rms = np.where(np.any(not_identifiable[rows]), np.inf, pos_rms)
            rot_rms = np.where(np.any(not_identifiable[rows]), np.inf, rot_rms)
    machine_names = tuple(np.asarray(names)[rows])
    return PoseSetAnalysis(
        names=names,
        n_poses=len(problem),
        indices=indices,
        unidentifiable=weak,
        not_identifiable=not_identifiable,
        std_bound=std,
        std_estimator=std.copy(),
        mean_error_bound=length_mean_abs(std[rows], machine_names),
        mean_error_estimator=length_mean_abs(std[rows], machine_names),
        test_position_rms=pos_rms,
        test_orientation_rms=rot_rms,
        method="ml",
        noise=noise,
        weighted=True,
        instrument=instrument.describe(),
        gauges=gauge.labels,
        n_machine=int(rows.sum()),
        stroke=stroke_coverage(geometry, poses),
    )
