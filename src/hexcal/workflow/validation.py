"""``validate``: the one validation workflow, for Python, notebooks and the command line.

``hexcal validate`` is: read the files, :func:`validate`, write what the :class:`Validation`
holds. Every decision is the library's: how the calibrated machine takes the instrument's
setup (its free quantities re-registered on the session by cross-validation:
:func:`hexcal.calibration.validate`), what the calibration expected it to measure, the nominal
machine side by side (refused through a calibrated setup whose quantities are all fixed), and
the ISO 230-4 circular test or the ISO 9283 pose figures, before and after calibration, with
how each column took the setup (:mod:`hexcal.calibration.iso_validation`). This module only
composes them, and gives the result its reports (text, JSON, HTML, the per-pose table, the
polar figure): each renders :meth:`Validation.to_dict`.

One step below, :func:`hexcal.calibration.validate` validates one geometry and returns its
:class:`~hexcal.calibration.ValidationResult` (:attr:`Validation.calibrated` is one).

>>> import hexcal
>>> from hexcal.simulation import simulate_session
>>> nominal, real = hexcal.preset("paper-hmt"), hexcal.preset("paper-hmt-true")
>>> held_out = simulate_session(nominal, real, None, hexcal.random_poses(nominal, 10, 2), rng=3)
>>> check = validate(real, held_out, nominal=nominal)
>>> check.to_dict()["position_rms_mm"] < 0.1 < check.to_dict()["nominal"]["position_rms_mm"]
True
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

from hexcal.calibration.iso_poses import check_visit_tolerance
from hexcal.calibration.iso_validation import (
    check_circle_instrument,
    check_nominal_setup,
    circular_tests,
    iso_validations,
    pose_tests,
)
from hexcal.calibration.limits import VALIDATION_FOLDS, VISIT_TOLERANCE
from hexcal.calibration.validation import ValidationResult, check_folds
from hexcal.calibration.validation import validate as validate_geometry
from hexcal.core.geometry import Geometry
from hexcal.core.noise import NoiseModel
from hexcal.core.stroke_legs import stroke_excess
from hexcal.errors import UsageError
from hexcal.estimation.sessions import as_sessions
from hexcal.instruments.base import Session


@dataclass(frozen=True)
class IsoTests:
    """The ISO test of a validation (``hexcal validate --iso230-4`` or ``--iso9283``).

    Attributes
    ----------
    test : str
        ``iso230-4`` or ``iso9283``.
    names : tuple of str
        The columns by role: ``("nominal", "calibrated")`` (before and after calibration), or
        ``("geometry",)`` without a nominal geometry.
    circular : dict of str to CircularTest, optional
        ISO 230-4: the circular test of each column.
    poses : dict of str to PoseStatistics, optional
        ISO 9283: the pose accuracy and repeatability of each column (None when no commanded
        pose is visited twice: ``note`` says so).
    note : str, optional
        Why there are no figures.
    tolerance : float, optional
        ISO 9283: the tolerance (mm) on the leg readings of visits of one commanded pose.
    after : dict
        How the after column took the instrument's setup
        (:func:`hexcal.calibration.iso_validation.after_setup`).
    """

    test: str
    names: tuple[str, ...]
    circular: dict[str, Any] | None = None
    poses: dict[str, Any] | None = None
    note: str | None = None
    tolerance: float | None = None
    after: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class Validation:
    """The outcome of :func:`validate`: how well the calibrated machine predicts a session it
    has not seen, beside the nominal machine and what the calibration expected.

    Attributes
    ----------
    calibrated : ValidationResult
        The calibrated machine's validation (the after column of an ISO test): per-pose errors,
        the re-registration of the instrument's free quantities (``registration``), what the
        calibration expected (``expected``).
    nominal : ValidationResult or None
        The nominal machine's, on the same session (the before column), when asked for.
    geometry : Geometry
        The calibrated geometry.
    session : Session
        The held-out session.
    nominal_geometry : Geometry or None
    iso : IsoTests or None
        The ISO test asked for.
    folds, seed : int
        The cross-validation of a re-registration.
    warnings : tuple of str
        What the command line prints as warnings (one line each): legs taken beyond a stroke
        model's calibrated stroke.
    beyond_stroke : StrokeExcess or None
        How far the session's readings go beyond the calibrated stroke (a stroke model).
    inputs : mapping
        Provenance: the files and options that produced it (the command line's), by label.
    """

    calibrated: ValidationResult
    nominal: ValidationResult | None
    geometry: Geometry
    session: Session
    nominal_geometry: Geometry | None = None
    iso: IsoTests | None = None
    folds: int = VALIDATION_FOLDS
    seed: int = 0
    warnings: tuple[str, ...] = ()
    inputs: Mapping[str, Any] = field(default_factory=dict)
    beyond_stroke: Any = None

    # -- what it found ----------------------------------------------------------------
    @property
    def ids(self) -> tuple[str, ...]:
        """The held-out observations' ids."""
        return tuple(self.calibrated.ids)

    @property
    def registration(self) -> dict[str, Any] | None:
        """How the instrument's free quantities were re-registered for the calibrated machine
        (None when the setup was used as given)."""
        return self.calibrated.registration

    @property
    def expected(self) -> dict[str, Any] | None:
        """What the calibration's own uncertainty says this validation should measure, and
        the ratio of each measured RMS to it (None without the geometry's record)."""
        return self.calibrated.expected

    # -- reports and files ------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The one schema every report renders (text, JSON, HTML, the per-pose table, the polar
        figure): ``hexcal validate --json`` writes exactly this. Built once (the reports share
        it: do not change it in place)."""
        return self._dict

    @cached_property
    def _dict(self) -> dict[str, Any]:
        from hexcal.report import validation_report_dict

        return validation_report_dict(self)

    def report(self, fmt: str = "text") -> str:
        """The report as text (``fmt="text"``: the validation, then the ISO figures) or strict
        JSON (``"json"``)."""
        from hexcal.report import render

        return render("validation", self.to_dict(), fmt)

    def html(self) -> str:
        """The self-contained HTML page of ``hexcal validate --html`` (the ISO page with an ISO
        test)."""
        from hexcal.report import render_html, validation_report

        return render_html(validation_report(self.to_dict()))

    def table(self) -> tuple[list[str], Any, list[str], str]:
        """The per-pose table of ``hexcal validate --out``: ``(columns, rows, ids, comment)``."""
        from hexcal.report import validation_table

        return validation_table(self.to_dict())

    def save_table(self, path: str | os.PathLike[str]) -> None:
        """Write the per-pose table (CSV; an empty cell where a value does not exist)."""
        from hexcal.io import write_table

        columns, rows, ids, comment = self.table()
        write_table(path, columns, rows, ids, comment=comment, missing=True)

    def save_polar(self, path: str | os.PathLike[str]) -> None:
        """Write the polar figure of the ISO 230-4 circular test (PNG).

        Raises
        ------
        UsageError
            When the validation has no circular test (``iso230_4=True``).
        """
        from hexcal.report import plot_polar_deviation

        iso = self.to_dict()["iso"]
        if iso is None or not iso.get("iso230_4"):
            raise UsageError("--polar draws the circular test: give --iso230-4")
        plot_polar_deviation(iso["iso230_4"], path, iso["labels"])

    def _repr_html_(self) -> str:  # a notebook shows the figures side by side
        from hexcal.report import validation_summary

        return validation_summary(self.to_dict())

    def __repr__(self) -> str:
        position = self.calibrated.summary()["position_rms"]
        shown = f", position RMS {position:.4g} mm" if math.isfinite(position) else ""
        return f"<Validation on {len(self.ids)} held-out observations ({self.calibrated.instrument}){shown}>"


def check_options(
    *,
    iso230_4: bool = False,
    iso9283: bool = False,
    visit_tolerance: float | None = None,
    folds: int | None = None,
    polar: bool = False,
) -> None:
    """Refuse, before any work and in one line, options of :func:`validate` that cannot act
    together: both ISO tests, a visit tolerance without ISO 9283 (or out of bounds), fewer than
    two folds, a polar figure without the circular test (``polar``: the command line's
    ``--polar``).

    Raises
    ------
    UsageError, InputError
    """
    if folds is not None and (isinstance(folds, bool) or not isinstance(folds, int) or folds < 2):
        raise UsageError(f"--folds must be at least 2, got {folds}")
    if polar and not iso230_4:
        raise UsageError("--polar draws the circular test: give --iso230-4")
    if iso230_4 and iso9283:
        raise UsageError("--iso230-4 (a ball bar) and --iso9283 (the pose) need different instruments")
    if visit_tolerance is not None:
        if not iso9283:
            raise UsageError("--visit-tolerance groups the visits of --iso9283: give --iso9283")
        check_visit_tolerance(visit_tolerance)


def validate(
    calibrated: Any,
    session: Any,
    *,
    nominal: Geometry | None = None,
    iso230_4: bool = False,
    iso9283: bool = False,
    visit_tolerance: float | None = None,
    folds: int | None = None,
    seed: int = 0,
    noise: NoiseModel | None = None,
    inputs: Mapping[str, Any] | None = None,
) -> Validation:
    """Validate a calibration on a held-out session (module docstring).

    Parameters
    ----------
    calibrated : Geometry or Calibration
        The calibrated machine (a :class:`~hexcal.workflow.Calibration`: its geometry).
    session : Session, or a sequence of one
        The held-out session (:func:`hexcal.io.read_sessions` reads it from files), with the
        instrument's setup: quantities it leaves free are re-registered on the session.
    nominal : Geometry, optional
        Also validate this geometry, side by side (a free frame or tool re-registered for it
        too); with an ISO test, the before column.
    iso230_4 : bool
        The ISO 230-4 circular test of a ball-bar circle (one distance per observation).
    iso9283 : bool
        The ISO 9283 pose accuracy and repeatability of the poses visited more than once (the
        instrument gives the pose).
    visit_tolerance : float, optional
        ISO 9283: observations whose six leg readings agree within it (mm) are visits of one
        commanded pose (default :data:`hexcal.calibration.limits.VISIT_TOLERANCE`).
    folds : int, optional
        Folds of the cross-validated re-registration (at least 2; default
        :data:`hexcal.calibration.limits.VALIDATION_FOLDS`); refused when the session has
        nothing to re-register (:func:`hexcal.calibration.validation.check_folds`).
    seed : int
        Seed of the poses' folds.
    noise : NoiseModel, optional
        The noise the registrations weight with (default learned from the session).
    inputs : mapping, optional
        Provenance recorded with the result (files, options).

    Raises
    ------
    UsageError
        Options that cannot act together (:func:`check_options`), several sessions, an
        instrument the ISO test cannot use, the nominal machine through a calibrated setup
        whose quantities are all fixed.
    ValidationError
        Forward kinematics that does not converge, too few poses to re-register.
    """
    check_options(iso230_4=iso230_4, iso9283=iso9283, visit_tolerance=visit_tolerance, folds=folds)
    geometry = getattr(calibrated, "geometry", calibrated)
    if not isinstance(geometry, Geometry):
        raise UsageError(f"validate: a calibrated Geometry or Calibration, not {type(calibrated).__name__}")
    sessions = as_sessions(session)
    if len(sessions) != 1:
        raise UsageError(
            f"validate: one session at a time, got {len(sessions)} (validate each session on its own)"
        )
    held = sessions[0]
    check_folds(held, folds=folds)  # folds given where nothing is re-registered cannot act
    folds = VALIDATION_FOLDS if folds is None else folds
    options = {"folds": folds, "seed": seed, "noise": noise}
    common = {"geometry": geometry, "session": held, "nominal_geometry": nominal, "folds": folds}
    common |= {"seed": seed, "inputs": dict(inputs or {})}
    beyond = stroke_excess(geometry, held.instrument.readings(held.data), ids=held.ids)
    line = beyond.warning("pose(s) of the session") if beyond is not None else None
    common |= {"warnings": (line,) if line else (), "beyond_stroke": beyond}
    if not (iso230_4 or iso9283):
        after = validate_geometry(geometry, held, **options)
        before = None
        if nominal is not None:
            check_nominal_setup(held.instrument, after)
            before = validate_geometry(nominal, held, **options)
        return Validation(after, before, **common)
    test = "iso230-4" if iso230_4 else "iso9283"
    if iso230_4:
        check_circle_instrument(held.instrument)
    checked = iso_validations(geometry, held, nominal, test=test, **options)
    results = checked.results
    names = tuple(results)
    if iso230_4:
        iso = IsoTests(test, names, circular=circular_tests(held, results), after=checked.after)
    else:
        tolerance = VISIT_TOLERANCE if visit_tolerance is None else visit_tolerance
        poses = pose_tests(held, results, tolerance)
        note = None
        if poses is None:
            within = f"leg readings within {tolerance:g} mm"
            note = f"no commanded pose is visited twice ({within}): nothing to report"
        iso = IsoTests(test, names, poses=poses, note=note, tolerance=tolerance, after=checked.after)
    return Validation(checked.after_result, results.get("nominal"), iso=iso, **common)


__all__ = ["IsoTests", "Validation", "validate"]
