"""``estimate``: the one entry point of identification, for every instrument and session.

From the nominal geometry and one or more measurement sessions (each its data and the
instrument that recorded them), :func:`estimate`

1. registers what the data must settle before a fit can start (an instrument frame given as
   ``auto``: :meth:`MeasurementModel.register`);
2. builds the :class:`~hexcal.estimation.problem.Problem` (the machine shared, each session's
   instrument quantities its own), learns the noise of every session and group from the data
   (``noise="auto"``, :mod:`hexcal.estimation.noise_estimation`) or checks a given one;
3. runs a registered estimator (:mod:`hexcal.estimation.registry`; the ones that need the
   pose refused in one line where an instrument does not give it), optionally leaving
   outliers out (:mod:`hexcal.estimation.outliers`);
4. attaches the Cramér–Rao bound, the outlier check and the verdict with its predicted
   accuracy and diagnoses (:mod:`hexcal.calibration.verdict`).

>>> from hexcal.core.presets import preset
>>> from hexcal.core.workspace import workspace_corners
>>> from hexcal.estimation.uncertainty import planned_measurements
>>> nominal, real = preset("paper-hmt"), preset("paper-hmt-true")
>>> data = planned_measurements(real, workspace_corners(nominal)[1::3])  # exact, noise-free
>>> result = estimate(nominal, data, "length")
>>> result.rank, result.n_poses
(42, 21)
>>> round(result.parameters["u1.x"], 4)    # the real machine's u1.x
305.2599
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from hexcal.calibration import diagnosis
from hexcal.calibration.diagnosis import Quality
from hexcal.calibration.noise_judgement import reference_noises
from hexcal.calibration.verdict import FAIL_FACTOR, MAX_CHANGE, assess, limit_scale, undetermined
from hexcal.core.geometry import Geometry
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import ParameterSet
from hexcal.errors import GeometryError, HexcalError, IdentificationError, InputError, UsageError
from hexcal.estimation.gauge import gauge_freedoms, unidentifiable
from hexcal.estimation.least_squares import fit_least_squares
from hexcal.estimation.likelihood import ml_misfit
from hexcal.estimation.noise_check import NoiseCheck, check_noise
from hexcal.estimation.noise_estimation import NoiseEstimate, estimate_noise
from hexcal.estimation.outliers import DEFAULT_ALPHA, SCREEN_THRESHOLD, pose_diagnostics
from hexcal.estimation.problem import Problem, as_sessions, session_noises
from hexcal.estimation.registry import DEFAULT_ESTIMATOR, get_estimator
from hexcal.estimation.result import IdentificationResult
from hexcal.estimation.robust import identify_robust, screen_poses
from hexcal.estimation.sessions import refuse_repeated_sessions
from hexcal.estimation.uncertainty import bound_stderr, gauge_fixed_covariance, projected_jacobian
from hexcal.instruments.base import MeasurementModel, Session

#: ``noise=`` value (and ``default_noise``) that learns the noise from the data.
AUTO = "auto"

#: Evaluations a diagnosis refit may take (its last iterate counts: the variants are compared).
_DIAGNOSIS_NFEV = 60

#: How a fit fails outright (a solver that did not converge, a geometry beyond validity, a
#: degenerate solution): the diagnoses then look for the cause among re-readings of the data.
_FIT_FAILURES = (IdentificationError, GeometryError, InputError, np.linalg.LinAlgError)


def register_sessions(start: Geometry, sessions: Sequence[Session]) -> tuple[list[Session], tuple[Any, ...]]:
    """Each session with its unknown quantities registered (start values), and the records."""
    out, records = [], []
    for session in sessions:
        instrument, record = session.instrument.register(start, session.data)
        out.append(session.replace(instrument=instrument))
        records.append(record)
    return out, tuple(records)


def _noise(noise: Any) -> Any:
    if noise is None:
        return AUTO
    if isinstance(noise, str) and noise != AUTO:
        raise UsageError(f"noise must be a NoiseModel or {AUTO!r}, got {noise!r}")
    return noise


def estimate(
    start: Geometry,
    measurements: Any,
    method: str = DEFAULT_ESTIMATOR,
    mask: ArrayLike | None = None,
    noise: NoiseModel | Sequence[NoiseModel] | str | None = None,
    with_bound: bool = True,
    *,
    model: MeasurementModel | None = None,
    parameters: ParameterSet | None = None,
    fit: str | Sequence[str] | None = None,
    fix: Iterable[str] = (),
    robust: bool = False,
    diagnose: bool | None = None,
    alpha: float = DEFAULT_ALPHA,
    verdict: bool | None = None,
    sigma_limit: float | None = None,
    max_change: float | None = None,
    **options: Any,
) -> IdentificationResult:
    """Identify the machine from measurement sessions with any registered estimator.

    Parameters
    ----------
    start : Geometry
        Start values (the nominal geometry); parameters not varied keep its values.
    measurements
        A :class:`~hexcal.instruments.Session`, a list of sessions (one machine, each
        session its own instrument quantities), or one data set read by ``model`` (default
        the full pose in the base frame, :class:`hexcal.instruments.Measurements`).
    method : str
        A name of :data:`hexcal.estimation.registry.ESTIMATORS` (default ``"ml"``).
    mask : array_like of bool, optional
        Varied machine parameters (48 flags for linear legs; default joints and ``l0``);
        the instruments' free quantities vary too.
    noise : NoiseModel, one per session, or "auto", optional
        The measurement noise: used by the noise-weighted estimators and for the bound and
        the outlier check of every estimator. ``"auto"`` (the default, ``None`` too) learns it
        from the data, per session and group (``result.noise_source == "estimated"``), held
        against what the instruments can do (:mod:`hexcal.calibration.noise_judgement`). A
        given model is checked against the data (``result.noise_check``).
    with_bound : bool
        Attach the Cramér–Rao bound (``result.bound``) and the noise model.
    model : MeasurementModel, optional
        The instrument of ``measurements`` when they are not sessions.
    parameters : ParameterSet, optional
        The whole parameter set, replacing ``mask``/``fit``/``fix``.
    fit, fix
        Parameter groups to vary (``joints``, ``l0``, ``gains``, ``frame``, ``tool``,
        ``targets``, ...) and names or groups to hold, instead of ``mask``.
    robust : bool
        Leave out outliers (:func:`hexcal.estimation.robust.identify_robust`, with this
        estimator); what was left out is in ``result.outliers``.
    diagnose : bool, optional
        Check every observation for implausible residuals (``result.flagged``); default
        ``with_bound``.
    alpha : float
        Family-wise false alarm rate of the outlier check.
    verdict : bool, optional
        Judge the fit (``result.verdict``, :func:`hexcal.calibration.verdict.assess`);
        default ``with_bound``.
    sigma_limit : float, optional
        The identifiability limit as a fraction of the platform radius (default
        :data:`hexcal.calibration.verdict.SIGMA_LIMIT`): a parameter combination whose
        predicted σ exceeds it is poorly determined, beyond 3 times it undetermined (gains:
        1e-3 relative, instrument angles 1e-3 rad per mm of it).
    max_change : float, optional
        Largest plausible parameter change as a fraction of the machine's size (default
        :data:`hexcal.calibration.verdict.MAX_CHANGE`).
    **options
        Passed to the estimator (e.g. ``xtol``, ``max_nfev``).

    Returns
    -------
    IdentificationResult
    """
    given = as_sessions(measurements, model)
    refuse_repeated_sessions(given)
    absolute = diagnosis.absolute_readings(start, given)
    if absolute is not None:
        raise InputError(absolute)
    noise = _noise(noise)
    auto = isinstance(noise, str)
    sigma_limit = limit_scale(start, sigma_limit)
    max_change = MAX_CHANGE if max_change is None else max_change
    if not max_change > 0:
        raise UsageError(f"max_change must be > 0, got {max_change}")
    estimator = get_estimator(method)
    diagnose = with_bound if diagnose is None else diagnose
    verdict = with_bound if verdict is None else verdict
    if auto and not (with_bound or verdict or diagnose or robust or estimator.uses_noise):
        noise, auto = NoiseModel(), False  # nothing would use it: no need to learn it
    sessions, registrations = register_sessions(start, given)
    problem = Problem(start, sessions, mask=mask, parameters=parameters, fit=fit, fix=fix)
    if estimator.needs_pose and not problem.determines_pose:
        estimator.fit(problem)  # refuses in one line, naming the session
    try:
        noise_estimate = noise_check = None
        flagged: tuple[str, ...] = ()
        if robust:
            problem.check_size()  # too few poses by the data's count, before any is set aside
            if auto:
                noise_estimate = _robust_noise(problem, options)
                noise = noise_estimate.noises
            with np.errstate(over="ignore"):  # a gross outlier's deletion statistic may be inf
                robust_fit = identify_robust(
                    start, problem=problem, method=method, alpha=alpha, noise=noise, **options
                )
            result, used = robust_fit.result, robust_fit.problem
        else:
            if auto:
                noise_estimate, ml_fit = _learn_noise(problem, options)
                noise = noise_estimate.noises
                result = ml_fit if method == "ml" else estimator.fit(problem, noise, **options)
            else:
                result = estimator.fit(problem, noise, **options)
                if verdict:
                    noise_check = _check(problem, noise, result, alpha)
            used = problem
            if diagnose:
                flagged = _flagged(problem, result, method, noise, alpha)
        noises = session_noises(used, noise)
        bound = None
        if with_bound:
            poses = None if used.determines_pose else result.poses
            bound = bound_stderr(_at_result(used, result), noises, poses=poses)
        result = result.replace(
            bound=bound,
            noise=noises[0],
            noises=noises,
            flagged=flagged,
            noise_source="estimated" if auto else "given",
            noise_estimate=noise_estimate,
            noise_check=noise_check,
            registrations=registrations,
        )
    except _FIT_FAILURES as exc:
        if verdict:  # name the likely cause (a unit, an Euler sequence, weak poses) in the one line
            _explain_failure(exc, problem, given, noise if not auto else None, sigma_limit)
        raise
    if verdict:

        def run_diagnosis(bad: bool) -> list:
            return diagnosis.diagnose(result, given, _refit(_diagnosis_noises(noises, auto)), bad)

        judged = assess(
            result,
            used,
            noise_estimate=noise_estimate,
            noise_check=noise_check,
            sigma_limit=sigma_limit,
            max_change=max_change,
            alpha=alpha,
            robust=robust,
            diagnose=run_diagnosis,
            noise=noises,
            reference=_as_given(used, given),
        )
        result = result.replace(verdict=judged)
    return result


def _at_result(problem: Problem, result: IdentificationResult) -> Problem:
    """The problem with its start values at the fit's values (instruments calibrated)."""
    full = np.array(problem.full0)
    full[problem.mask] = result.values
    sessions = [
        p.session.replace(instrument=inst, label=p.label)
        for p, inst in zip(problem.parts, problem.instruments(full), strict=True)
    ]
    return Problem(problem.geometry(full), sessions, parameters=problem.parameters.with_values(full))


