"""``calibrate``: the one calibration workflow, for Python, notebooks and the command line.

``hexcal identify`` is: read the files, :func:`calibrate`, write what the
:class:`Calibration` holds. Every decision is the library's: the noise learned from the data
and held against what the instruments can do, the leg model (chosen by cross-validation for
``leg_model="auto"``: :func:`hexcal.calibration.leg_model_choice.choose_leg_model`), outliers,
the verdict with its limits (:mod:`hexcal.calibration.verdict`), steps and drifts in
acquisition order, a session split where its instrument moved (``split``:
:mod:`hexcal.calibration.splitting`), the predicted accuracy, each session's registration.
This module only composes them, and gives the result its reports and its file.

>>> import hexcal
>>> from hexcal.core.workspace import workspace_corners
>>> from hexcal.simulation import simulate_session
>>> nominal = hexcal.preset("paper-hmt")
>>> session = simulate_session(nominal, hexcal.preset("paper-hmt-true"), None,
...                            workspace_corners(nominal), rng=1)
>>> calibration = calibrate(nominal, [session])
>>> calibration.verdict.status, calibration.n_parameters
('pass', 42)
>>> round(calibration.parameters["u1.x"], 1)      # the real machine's 305.26
305.3
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.calibration.identify import AUTO, estimate
from hexcal.calibration.leg_model_choice import choose_leg_model, fit_for, parse_leg_model, start_for
from hexcal.calibration.splitting import split_sessions, step_splits
from hexcal.core.geometry import Geometry
from hexcal.core.progress import task
from hexcal.errors import CalibrationFailed, UsageError
from hexcal.estimation.outliers import DEFAULT_ALPHA
from hexcal.estimation.registry import DEFAULT_ESTIMATOR
from hexcal.estimation.sessions import as_sessions
from hexcal.instruments.base import Session


@dataclass(frozen=True, eq=False)
class Calibration:
    """The outcome of :func:`calibrate`: the machine, how well it is known, and the verdict.

    Attributes
    ----------
    result : IdentificationResult
        The fit: parameters, covariance, bound, noise, registrations, the verdict.
    nominal : Geometry
        The geometry the calibration started from (as given, before a leg model was added).
    sessions : tuple of Session
        The sessions calibrated (after any split).
    leg_model : str
        The leg model of the calibrated geometry (``linear``, ``stroke:3``, ...).
    leg_model_choice : LegModelChoice or None
        The cross-validation of ``leg_model="auto"``: candidates and their held-out scores.
    splits : tuple of str
        Where sessions were split (``LABEL:ID``: before that pose).
    before_split : Calibration or None
        With ``split="auto"``: the calibration of the sessions as given, whose verdict found
        the steps.
    inputs : mapping
        Provenance: the files and options that produced it (the command line's), by label.
    """

    result: Any
    nominal: Geometry
    sessions: tuple[Session, ...]
    leg_model: str = "linear"
    leg_model_choice: Any = None
    splits: tuple[str, ...] = ()
    before_split: Calibration | None = None
    inputs: Mapping[str, Any] = field(default_factory=dict)

    # -- what it found ----------------------------------------------------------------
    @property
    def verdict(self) -> Any:
        """``pass``, ``warn`` or ``fail`` (``.status``) with its reasons."""
        return self.result.verdict

    @property
    def status(self) -> str:
        return self.result.verdict_status

    @property
    def failed(self) -> bool:
        """The calibrated geometry should not be used: :meth:`save` refuses it."""
        return self.result.failed

    @property
    def names(self) -> tuple[str, ...]:
        """The identified parameters' names (the machine's, then each session's setup)."""
        return tuple(self.result.names)

    @property
    def n_parameters(self) -> int:
        return len(self.names)

    @property
    def parameters(self) -> dict[str, float]:
        """Identified values by name."""
        return self.result.parameters

    @property
    def units(self) -> dict[str, str]:
        """Each parameter's unit as its value is held (``mm``, ``rad`` or ``1``), by name."""
        from hexcal.report.units import is_angle, is_gain

        return {n: "rad" if is_angle(n) else "1" if is_gain(n) else "mm" for n in self.names}

    @property
    def stderr(self) -> dict[str, float]:
        """Standard errors by name."""
        return self.result.standard_errors

    @property
    def covariance(self) -> NDArray[np.float64]:
        """Covariance of the parameters, in the order of :attr:`names` (gauge-fixed)."""
        return np.asarray(self.result.covariance)

    @property
    def bound(self) -> dict[str, float] | None:
        """The Cramér–Rao σ of each parameter under the noise, by name."""
        bound = self.result.bound
        return None if bound is None else dict(zip(self.names, np.asarray(bound).tolist(), strict=True))

    @property
    def noise(self) -> tuple[Any, ...]:
        """Each session's noise (learned, or as given)."""
        return tuple(self.result.noises)

    @property
    def accuracy(self) -> dict[str, float] | None:
        """The predicted pose accuracy after calibration (the verdict's)."""
        return None if self.verdict is None else self.verdict.accuracy

    @property
    def registrations(self) -> tuple[Any, ...]:
        """How each session's unknown frame was registered (None where none needed it)."""
        return tuple(self.result.registrations)

    @property
    def geometry(self) -> Geometry:
        """The calibrated geometry, named, with its ``calibration:`` mapping (what its file holds)."""
        result = self.result
        calibration = result.calibration_metadata()
        for key in ("data", "setup"):
            if key in self.inputs:
                calibration[key] = self.inputs[key]
        calibration["outliers"] = list(result.outliers)
        if self.leg_model_choice is not None:
            calibration["leg_model_choice"] = self.leg_model_choice.to_dict()
        if self.splits:
            calibration["splits"] = list(self.splits)
        if result.convention:
            calibration["gauge"] = result.convention
        name = f"{self.nominal.name}-calibrated" if self.nominal.name else "calibrated"
        return result.geometry.replace(name=name, calibration=calibration)

    def calibrated_setups(self) -> tuple[dict[str, Any] | None, ...]:
        """Each session's calibrated setup, as the mapping of its setup file (None: none)."""
        return tuple(inst.setup_dict() for inst in self.result.calibrated_instruments())

    # -- reports and files ------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The one schema every report renders (text, JSON, HTML): ``hexcal identify --json``
        writes exactly this. Built once (the reports share it: do not change it in place)."""
        return self._dict

    @cached_property
    def _dict(self) -> dict[str, Any]:
        from hexcal.report import calibration_dict

        return calibration_dict(self)

    def report(self, fmt: str = "text") -> str:
        """The report as text (``fmt="text"``) or strict JSON (``"json"``)."""
        from hexcal.report import render

        return render("identification", self.to_dict(), fmt)

    def html(self) -> str:
        """The self-contained HTML page of ``hexcal identify --html``."""
        from hexcal.report import identification_report, render_html

        return render_html(identification_report(self))

    def _repr_html_(self) -> str:  # a notebook shows the verdict and the parameters
        from hexcal.report import calibration_summary

        return calibration_summary(self.to_dict())

    def __repr__(self) -> str:
        return f"<Calibration {self.status}: {self.n_parameters} parameters, {self.result.n_poses} poses>"

    def save(self, path: str | os.PathLike[str], *, force: bool = False) -> None:
        """Write the calibrated geometry file; a failed calibration is refused
        (:class:`CalibrationFailed`, its reasons in one line) unless ``force``."""
        from hexcal.io import save_geometry

        if self.failed and not force:
            raise CalibrationFailed(
                f"verdict fail: {self.failure()}; nothing written (force writes it anyway)"
            )
        save_geometry(self.geometry, path)

    def failure(self) -> str:
        """The fail and warn reasons of the verdict, in one line."""
        reasons = self.verdict.reasons if self.verdict is not None else ()
        serious = [r.message for r in reasons if r.severity == "fail"]
        serious += [r.message for r in reasons if r.severity == "warn"]
        return "; ".join(serious)

    def save_setups(self, paths: Sequence[str | os.PathLike[str]], *, force: bool = False) -> None:
        """Write each session's calibrated setup (one path per session, in order)."""
        from hexcal.io import save_setup_dict

        if self.failed and not force:
            raise CalibrationFailed(
                f"verdict fail: {self.failure()}; nothing written (force writes it anyway)"
            )
        for path, setup in zip(paths, self.calibrated_setups(), strict=False):
            save_setup_dict(setup, path)


def calibrate(
    nominal: Geometry,
    sessions: Any,
    *,
    method: str = DEFAULT_ESTIMATOR,
    noise: Any = AUTO,
    fit: str | Sequence[str] | None = None,
    fix: Sequence[str] = (),
    leg_model: str | None = None,
    robust: bool = False,
    split: str | Sequence[str] | None = None,
    sigma_limit: float | None = None,
    max_change: float | None = None,
    alpha: float = DEFAULT_ALPHA,
    inputs: Mapping[str, Any] | None = None,
    **options: Any,
) -> Calibration:
    """Calibrate a machine from measurement sessions (module docstring).

    Parameters
    ----------
    nominal : Geometry
        The controller's geometry (start values), with its leg model.
    sessions : Session or sequence of Session
        The measurement sessions (:func:`hexcal.io.read_sessions` reads them from files).
    method : str
        Estimator (:data:`hexcal.estimation.ESTIMATORS`; default maximum likelihood).
    noise : "auto" or NoiseModel or one per session
        ``"auto"`` (default) learns it from the data, per session and group.
    fit, fix
        Parameter groups to identify (default joints and ``l0``, and the leg model's own
        terms) and names or groups to hold.
    leg_model : str, optional
        ``linear``, ``stroke[:DEGREE]``, a registered model, or ``auto`` (chosen by
        cross-validation); default the nominal geometry's own.
    robust : bool
        Leave outliers out.
    split : "auto" or sequence of str, optional
        Split sessions where their instrument moved: ``LABEL:ID`` splits (the first pose after
        the step), or ``"auto"``: where the verdict finds a step (the calibration of the
        sessions as given is kept in :attr:`Calibration.before_split`).
    sigma_limit, max_change : float, optional
        The verdict's limits (default :data:`hexcal.calibration.SIGMA_LIMIT` of the platform
        radius and :data:`hexcal.calibration.MAX_CHANGE`).
    alpha : float
        Level of the outlier check.
    inputs : mapping, optional
        Provenance recorded with the result (files, options).
    **options
        Passed to the estimator.
    """
    given = list(as_sessions(sessions))
    inputs = dict(inputs or {})
    explicit = () if split in (None, AUTO) else ((split,) if isinstance(split, str) else tuple(split))
    done: tuple[str, ...] = ()
    if explicit:
        given, done = split_sessions(given, explicit)
    with task("calibration") as step:
        start, fit, choice, spec = _leg_model(nominal, given, leg_model, method, fit, fix, noise)
        common = dict(
            noise=noise, fit=fit, fix=fix, robust=robust, sigma_limit=sigma_limit, max_change=max_change
        )
        result = estimate(start, given, method, alpha=alpha, **common, **options)
        step()
        first = None
        if split == AUTO:
            steps = step_splits(result.verdict)
            if steps:  # the sessions as given are kept: their verdict found the steps
                first = Calibration(result, nominal, tuple(given), spec, choice, done, None, inputs)
                given, more = split_sessions(given, steps)
                done += more
                result = estimate(start, given, method, alpha=alpha, **common, **options)
                step()
    return Calibration(result, nominal, tuple(given), spec, choice, done, first, inputs)


def _leg_model(
    nominal: Geometry,
    sessions: list[Session],
    leg_model: str | None,
    method: str,
    fit: Any,
    fix: Sequence[str],
    noise: Any,
) -> tuple[Geometry, Any, Any, str]:
    """The start geometry with the leg model, the fitted groups with its own, the choice of
    ``auto`` (or None), and the model's name."""
    if leg_model is None:
        return nominal, fit, None, _spec(nominal)
    choice = None
    if parse_leg_model(leg_model)[0] == AUTO:
        choice = choose_leg_model(nominal, sessions, method=method, fit=fit, fix=fix, noise=noise)
        leg_model = choice.choice
    start = start_for(leg_model, nominal, sessions)
    return start, fit_for(fit, start.leg_model), choice, _spec(start)


def _spec(geometry: Geometry) -> str:
    """The leg model's name as ``leg_model=`` takes it (``stroke:3``)."""
    legs = geometry.leg_model
    degree = getattr(legs, "degree", None)
    return f"{legs.name}:{degree}" if degree is not None else legs.name


def check_split(split: Any) -> None:
    """Refuse a ``split`` that is neither ``auto`` nor ``LABEL:ID`` texts."""
    if split is None or split == AUTO:
        return
    items = (split,) if isinstance(split, str) else split
    if not all(isinstance(s, str) and s.strip() for s in items):
        raise UsageError(f"split must be 'auto' or LABEL:ID texts, got {split!r}")


__all__ = ["Calibration", "calibrate"]
