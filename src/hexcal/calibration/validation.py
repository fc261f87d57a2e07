"""Validation of a calibration on held-out measurements, for every instrument.

Validation asks of observations that were not used to identify:

- **in the instrument's own terms**: where does the calibrated machine say the platform is
  for the leg readings (forward kinematics), what would the instrument then have measured,
  and how far is that from what it did measure (target distances, tool position and angle);
- **as platform pose error**: the platform pose the instrument's values give (the pose
  itself for a full-pose instrument, the pose that best explains the targets or tool
  otherwise; undetermined where one observation cannot give it, e.g. a single target) against
  the forward kinematics of the readings: position (mm) and rotation angle (rad);
- **leg residuals**: ``|o + R s_i - u_i| - f(θ_i, dl_i)`` at that platform pose.

Compensation (leg commands for targets) is :mod:`hexcal.core.compensation`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import forward_kinematics, inverse_kinematics, leg_lengths, pose_errors
from hexcal.errors import ValidationError
from hexcal.estimation.problem import as_sessions
from hexcal.instruments.base import MeasurementModel

_POSE_ITERATIONS = 30


@dataclass(frozen=True, eq=False)
class ValidationResult:
    """Per-observation validation of one geometry (and instrument).

    Attributes
    ----------
    ids : tuple of str
    leg_residuals : ndarray, shape (m, 6)
        ``|o + R s - u| - f(θ, dl)`` at the platform poses the instrument gives, mm (NaN where
        it gives none).
    model_poses : ndarray, shape (m, 6)
        Forward kinematics of the leg readings.
    position_error, orientation_error : ndarray, shape (m,)
        Distance (mm) and rotation angle (rad) between model and measured platform poses.
    instrument_errors : dict of str to ndarray
        The instrument's own prediction errors (``target`` distances ``(m, n)``, ``position``,
        ...).
    instrument : str
        What the instrument is.
    value_labels : tuple of str
        Labels of the columns of a per-value error (the targets ``t1``, ...).
    """

    ids: tuple[str, ...]
    leg_residuals: NDArray[np.float64]
    model_poses: NDArray[np.float64]
    position_error: NDArray[np.float64]
    orientation_error: NDArray[np.float64]
    instrument_errors: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    instrument: str = "full pose in the base frame"
    value_labels: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, object]:
        """Summary and per-observation errors, JSON-ready (mm and rad)."""
        with np.errstate(invalid="ignore"):
            leg = np.sqrt(np.mean(self.leg_residuals**2, axis=1))
        return {
            "summary": self.summary(),
            "ids": list(self.ids),
            "leg_rms": leg.tolist(),
            "position_error": self.position_error.tolist(),
            "orientation_error": self.orientation_error.tolist(),
            "instrument_errors": {k: v.tolist() for k, v in self.instrument_errors.items()},
        }

    def summary(self) -> dict[str, float]:
        """RMS and maximum of the leg residuals, pose errors and instrument errors (the
        values that exist)."""
        out: dict[str, float] = {"poses": len(self.ids)}
        groups = [
            ("leg", self.leg_residuals),
            ("position", self.position_error),
            ("orientation", self.orientation_error),
        ]
        groups += [(f"instrument_{k}", v) for k, v in self.instrument_errors.items()]
        for key, values in groups:
            good = np.asarray(values)[np.isfinite(values)]
            out[f"{key}_rms"] = float(np.sqrt(np.mean(good**2))) if good.size else float("nan")
            out[f"{key}_max"] = float(np.max(np.abs(good))) if good.size else float("nan")
        return out


def instrument_poses(
    instrument: MeasurementModel,
    setup: NDArray[np.float64],
    data: Any,
    start: NDArray[np.float64],
    euler: str,
) -> NDArray[np.float64]:
    """The platform poses ``(m, 6)`` that best explain each observation's instrument values
    (Gauss–Newton from ``start``; the observation itself where the instrument gives the pose);
    NaN rows where the values cannot determine a pose (fewer than six independent values)."""
    if instrument.determines_pose:
        return instrument.platform_poses(setup, data, euler)
    observed, present = instrument.observed(data)
    poses = np.array(start)
    jac = np.zeros((len(poses), instrument.size, 6))
    for _ in range(_POSE_ITERATIONS):
        r = np.where(present, instrument.residual(setup, poses, euler, observed), 0.0)
        jac = np.where(present[..., None], instrument.pose_jacobian(setup, poses, euler), 0.0)
        step, ok = _least_squares_steps(jac, r)
        poses = poses - np.where(ok[:, None], step, 0.0)
        if np.max(np.abs(step[ok]), initial=0.0) < 1e-12 * (1.0 + np.max(np.abs(poses))):
            break
    sv = np.linalg.svd(jac, compute_uv=False)
    determined = sv[:, -1] > 1e-9 * sv[:, 0] if sv.shape[1] == 6 else np.zeros(len(poses), dtype=bool)
    poses[~determined] = np.nan
    return poses


def _least_squares_steps(jac: NDArray[np.float64], r: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """Per-observation least-squares steps ``J⁺ r`` and whether ``J`` has full column rank."""
    hess = np.einsum("mki,mkj->mij", jac, jac)
    grad = np.einsum("mki,mk->mi", jac, r)
    det_ok = np.linalg.cond(hess) < 1e12
    safe = np.where(det_ok[:, None, None], hess, np.eye(6))
    return np.linalg.solve(safe, grad[..., None])[..., 0], det_ok


def validate(geometry: Geometry, data: Any, instrument: MeasurementModel | None = None) -> ValidationResult:
    """Prediction errors of ``geometry`` (and a calibrated instrument) on held-out data.

    Parameters
    ----------
    geometry : Geometry
        The calibrated machine.
    data
        One session, or one data set read by ``instrument`` (default the full pose in the
        base frame).
    instrument : MeasurementModel, optional
        The calibrated instrument of ``data`` (its frame known).

    Raises
    ------
    ValidationError
        When the forward kinematics of some leg readings does not converge (named by id), or
        the instrument's frame is unknown.
    """
    session = as_sessions(data, instrument)[0]
    inst, values = session.instrument, session.data
    setup = inst.parameters().values
    if inst.unregistered:
        raise ValidationError(
            "validation needs a calibrated setup (the instrument frame is auto): give the setup "
            "that identify wrote with --setup-out"
        )
    ids = inst.ids(values)
    readings = inst.readings(values)
    lengths = leg_lengths(geometry, readings)
    start = inst.start_poses(geometry, setup, values)
    fk = forward_kinematics(geometry, lengths, guess=start)
    if not fk.all_converged:
        bad = [ids[k] for k in np.flatnonzero(~fk.converged)]
        raise ValidationError(
            f"forward kinematics of the leg readings did not converge at pose(s) {', '.join(bad[:20])}: "
            "the geometry does not describe these measurements"
        )
    measured = instrument_poses(inst, setup, values, fk.poses, geometry.euler)
    with np.errstate(invalid="ignore"):
        residuals = inverse_kinematics(geometry, np.nan_to_num(measured)) - lengths
    residuals[~np.all(np.isfinite(measured), axis=1)] = np.nan
    if np.all(np.isfinite(measured)):
        position, orientation = pose_errors(measured, fk.poses, geometry.euler)
    else:  # NaN where the instrument gives no pose
        position, orientation = pose_errors(fk.poses, measured, geometry.euler)
    errors = {} if inst.determines_pose else inst.errors(setup, fk.poses, values, geometry.euler)
    labels = tuple(label.split()[-1] for label, _ in inst.value_groups())
    return ValidationResult(ids, residuals, fk.poses, position, orientation, errors, inst.describe(), labels)
