"""Validation of a geometry on held-out measurements, and compensation of targets.

Validation asks two questions of measured poses that were not used to identify:

- leg residuals: do the measured poses and the leg readings agree under the model,
  ``|o + R s_i - u_i| - (l0_i + g_i dl_i)``?
- pose error: where does the model say the platform is for the leg readings (forward
  kinematics), and how far is that from the measured pose?

Compensation (leg commands for targets) is :mod:`hexcal.core.compensation`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import (
    forward_kinematics,
    inverse_kinematics,
    leg_lengths,
    pose_errors,
)
from hexcal.errors import ValidationError
from hexcal.instruments.pose import Measurements


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

    def to_dict(self) -> dict[str, object]:
        """Summary and per-pose errors, JSON-ready (mm and rad)."""
        return {
            "summary": self.summary(),
            "ids": list(self.ids),
            "leg_rms": np.sqrt(np.mean(self.leg_residuals**2, axis=1)).tolist(),
            "position_error": self.position_error.tolist(),
            "orientation_error": self.orientation_error.tolist(),
        }

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