def _as_given(problem: Problem, given: Sequence[Session]) -> np.ndarray:
    """The varied parameters as the user gave them (each instrument's setup before the data
    registered it): what a change is measured from. A free tool's registered start can be tens
    of millimetres from the setup's tool (the nominal machine's errors through the platform's
    small rotations); the calibrated tool is judged against the setup, not that start."""
    full = np.array(problem.full0)
    for part, session in zip(problem.parts, given, strict=True):
        full[part.block] = session.instrument.parameters().values
    return full[problem.mask]


def _flagged(problem: Problem, result: IdentificationResult, method: str, noise: Any, alpha: float) -> tuple:
    """Labels of the observations (and value groups) the outlier check flags.

    Where every instrument gives the pose, the whitened deletion statistic follows its F
    distribution exactly on the generalised least-squares fit of the same data, which is
    computed for the check; else it is taken at the maximum-likelihood solution."""
    fitted = result
    if problem.determines_pose and method != "gls":
        fitted = get_estimator("gls").fit(problem, noise)
    with np.errstate(over="ignore"):  # a gross outlier's statistic may be inf
        diag = pose_diagnostics(fitted, problem=problem, alpha=alpha, noise=noise)
    return diag.flagged_labels(problem.ids)


def _check(problem: Problem, noise: Any, result: IdentificationResult, alpha: float) -> NoiseCheck | None:
    """The given noise against the data (None when it has no noise to test)."""
    noises = session_noises(problem, noise)
    if any(n.sigmas[0] <= 0 or not n.has_pose_noise for n in noises):
        return None
    try:
        return check_noise(problem, noises, result, alpha)
    except (HexcalError, np.linalg.LinAlgError):
        return None


