"""The ISO tests of a validation: what ``hexcal validate --iso230-4`` and ``--iso9283`` compute.

:func:`iso_validations` validates the session with each geometry (the calibrated one, the
*after* column, and with ``nominal`` the nominal one, the *before* column), deciding how each
column takes the instrument's setup; :func:`circular_tests` and :func:`pose_tests` turn those
validations into the figures of :mod:`hexcal.calibration.iso_tests` and
:mod:`hexcal.calibration.iso_poses`.

**The setup after calibration.** The after figures describe the calibrated machine with the
instrument as set up, so they must not depend on the frames in which its quantities are
written. A setup's pivot, ball, frame, tool or targets are numbers in some base and platform
frames; a calibration whose instrument had quantities of its own fixed the machine's frames by
hexcal's gauge convention (the joints closest to nominal: the geometry's ``calibration:`` record
says so), and a setup as set up is not written in those frames. So after calibration the
instrument's quantities are **re-registered** on the session for the calibrated machine, by
:func:`~hexcal.calibration.validate`'s cross-validation (each observation judged by quantities
fitted on the other folds; those the session cannot determine held as given): the ones its
setup leaves free and, for a setup as set up with a calibration of the gauge convention, the
ones that move with the frames whatever its ``fixed:`` says. A **calibrated setup**
(``identify --setup-out``: in the calibrated machine's frames) whose quantities are fixed is
used as it is, and so is a setup as set up when the calibration's frames are the set-up's
(full pose, or a frame held in the calibration). ``nominal`` changes the before column only:
the after column is the same with and without it. :func:`after_setup` says which (the pages
print it).

**Before calibration** the nominal machine takes the setup's values as they are (the bar as set
up): ISO 230-4 holds them all (re-registering a pivot would absorb the centre offset the test is
there to show), ISO 9283 re-registers what the setup leaves free, as validate does.

**ISO 230-4 on a one-distance instrument** (a ball bar). For each geometry, the commanded
circle is the least-squares circle of its forward kinematics of the readings. For the nominal
geometry these positions are what the nominal controller commanded, and the actual point lies
at ``|q - c0| + d``; for the calibrated one they are the path the machine took, which only
locates each point on the circle a controller compensated with it is taken to command (at its
own angle): the actual point lies at ``R0 + d``. In both, ``d`` is the measured distance minus
the one that geometry predicts (validate's held-out prediction error, negated). After calibration
``d`` is what the calibrated model does not explain: to first order in the model's errors, what
a compensated machine would deviate from the circle (not a second measured run). The
deviations are along the bar: radial when the pivot lies in the circle's plane.

**ISO 9283 on an instrument that gives the pose** (full pose, a tool, three targets or more).
Visits of the same commanded pose are the observations whose six leg readings agree within a
tolerance (the same leg commands: :func:`~hexcal.calibration.iso_poses.repeated_visits`,
checked by :func:`~hexcal.calibration.iso_poses.check_visits`); their commanded pose is the
forward kinematics of the readings through each geometry, their attained poses those the
instrument gives.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from hexcal.calibration.iso_poses import PoseStatistics, check_visits, pose_statistics
from hexcal.calibration.iso_poses import repeated_visits as visits_of
from hexcal.calibration.iso_tests import CircularTest, circular_test
from hexcal.calibration.limits import VISIT_TOLERANCE
from hexcal.calibration.validation import DEFAULT_FOLDS, ValidationResult, validate
from hexcal.core.geometry import Geometry
from hexcal.core.noise import NoiseModel
from hexcal.errors import UsageError
from hexcal.instruments.base import MeasurementModel, Session

#: The ISO tests, by the name of their option.
ISO_TESTS = ("iso230-4", "iso9283")


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


def calibrated_setup(instrument: MeasurementModel) -> bool:
    """Whether the instrument's setup was written by a calibration (its ``calibration:``
    record): its quantities are then in the calibrated machine's frames."""
    return (instrument.setup_dict() or {}).get("calibration") is not None


def check_nominal_setup(instrument: MeasurementModel, calibrated: ValidationResult) -> None:
    """Refuse, in one line, judging the nominal machine through a calibrated setup whose
    quantities are all fixed (``validate --nominal``, and the before column of ISO 9283): they
    were calibrated with the machine, in its frames."""
    if calibrated.registration is None and calibrated_setup(instrument):
        raise UsageError(
            "--nominal with a calibrated setup whose quantities are all fixed: they were calibrated "
            "with the machine, so the nominal machine cannot be judged through them; leave the frame "
            "free (auto, or not in fixed:) so that validate re-registers it for each machine"
        )


def frames_by_convention(geometry: Geometry) -> bool:
    """Whether the geometry's calibration fixed its base and platform frames by the gauge
    convention (an instrument with quantities of its own on both sides), so that a setup
    written in other frames does not belong to it."""
    record = geometry.calibration or {}
    if str(record.get("gauge") or "none") != "none":
        return True
    gauge = (record.get("uncertainty") or {}).get("gauge") or []
    return bool(gauge) and bool(np.size(gauge[0]))


def frame_quantities(instrument: MeasurementModel, euler: str) -> tuple[str, ...]:
    """The instrument's quantities that change with the base or platform frame (a pivot, a
    ball, a frame, a tool, targets; not a bar's length)."""
    from scipy.spatial.transform import Rotation

    params = instrument.parameters()
    values = np.asarray(params.values, dtype=float)
    turn = (Rotation.from_rotvec([0.01, 0.02, 0.03]).as_matrix(), np.array([1.0, 2.0, 3.0]))
    moved = instrument.transform_setup(values, turn, turn, euler)
    if moved is None:
        return ()
    changed = np.abs(np.asarray(moved) - values) > 1e-9 * (1.0 + np.abs(values))
    return tuple(n for n, c in zip(params.names, changed, strict=True) if c)


