"""The ISO tests of a validation: what ``hexcal validate --iso230-4`` and ``--iso9283`` compute.

Both start from :func:`hexcal.calibration.validate` (one result per geometry: the calibrated
one and, with ``--nominal``, the nominal one), which has put every observation's leg readings
through the geometry's forward kinematics (``model_poses``) and found the platform pose the
instrument gives (``measured_poses``). The definitions are those of
:mod:`hexcal.calibration.iso_tests` and :mod:`hexcal.calibration.iso_poses`.

**ISO 230-4 on a one-distance instrument** (a ball bar). The commanded positions are the
platform positions of the forward kinematics of the readings through the *nominal* geometry
(what the nominal controller commanded; the geometry validated when no nominal is given):
they give the circle's plane, centre, radius and every point's angle and direction. Each
geometry's radial deviation is the measured distance minus the distance that geometry
predicts at the pose its forward kinematics gives for the same readings, with the
instrument's setup as given (its pivot, ball and length as set up; a setup with free
quantities is refused, since re-registering the pivot would absorb the centre offset the test
is there to show):

- *before* (nominal geometry): the readings through the nominal model, i.e. what the machine
  does under its nominal controller;
- *after* (calibrated geometry): what is left once the calibrated model explains the readings.
  A controller compensated with the calibrated model commands the legs so that the
  calibrated model's pose is the commanded one; to first order in the model's errors the
  machine then deviates from the circle by what the calibrated model does not explain, which
  is this deviation (it is not a second measured run).

The deviations are along the bar: radial when the pivot lies in the circle's plane (the usual
set-up; for a bar tilted by an angle ``φ`` out of the plane divide by ``cos φ``).

**ISO 9283 on an instrument that gives the pose** (full pose, a tool, three targets or more).
Visits of the same commanded pose are the observations whose six leg readings agree within a
tolerance (the same leg commands: :func:`~hexcal.calibration.iso_poses.repeated_visits`);
their commanded pose is the forward kinematics of the readings through each geometry (the
pose that geometry's controller commands), their attained poses those the instrument gives.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.calibration.iso_poses import PoseStatistics, pose_statistics
from hexcal.calibration.iso_poses import repeated_visits as visits_of
from hexcal.calibration.iso_tests import CircularTest, circular_test
from hexcal.errors import UsageError
from hexcal.instruments.base import MeasurementModel, Session

#: Default tolerance (mm) on every leg reading for two observations to be visits of one pose.
VISIT_TOLERANCE = 0.01


def one_distance(instrument: MeasurementModel) -> bool:
    """Whether an instrument measures one distance per observation (a ball bar)."""
    return instrument.size == 1 and not instrument.determines_pose


def check_circle_instrument(instrument: MeasurementModel) -> None:
    """Refuse, in one line, an instrument the circular test cannot use."""
    if not one_distance(instrument):
        raise UsageError(
            f"--iso230-4 needs an instrument that measures one distance per observation (a ball bar), "
            f"not {instrument.describe()}"
        )
    if instrument.unregistered or bool(np.any(instrument.parameters().vary)):
        raise UsageError(
            "--iso230-4: the ball bar's setup must fix its quantities (pivot, ball, length as set up); "
            "re-registering them would absorb the centre offset the circular test shows"
        )


def radial_deviations(session: Session, model_poses: NDArray[np.float64], euler: str) -> NDArray[np.float64]:
    """Measured minus predicted distance at each observation, mm: the prediction at
    ``model_poses`` (a geometry's forward kinematics of the readings) with the setup as given."""
    inst = session.instrument
    observed, present = inst.observed(session.data)
    predicted = inst.predict(inst.parameters().values, model_poses, euler)
    return np.where(present, observed - predicted, np.nan)[:, 0]


def circular_tests(
    session: Session, results: Mapping[str, Any], euler: str, commanded: str | None = None
) -> dict[str, CircularTest]:
    """The ISO 230-4 test of each geometry's validation (module docstring), by the results'
    names; the commanded positions from the result named ``commanded`` (default the one named
    ``nominal`` if there is one, else the first)."""
    check_circle_instrument(session.instrument)
    if not results:
        raise UsageError("--iso230-4: no validation to test")
    if commanded is None:
        commanded = "nominal" if "nominal" in results else next(iter(results))
    reference = results[commanded]
    positions = reference.model_poses[:, :3]
    out = {}
    for name, result in results.items():
        deviation = radial_deviations(session, result.model_poses, euler)
        keep = np.isfinite(deviation)
        out[name] = circular_test(positions[keep], deviation[keep])
    return out


def pose_tests(
    session: Session, results: Mapping[str, Any], tolerance: float = VISIT_TOLERANCE
) -> dict[str, PoseStatistics] | None:
    """The ISO 9283 figures of each geometry's validation (module docstring), by the results'
    names; None when no commanded pose is visited twice."""
    first = next(iter(results.values()))
    attained = first.measured_poses
    if attained is None or not np.all(np.isfinite(attained)):
        raise UsageError(
            f"--iso9283 needs the platform pose at every observation, which {session.instrument.describe()} "
            "does not give"
        )
    visits = visits_of(session.instrument.readings(session.data), tolerance)
    if np.bincount(visits).max(initial=0) < 2:
        return None
    ids = tuple(first.ids)
    return {
        name: pose_statistics(result.model_poses, result.measured_poses, visits, ids)
        for name, result in results.items()
    }