def _robust_noise(problem: Problem, options: dict) -> NoiseEstimate:
    """Variance components from the observations that the robust screening keeps."""
    scores = screen_poses(problem.start, problem=problem, noise=NoiseModel())
    limit = int(0.25 * len(scores))
    drop = np.argsort(-scores)[:limit]
    keep = np.ones(len(scores), dtype=bool)
    keep[drop[scores[drop] > SCREEN_THRESHOLD]] = False
    return _learn_noise(problem.subset(keep), options)[0]


def _learn_noise(problem: Problem, options: dict) -> tuple[NoiseEstimate, IdentificationResult]:
    """The noise of every session and group learned from the data; where these data cannot
    determine a group, held at what its instrument declares or such instruments typically do
    (:func:`hexcal.calibration.noise_judgement.reference_noises`). The iteration starts from the
    seed paper's noise, lenient towards the instrument: a first fit under a strict instrument
    weight (a ballbar's micrometre) can fall into another minimum."""
    references = reference_noises([p.instrument for p in problem.parts])
    return estimate_noise(problem, fallback=references, **options)


def _explain_failure(
    exc: Exception, problem: Problem, given: Sequence[Session], noise: Any, sigma_limit: float
) -> None:
    """Raise the failure again with its likely cause when one is found: a unit or Euler
    re-reading of the data that fits (:func:`hexcal.calibration.diagnosis.explain_failure`), or
    else the combinations the poses do not determine (poses that barely rotate make the
    solver run out of evaluations rather than the rank fall)."""
    noises = _diagnosis_noises(session_noises(problem, noise), noise is None)
    cause = diagnosis.explain_failure(problem.start, problem.names, given, _refit(noises))
    text = str(exc) if isinstance(exc, HexcalError) else f"the computation failed numerically ({exc})"
    if cause is not None:
        raise IdentificationError(f"the fit failed ({text}); likely cause: {cause.message}") from exc
    weak = _weak_combinations(problem, noises, sigma_limit)
    if weak and "combination" not in text:
        raise IdentificationError(f"{text}; {weak}") from exc