def after_quantities(geometry: Geometry, instrument: MeasurementModel) -> tuple[str, ...]:
    """The quantities the after column re-registers (module docstring): those the setup
    leaves free, and those that move with the frames when a setup as set up meets a calibration
    of the gauge convention."""
    params = instrument.parameters()
    free = {n for n, v in zip(params.names, params.vary, strict=True) if v}
    if not calibrated_setup(instrument) and frames_by_convention(geometry):
        free |= set(frame_quantities(instrument, geometry.euler))
    return tuple(n for n in params.names if n in free)


@dataclass(frozen=True)
class IsoValidations:
    """The validations behind the ISO figures, by role (``nominal`` before, ``calibrated``
    after; ``geometry`` alone without a nominal), and how the after column took the setup
    (:func:`after_setup`)."""

    results: dict[str, ValidationResult]
    after: dict[str, Any]

    @property
    def after_result(self) -> ValidationResult:
        """The calibrated machine's validation (the after column)."""
        return self.results.get("calibrated", self.results.get("geometry"))  # type: ignore[return-value]


def after_setup(geometry: Geometry, instrument: MeasurementModel, result: ValidationResult) -> dict[str, Any]:
    """How the after column took the instrument's setup, JSON-ready: ``setup``
    (``re-registered`` or ``as given``), ``calibrated_setup`` (the setup was written by a
    calibration), ``frames`` (``convention`` when the calibration fixed them by the gauge
    convention, else ``set-up``), and for a re-registration its ``quantities``, ``held``,
    ``folds`` and ``seed``."""
    out: dict[str, Any] = {
        "setup": "re-registered" if result.registration else "as given",
        "calibrated_setup": calibrated_setup(instrument),
        "frames": "convention" if frames_by_convention(geometry) else "set-up",
    }
    if result.registration:
        out |= {k: result.registration[k] for k in ("quantities", "held", "folds", "seed")}
    return out


def iso_validations(
    geometry: Geometry,
    session: Session,
    nominal: Geometry | None = None,
    *,
    test: str = "iso230-4",
    folds: int = DEFAULT_FOLDS,
    seed: int = 0,
    noise: NoiseModel | None = None,
) -> IsoValidations:
    """The validations of an ISO test (module docstring): the after column (``geometry``, the
    calibrated machine) and, with ``nominal``, the before column.

    Raises
    ------
    UsageError
        An unknown ``test``, an instrument the test cannot use.
    """
    if test not in ISO_TESTS:
        raise UsageError(f"unknown ISO test {test!r}; choose from {', '.join(ISO_TESTS)}")
    inst = session.instrument
    if test == "iso230-4":
        check_circle_instrument(inst)
    options = {"folds": folds, "seed": seed, "noise": noise}
    after = validate(geometry, session, register=after_quantities(geometry, inst), **options)
    if nominal is None:
        return IsoValidations({"geometry": after}, after_setup(geometry, inst, after))
    if test == "iso9283":
        check_nominal_setup(inst, after)
    held = () if test == "iso230-4" else None
    before = validate(nominal, session, register=held, **options)
    return IsoValidations({"nominal": before, "calibrated": after}, after_setup(geometry, inst, after))


def circular_tests(session: Session, results: Mapping[str, ValidationResult]) -> dict[str, CircularTest]:
    """The ISO 230-4 test of each geometry's validation (module docstring), by the results'
    names (:func:`iso_validations` takes the setup as each column needs it). The one named
    ``nominal`` is the before column: its positions are the commanded path itself (within 1 %
    of a circle, each point where it was commanded); every other result's positions locate its
    points on the circle its controller is taken to command (within 10 %: the path the machine
    took)."""
    check_circle_instrument(session.instrument)
    if not results:
        raise UsageError("--iso230-4: no validation to test")
    out = {}
    for name, result in results.items():
        if result.instrument_residuals is None:
            raise UsageError("--iso230-4: the validation has no prediction errors of the instrument")
        deviation = -result.instrument_residuals[:, 0]
        keep = np.isfinite(deviation) & np.all(np.isfinite(result.model_poses), axis=1)
        located = name != "nominal"
        out[name] = circular_test(result.model_poses[keep, :3], deviation[keep], on_circle=located)
    return out


def pose_tests(
    session: Session, results: Mapping[str, ValidationResult], tolerance: float = VISIT_TOLERANCE
) -> dict[str, PoseStatistics] | None:
    """The ISO 9283 figures of each geometry's validation (module docstring), by the results'
    names; None when no commanded pose is visited twice.

    Raises
    ------
    UsageError
        The instrument does not give the pose; the tolerance joins distinct commanded poses
        (:func:`~hexcal.calibration.iso_poses.check_visits`).
    """
    first = next(iter(results.values()))
    attained = first.measured_poses
    if attained is None or not np.all(np.isfinite(attained)):
        raise UsageError(
            f"--iso9283 needs the platform pose at every observation, which {session.instrument.describe()} "
            "does not give"
        )
    readings = session.instrument.readings(session.data)
    visits = visits_of(readings, tolerance)
    check_visits(readings, visits, tolerance, tuple(first.ids))
    if np.bincount(visits).max(initial=0) < 2:
        return None
    ids = tuple(first.ids)
    return {
        name: pose_statistics(result.model_poses, result.measured_poses, visits, ids)
        for name, result in results.items()
    }
