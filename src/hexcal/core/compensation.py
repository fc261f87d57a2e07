"""Compensation: the leg commands that bring the real (calibrated) machine to targets.

Also the corrected target poses for a controller that still uses the nominal geometry:
commanding them, that controller produces exactly the calibrated leg lengths. Imports the
rest of :mod:`hexcal.core`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.conventions import as_poses
from hexcal.core.covariate_legs import geometry_inputs
from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import forward_kinematics, inverse_kinematics, leg_lengths, leg_readings
from hexcal.core.workspace import leg_limit_violations
from hexcal.errors import ValidationError


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
    covariates: Any = None,
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
    covariates : Covariates, optional
        The conditions each target is to be reached under (the legs' temperatures, the
        payload: :class:`hexcal.instruments.Covariates`), for a leg model that reads them
        (:mod:`hexcal.core.covariate_legs`); the axial forces at the targets. A leg model that
        needs one the covariates lack is refused in one line.

    Raises
    ------
    ValidationError
        When a corrected pose cannot be found (forward kinematics does not converge).
    """
    targets = np.array(as_poses(targets, "targets"), dtype=float).reshape(-1, 6)
    ids = tuple(ids) if ids is not None else tuple(str(k + 1) for k in range(len(targets)))
    lengths = inverse_kinematics(geometry, targets)
    readings = leg_readings(geometry, lengths, geometry_inputs(geometry, covariates, targets, "the targets"))
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
