"""Validation of a geometry on held-out measurements, and compensation of targets.

Validation asks two questions of measured poses that were not used to identify:

- leg residuals: do the measured poses and the leg readings agree under the model,
  ``|o + R s_i - u_i| - (l0_i + g_i dl_i)``?
- pose error: where does the model say the platform is for the leg readings (forward
  kinematics), and how far is that from the measured pose?

Compensation computes the leg readings that bring the real machine, described by the
calibrated geometry, to each target, and optionally the corrected targets to give a
controller that still uses the nominal geometry.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.conventions import as_poses
from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import (
    forward_kinematics,
    inverse_kinematics,
    leg_lengths,
    leg_readings,
)
from hexcal.core.workspace import leg_limit_violations
from hexcal.errors import ValidationError
from hexcal.models.pose import Measurements
from hexcal.simulation.campaign import pose_errors


@dataclass(frozen=True, eq=False)
class ValidationResult:
    """Per-pose validation of one geometry.

    Attributes
    ----------
    ids : tuple of str
    leg_residuals : ndarray, shape (m, 6)
        ``|o + R s - u| - (l0 + g dl)`` at the measured poses, mm.
    model_poses : ndarray, shape (m, 6)
        Forward kinematics of the leg readings.
    position_error, orientation_error : ndarray, shape (m,)
        Distance (mm) and rotation angle (rad) between model and measured poses.
    """

    ids: tuple[str, ...]
    leg_residuals: NDArray[np.float64]
    model_poses: NDArray[np.float64]
    position_error: NDArray[np.float64]
    orientation_error: NDArray[np.float64]

    def summary(self) -> dict[str, float]:
        """RMS and maximum of the leg residuals and pose errors."""
        out: dict[str, float] = {"poses": len(self.ids)}
        for key, values in (
            ("leg", self.leg_residuals),
            ("position", self.position_error),
            ("orientation", self.orientation_error),
        ):
            out[f"{key}_rms"] = float(np.sqrt(np.mean(values**2)))
            out[f"{key}_max"] = float(np.max(np.abs(values)))
        return out


def validate(geometry: Geometry, measurements: Measurements) -> ValidationResult:
    """Leg residuals and model pose errors of ``geometry`` on measurements.

    Raises
    ------
    ValidationError
        When the forward kinematics of some leg readings does not converge (named by id).
    """
    lengths = leg_lengths(geometry, measurements.readings)
    residuals = inverse_kinematics(geometry, measurements.poses) - lengths
    fk = forward_kinematics(geometry, lengths, guess=measurements.poses)
    if not fk.all_converged:
        bad = [measurements.ids[k] for k in np.flatnonzero(~fk.converged)]
        raise ValidationError(
            f"forward kinematics of the leg readings did not converge at pose(s) {', '.join(bad[:20])}: "
            "the geometry does not describe these measurements"
        )
    position, orientation = pose_errors(measurements.poses, fk.poses, geometry.euler)
    return ValidationResult(measurements.ids, residuals, fk.poses, position, orientation)


@dataclass(frozen=True, eq=False)
class Compensation:
    """Leg commands for targets on the real (calibrated) machine.

    Attributes
    ----------
    targets : ndarray, shape (m, 6)
    lengths, readings : ndarray, shape (m, 6)
        Absolute leg lengths and leg readings ``dl`` that reach each target.
    feasible : ndarray of bool, shape (m,)
        Whether the lengths are within the geometry's leg length limits.
    corrected_poses : ndarray, shape (m, 6) or None
        Poses to command to a controller using the nominal geometry so that it
        produces ``readings`` (when a nominal geometry was given; NaN for infeasible
        targets).
    """

    ids: tuple[str, ...]
    targets: NDArray[np.float64]
    lengths: NDArray[np.float64]
    readings: NDArray[np.float64]
    feasible: NDArray[np.bool_]
    corrected_poses: NDArray[np.float64] | None = None

    @property
    def infeasible_ids(self) -> tuple[str, ...]:
        return tuple(self.ids[k] for k in np.flatnonzero(~self.feasible))


def compensate(
    geometry: Geometry,
    targets: ArrayLike,
    ids: tuple[str, ...] | None = None,
    nominal: Geometry | None = None,
) -> Compensation:
    """Leg readings that bring the machine described by ``geometry`` to each target.

    Parameters
    ----------
    geometry : Geometry
        The calibrated (real) geometry.
    targets : array_like, shape (m, 6)
    ids : tuple of str, optional
    nominal : Geometry, optional
        The controller's geometry: also compute the corrected target poses ``p'`` with
        ``IK_nominal(p') = l0_nominal + g_nominal dl`` (forward kinematics of the nominal
        geometry started at the target).

    Raises
    ------
    ValidationError
        When a corrected pose cannot be found (forward kinematics does not converge).
    """
    targets = np.array(as_poses(targets, "targets"), dtype=float).reshape(-1, 6)
    ids = tuple(ids) if ids is not None else tuple(str(k + 1) for k in range(len(targets)))
    lengths = inverse_kinematics(geometry, targets)
    readings = leg_readings(geometry, lengths)
    short, long = leg_limit_violations(geometry, lengths, margin=1e-9)
    feasible = ~(short | long)
    corrected = None
    if nominal is not None:
        # only for the reachable targets: an unreachable one has no command to correct
        corrected = np.full_like(targets, np.nan)
        fk = forward_kinematics(nominal, leg_lengths(nominal, readings[feasible]), guess=targets[feasible])
        if not fk.all_converged:
            bad = [ids[k] for k in np.flatnonzero(feasible)[~fk.converged]]
            raise ValidationError(f"no corrected pose found for target(s) {', '.join(bad[:20])}")
        corrected[feasible] = fk.poses
    return Compensation(ids, targets, lengths, readings, feasible, corrected)