def _weak_combinations(problem: Problem, noises: tuple[NoiseModel, ...], sigma_limit: float) -> str:
    """The combinations the poses do not determine at the start (beyond the gauges, or with a
    predicted σ beyond the fail limit of the verdict), named; empty when none."""
    try:
        jac = projected_jacobian(problem, noises)
        gauge = gauge_freedoms(problem, problem.full0)
        lost = unidentifiable(problem, jac, gauge)
        if lost:
            return f"not determined by these data: {lost[-1]} ({len(lost)} combination(s))"
        cov = gauge_fixed_covariance(problem, jac, gauge)
        values = problem.full0[problem.mask]
        weak = [(s, c) for s, c in undetermined(cov, problem.names, sigma_limit, values) if s > FAIL_FACTOR]
    except (HexcalError, ValueError, np.linalg.LinAlgError):
        return ""
    return "; ".join(
        f"not determined by these data: {c} (predicted σ {s:.3g} × the limit of {sigma_limit:g} mm)"
        for s, c in weak[:3]
    )


def _diagnosis_noises(noises: tuple[NoiseModel, ...], learned: bool) -> tuple[NoiseModel, ...]:
    """The noise the diagnoses' refits weigh with: the given one, or the default noise model
    when it was learned (a learned noise has absorbed the error a diagnosis looks for)."""
    return tuple(NoiseModel() for _ in noises) if learned else noises


def _refit(noises: tuple[NoiseModel, ...]) -> Any:
    """The diagnoses' refit: least squares on the leg lengths where every instrument gives the
    pose, else maximum likelihood under ``noises``; unknown frames registered again."""

    def refit(
        start: Geometry, sessions: Sequence[Session], names: tuple[str, ...], max_nfev: int | None = None
    ) -> Quality:
        nfev = _DIAGNOSIS_NFEV if max_nfev is None else max_nfev
        try:
            registered, _ = register_sessions(start, sessions)
            base = Problem(start, registered)
            vary = np.isin(base.parameters.names, names) | (
                ~np.isin(base.parameters.names, start.machine_names()) & base.parameters.vary
            )
            problem = Problem(start, registered, parameters=base.parameters.with_vary(vary))
            if problem.determines_pose:
                res = fit_least_squares(problem, "length", max_nfev=nfev, truncate=True)
                return Quality(res.rms_after, float(np.sum(res.residuals**2)), res.dof, "mm")
            problem.check_size()
            value, sse, dof = ml_misfit(problem, noises, max_nfev=nfev)
            return Quality(value, sse, dof, "(whitened)")
        except (HexcalError, ValueError, np.linalg.LinAlgError):
            return Quality(float("inf"), float("inf"), 0)

    return refit
