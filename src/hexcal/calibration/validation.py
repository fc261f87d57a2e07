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

An instrument whose quantities are not all fixed (a frame given as ``auto`` or not in the
setup's ``fixed:``, a tool, targets) may have moved since the calibration: a tracker set up
again, a motion-capture system re-zeroed. Its free quantities are then **re-registered** on the
held-out session, by cross-validation, so that the figures describe the calibration and not the
moved instrument: the poses are dealt at random (``seed``) into ``folds`` folds; the instrument
fitted (machine fixed, maximum likelihood) on the other folds predicts each fold's poses, so no
pose is judged by frames it helped to fit. The default, 5 folds, fits the frames on 80 % of the
session (their own error then adds about ``p / (0.8 m k)`` of the noise variance for ``p``
free quantities, ``m`` poses and ``k`` values per pose) and judges every pose once. The
registration on all the poses is reported beside the figures. What the session cannot
determine (a ball bar's pivot and ball on one level circle) is held as given and named
(:mod:`hexcal.calibration.reregistration`); ``register=`` names the quantities to re-register
when they are not the free ones (the ISO reports: :mod:`hexcal.calibration.iso_validation`).

Compensation (leg commands for targets) is :mod:`hexcal.core.compensation`.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.calibration.accuracy import expected_validation, machine_mask
from hexcal.calibration.identify import register_sessions
from hexcal.calibration.limits import VALIDATION_FOLDS
from hexcal.calibration.reregistration import quantity_mask, reregister, undetermined_quantities
from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import forward_kinematics, inverse_kinematics, leg_lengths, pose_errors
from hexcal.core.noise import NoiseModel
from hexcal.errors import UsageError, ValidationError
from hexcal.estimation.problem import as_sessions
from hexcal.instruments.base import MeasurementModel, Session

_POSE_ITERATIONS = 30

#: Folds of the cross-validated re-registration (module docstring).
DEFAULT_FOLDS = VALIDATION_FOLDS

#: Poses a fold's registration must keep per free quantity of the instrument, at least.
_POSES_PER_QUANTITY = 1.0


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
    measured_poses : ndarray, shape (m, 6), optional
        The platform poses the instrument's values give (NaN where they give none).
    instrument_residuals : ndarray, shape (m, size), optional
        Each value predicted (at ``model_poses``, with the instrument as registered for the
        observation's fold) minus measured, signed, in the instrument's units; NaN where absent.
    instrument : str
        What the instrument is.
    value_labels : tuple of str
        Labels of the columns of a per-value error (the targets ``t1``, ...).
    registration : dict, optional
        The re-registration of the instrument's free quantities (None when all are fixed):
        ``folds``, ``seed``, ``quantities`` (their names), ``held`` (those asked for that the
        session cannot determine, held as given), ``values`` and ``stderr`` fitted on all the
        poses, ``leg_rms_mm`` of that fit at its estimated poses, and ``noise``.
    expected : dict, optional
        What this validation should measure if the calibration is as good as it said
        (:func:`~hexcal.calibration.accuracy.expected_validation` at these poses, with the
        uncertainty the geometry's ``calibration:`` record carries and this session's noise):
        ``position_rms_mm``, ``orientation_rms_rad``, ``leg_rms_mm``, ``from_parameters``,
        ``noise`` (where its σ come from), and ``measured_over_expected`` (the ratio of each
        measured RMS to it). None when the geometry has no such record.
    """

    ids: tuple[str, ...]
    leg_residuals: NDArray[np.float64]
    model_poses: NDArray[np.float64]
    position_error: NDArray[np.float64]
    orientation_error: NDArray[np.float64]
    instrument_errors: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    instrument: str = "full pose in the base frame"
    value_labels: tuple[str, ...] = ()
    registration: dict[str, Any] | None = None
    expected: dict[str, Any] | None = None
    measured_poses: NDArray[np.float64] | None = None
    instrument_residuals: NDArray[np.float64] | None = None

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
            "registration": self.registration,
            "expected": self.expected,
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


def validate(
    geometry: Geometry,
    data: Any,
    instrument: MeasurementModel | None = None,
    *,
    folds: int = DEFAULT_FOLDS,
    seed: int = 0,
    noise: NoiseModel | None = None,
    register: Iterable[str] | None = None,
) -> ValidationResult:
    """Prediction errors of ``geometry`` (and a calibrated instrument) on held-out data.

    Parameters
    ----------
    geometry : Geometry
        The calibrated machine.
    data
        One session, or one data set read by ``instrument`` (default the full pose in the
        base frame).
    instrument : MeasurementModel, optional
        The instrument of ``data``.
    folds : int
        Folds of the re-registration of an instrument with free quantities (module
        docstring); at least 2.
    seed : int
        Seed of the assignment of poses to folds.
    noise : NoiseModel, optional
        The noise the registrations weight with (default learned from the session).
    register : iterable of str, optional
        The instrument's quantities to re-register (names or groups: ``pivot``, ``frame``),
        whatever its setup fixes; default those its setup leaves free, and ``()`` holds them
        all as given. Those the session cannot determine are held at their given values
        (:mod:`hexcal.calibration.reregistration`) and named in ``registration["held"]``.

    Raises
    ------
    ValidationError
        When the forward kinematics of some leg readings does not converge (named by id), or
        the session has too few poses to re-register the instrument in ``folds`` folds.
    """
    session = as_sessions(data, instrument)[0]
    inst = session.instrument
    vary = quantity_mask(inst, register)
    if not (inst.unregistered or vary.any()):
        return _with_expected(_evaluate(geometry, session), geometry, inst, noise, folds)
    if folds < 2:
        raise UsageError(f"folds must be at least 2, got {folds}")
    m, free = len(session), int(np.sum(vary))
    smallest = m - -(-m // folds)  # the smallest training set: all but the largest fold
    if smallest < max(_POSES_PER_QUANTITY * free, 3):
        raise ValidationError(
            f"{m} poses are too few to re-register the instrument's {free} free quantities in {folds} "
            f"folds (each fold's registration keeps {smallest}): measure more poses, or fix the frame "
            "and tool in the setup"
        )
    if inst.unregistered:  # an `auto` frame: its start from the data, once
        session = register_sessions(geometry, [session])[0][0]
    asked = vary.copy()
    vary &= ~undetermined_quantities(geometry, session, vary, noise)
    if not vary.any():  # nothing these data determine: the setup as given
        return _with_expected(_evaluate(geometry, session), geometry, session.instrument, noise, folds)
    whole = reregister(geometry, session, vary, noise)
    noise = whole.noises[0] if noise is None else noise
    fold = np.random.default_rng(seed).permutation(m) % folds
    parts = []
    for f in range(folds):
        train, test = np.flatnonzero(fold != f), np.flatnonzero(fold == f)
        registered = reregister(geometry, session.subset(train), vary, noise).calibrated_instruments()[0]
        parts.append((test, _evaluate(geometry, session.replace(instrument=registered).subset(test))))
    machine = set(geometry.machine_names())
    names = [n for n in whole.names if n not in machine]
    own = session.instrument.parameters()
    record = {
        "folds": folds,
        "seed": seed,
        "quantities": names,
        "held": [n for n, a, v in zip(own.names, asked, vary, strict=True) if a and not v],
        "values": {n: whole.parameters[n] for n in names},
        "stderr": {n: whole.standard_errors[n] for n in names},
        "leg_rms_mm": whole.leg_rms_after,
        "noise": noise.describe(),
    }
    return _with_expected(_merge(parts, m, record), geometry, whole.calibrated_instruments()[0], noise, folds)


def check_folds(data: Any, instrument: MeasurementModel | None = None, folds: int | None = None) -> None:
    """Refuse ``folds`` given for a session with nothing to re-register (the full pose, or an
    instrument whose quantities are all fixed): no fold would be drawn, and the option would be
    ignored silently. ``None`` (not given) is always accepted.

    Raises
    ------
    ValidationError
        Naming what the instrument is and why the folds cannot act.
    """
    if folds is None:
        return
    inst = as_sessions(data, instrument)[0].instrument
    if not (inst.unregistered or quantity_mask(inst).any()):
        raise ValidationError(
            f"--folds {folds}: {inst.describe()} has nothing to re-register (no free frame, tool or "
            "other quantity), so the poses are not dealt into folds; leave --folds out"
        )


def _with_expected(
    result: ValidationResult,
    geometry: Geometry,
    instrument: MeasurementModel,
    noise: NoiseModel | None,
    folds: int,
) -> ValidationResult:
    """``result`` with what it should have measured (``expected``), when the geometry's
    calibration record has the identified machine's uncertainty (written by ``identify``).

    The prediction proper uses the noise the calibration learned (or was given) on its own
    sessions: it is independent of this session, and is what ``identify`` stated. With the
    noise learned on this session by its registration, the same figures under
    ``with_session_noise``: close to the measured ones by construction (the registration absorbs
    into that noise whatever the model does not describe), they separate a noisier session from
    a worse calibration."""
    record = (geometry.calibration or {}).get("uncertainty")
    if record is None:
        return result
    names, cov, gauge, recorded = _uncertainty(record, geometry)
    poses = result.model_poses[np.all(np.isfinite(result.model_poses), axis=1)]
    rigid = gauge if gauge.shape[1] else None
    mask = machine_mask(geometry, names=names)
    summary = result.summary()

    def predict(model: NoiseModel, source: str) -> dict[str, Any]:
        out = expected_validation(geometry, cov, [(instrument, poses, model)], mask, rigid, folds)
        out["noise"] = source  # calibration (its own sessions'), session (learned here) or given
        out["noise_sigmas"] = dict(zip(("leg", "position", "orientation"), model.sigmas, strict=True))
        pairs = (("position_rms", "position_rms_mm"), ("orientation_rms", "orientation_rms_rad"),
                 ("leg_rms", "leg_rms_mm"))  # fmt: skip
        with np.errstate(invalid="ignore", divide="ignore"):
            out["measured_over_expected"] = {
                key: float(summary[own] / out[key]) for own, key in pairs if np.isfinite(summary[own])
            }
        return out

    own = None
    if noise is not None:
        own = predict(noise, "session" if result.registration else "given")
    if recorded is None:
        return replace(result, expected=own)
    expected = predict(recorded, "calibration")
    expected["with_session_noise"] = own
    expected["findings"] = _findings(expected)
    return replace(result, expected=expected)


#: A session measured this many times worse than the calibration predicts (RMS) is not described
#: by the model as well as the calibration's own sessions: the RMS of ``m`` poses scatters by about
#: ``1 / sqrt(2 m)`` (5 % at 100 poses), so a factor 1.5 is no chance.
RATIO_LIMIT = 1.5
#: A σ learned on the session this many times the calibration's is "far above" it.
NOISE_LIMIT = 2.0


def _findings(expected: dict[str, Any]) -> list[str]:
    """What the comparison says when the calibration does not predict the session as it said."""
    out = []
    ratios = expected["measured_over_expected"]
    worse = {k.split("_rms")[0]: v for k, v in ratios.items() if v > RATIO_LIMIT}
    if worse:
        listed = ", ".join(f"{k} {v:.2g}x" for k, v in worse.items())
        out.append(
            f"this session is predicted worse than the calibration's uncertainty and noise say ({listed}): "
            "the model does not describe it as well as its own sessions (leg errors beyond a gain, a "
            "joint that moved, or a noisier session)"
        )
    own = expected.get("with_session_noise")
    if own is not None:
        mine, theirs = own["noise_sigmas"], expected["noise_sigmas"]
        far = {k: mine[k] / theirs[k] for k in mine if theirs[k] > 0 and mine[k] > NOISE_LIMIT * theirs[k]}
        if far:
            listed = ", ".join(f"{k} σ {mine[k]:.3g} ({v:.2g}x)" for k, v in far.items())
            out.append(
                f"the noise learned on this session with the machine fixed is far above the calibration's: "
                f"{listed}: what the model misses shows up as noise"
            )
    return out


def _uncertainty(
    record: Any, geometry: Geometry
) -> tuple[tuple[str, ...], NDArray, NDArray, NoiseModel | None]:
    """The machine parameters' names, covariance and gauge directions of a ``calibration:
    uncertainty`` record (in the geometry's parameter order), and the calibration's noise."""
    where = "the geometry's calibration: uncertainty record"
    try:
        names = tuple(str(n) for n in record["names"])
        cov = np.asarray(record["covariance"], dtype=float)
        gauge = np.asarray(record["gauge"], dtype=float).reshape(len(names), -1)
    except (KeyError, TypeError, ValueError):
        raise ValidationError(
            f"{where} is malformed (names, covariance, gauge): write it again with identify"
        ) from None
    order = [n for n in geometry.machine_names() if n in names]
    if cov.shape != (len(names), len(names)) or len(order) != len(names) or not np.all(np.isfinite(cov)):
        raise ValidationError(
            f"{where} does not match the geometry's parameters: write it again with identify"
        )
    index = [names.index(n) for n in order]
    noise = None
    sigmas = record.get("noise")
    if isinstance(sigmas, dict):
        try:
            noise = NoiseModel(
                float(sigmas["leg"]),
                float(sigmas["position"]),
                float(sigmas["orientation"]),
                distribution="normal",
            )
        except (KeyError, TypeError, ValueError):
            raise ValidationError(f"{where}: noise needs leg, position and orientation σ") from None
    return tuple(order), cov[np.ix_(index, index)], gauge[index], noise


def _merge(parts: list[tuple[NDArray[np.intp], ValidationResult]], m: int, record: dict) -> ValidationResult:
    """The folds' validations in the session's order."""
    order = np.empty(m, dtype=np.intp)
    order[np.concatenate([index for index, _ in parts])] = np.arange(m)
    results = [r for _, r in parts]

    def stack(get: Any) -> NDArray[np.float64]:
        return np.concatenate([get(r) for r in results])[order]

    ids = tuple(np.array([i for r in results for i in r.ids], dtype=object)[order].tolist())
    errors = {k: stack(lambda r, k=k: r.instrument_errors[k]) for k in results[0].instrument_errors}
    first = results[0]
    return ValidationResult(
        ids,
        stack(lambda r: r.leg_residuals),
        stack(lambda r: r.model_poses),
        stack(lambda r: r.position_error),
        stack(lambda r: r.orientation_error),
        errors,
        first.instrument,
        first.value_labels,
        record,
        measured_poses=stack(lambda r: r.measured_poses),
        instrument_residuals=stack(lambda r: r.instrument_residuals),
    )


def _evaluate(geometry: Geometry, session: Session) -> ValidationResult:
    """The validation of a session whose instrument is known."""
    inst, values = session.instrument, session.data
    setup = inst.parameters().values
    if inst.unregistered:
        raise ValidationError("validation needs the instrument frame (it is auto): register it first")
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
    observed, present = inst.observed(values)
    own = np.where(present, inst.residual(setup, fk.poses, geometry.euler, observed), np.nan)
    labels = tuple(label.split()[-1] for label, _ in inst.value_groups())
    return ValidationResult(
        ids, residuals, fk.poses, position, orientation, errors, inst.describe(), labels,
        measured_poses=measured, instrument_residuals=own,
    )  # fmt: skip
