"""``estimate``: the one entry point of identification.

Builds the :class:`~hexcal.estimation.problem.Problem`, runs a registered estimator
(:mod:`hexcal.estimation.registry`), optionally inside robust fitting
(:mod:`hexcal.estimation.robust`), and attaches the Cramér–Rao bound and the pose check.

>>> from hexcal.core.presets import preset
>>> from hexcal.core.workspace import workspace_corners
>>> from hexcal.estimation.bounds import planned_measurements
>>> nominal, real = preset("paper-hmt"), preset("paper-hmt-true")
>>> data = planned_measurements(real, workspace_corners(nominal)[1::3])  # exact, noise-free
>>> result = estimate(nominal, data, "length")
>>> result.rank, result.n_poses
(42, 21)
>>> round(result.parameters["u1.x"], 4)    # the real machine's u1.x
305.2599
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from hexcal.core.geometry import Geometry
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import PARAMETER_NAMES, ParameterSet
from hexcal.errors import HexcalError, UsageError
from hexcal.estimation.bounds import bound_stderr
from hexcal.estimation.noise_estimation import NoiseCheck, NoiseEstimate, check_noise, estimate_noise
from hexcal.estimation.problem import Problem
from hexcal.estimation.registry import DEFAULT_ESTIMATOR, get_estimator
from hexcal.estimation.result import IdentificationResult
from hexcal.estimation.robust import (
    DEFAULT_ALPHA,
    SCREEN_THRESHOLD,
    identify_robust,
    pose_diagnostics,
    screen_poses,
)
from hexcal.estimation.verdict import MAX_CHANGE, assess
from hexcal.instruments.base import MeasurementModel

#: ``noise=`` value (and ``default_noise``) that learns the noise from the data.
AUTO = "auto"


def estimate(
    start: Geometry,
    measurements: Any,
    method: str = DEFAULT_ESTIMATOR,
    mask: ArrayLike | None = None,
    noise: NoiseModel | str | None = None,
    with_bound: bool = True,
    *,
    model: MeasurementModel | None = None,
    parameters: ParameterSet | None = None,
    robust: bool = False,
    diagnose: bool | None = None,
    alpha: float = DEFAULT_ALPHA,
    default_noise: str = "paper",
    verdict: bool | None = None,
    sigma_limit: float = 1.0,
    max_change: float = MAX_CHANGE,
    **options: Any,
) -> IdentificationResult:
    """Identify the parameters from measurements with any registered estimator.

    Parameters
    ----------
    start : Geometry
        Start values (the nominal geometry); parameters not varied keep its values.
    measurements
        The observations (:class:`hexcal.instruments.pose.Measurements` for the default model).
    method : str
        A name of :data:`hexcal.estimation.registry.ESTIMATORS` (default ``"ml"``).
    mask : array_like of bool, shape (48,), optional
        Varied machine parameters (default joints and ``l0``,
        :func:`hexcal.core.parameters.select_parameters`).
    noise : NoiseModel or "auto", optional
        The measurement noise: used by the noise-weighted estimators and for the bound and
        the pose check of every estimator. ``"auto"`` learns it from the data (variance
        components, :func:`hexcal.estimation.noise_estimation.estimate_noise`;
        ``result.noise_source == "estimated"``). A given model is checked against the data
        (``result.noise_check``). ``None`` means ``default_noise``.
    with_bound : bool
        Attach the Cramér–Rao bound (``result.bound``) and the noise model.
    model : MeasurementModel, optional
        Default the full-pose measurement.
    parameters : ParameterSet, optional
        The whole parameter set, replacing ``mask``.
    robust : bool
        Leave out outlying poses (:func:`hexcal.estimation.robust.identify_robust`, with this
        estimator); their ids are in ``result.outliers``.
    diagnose : bool, optional
        Check every pose for implausible residuals (``result.flagged``); default
        ``with_bound``.
    alpha : float
        Family-wise false alarm rate of the pose check.
    default_noise : {"paper", "auto"}
        What ``noise=None`` means: the seed paper's noise model (the library's historical
        default) or ``"auto"`` (the CLI's default when no ``--noise`` is given).
    verdict : bool, optional
        Judge the fit (``result.verdict``, :func:`hexcal.estimation.verdict.assess`);
        default ``with_bound``.
    sigma_limit : float
        Scale of the limits above which a parameter combination is undetermined (1 mm for
        lengths, 1e-3 for gains by default).
    max_change : float
        Largest plausible parameter change as a fraction of the machine's size.
    **options
        Passed to the estimator (e.g. ``xtol``, ``max_nfev``).

    Returns
    -------
    IdentificationResult
    """
    if noise is None:
        noise = AUTO if default_noise == AUTO else NoiseModel()
    if isinstance(noise, str) and noise != AUTO:
        raise UsageError(f"noise must be a NoiseModel or {AUTO!r}, got {noise!r}")
    auto = noise == AUTO
    estimator = get_estimator(method)
    diagnose = with_bound if diagnose is None else diagnose
    verdict = with_bound if verdict is None else verdict
    noise_estimate = noise_check = None
    if robust:
        if auto:
            noise_estimate = _robust_noise(start, measurements, mask, model, parameters, options)
            noise = noise_estimate.noise
        with np.errstate(over="ignore"):  # a gross outlier's deletion statistic may be inf
            robust_fit = identify_robust(start, measurements, method, mask, alpha, noise=noise)
        result, used = robust_fit.result, measurements.subset(robust_fit.kept)
        flagged_idx = robust_fit.diagnostics.flagged
    else:
        problem = Problem(start, measurements, model, mask, parameters)
        if auto:
            noise_estimate, ml_fit = estimate_noise(problem, **options)
            noise = noise_estimate.noise
            result = ml_fit if method == "ml" else estimator.fit(problem, noise, **options)
        else:
            result = estimator.fit(problem, noise, **options)
            if verdict:
                noise_check = _check(problem, noise, result, alpha)
        used = measurements
        flagged_idx = np.empty(0, dtype=np.intp)
        if diagnose and problem.model.measures_pose:
            # the whitened deletion statistic follows a known F distribution on the
            # generalised least-squares fit of the same data
            gls = result if method == "gls" else get_estimator("gls").fit(problem, noise)
            with np.errstate(over="ignore"):  # a gross outlier's statistic may be inf
                flagged_idx = pose_diagnostics(gls, measurements, problem.mask, alpha, noise).flagged
    flagged = tuple(used.ids[k] for k in flagged_idx)
    bound = None
    if with_bound:
        bound = bound_stderr(result.geometry, used, noise, np.isin(PARAMETER_NAMES, result.names))
    result = result.replace(
        bound=bound,
        noise=noise,
        flagged=flagged,
        noise_source="estimated" if auto else "given",
        noise_estimate=noise_estimate,
        noise_check=noise_check,
    )
    if verdict:
        judged = assess(
            result,
            used,
            noise_estimate=noise_estimate,
            noise_check=noise_check,
            sigma_limit=sigma_limit,
            max_change=max_change,
            alpha=alpha,
            robust=robust,
        )
        result = result.replace(verdict=judged)
    return result


def _check(
    problem: Problem, noise: NoiseModel, result: IdentificationResult, alpha: float
) -> NoiseCheck | None:
    """The given noise against the data (None when it has no noise to test)."""
    if noise.sigmas[0] <= 0 or not noise.has_pose_noise:
        return None
    try:
        return check_noise(problem, noise, result, alpha)
    except (HexcalError, np.linalg.LinAlgError):
        return None


def _robust_noise(
    start: Geometry, measurements: Any, mask: ArrayLike | None, model: Any, parameters: Any, options: dict
) -> NoiseEstimate:
    """Variance components from the poses that the robust screening keeps."""
    problem = Problem(start, measurements, model, mask, parameters)
    scores = screen_poses(start, measurements, problem.mask)
    limit = int(0.25 * len(scores))
    drop = np.argsort(-scores)[:limit]
    keep = np.ones(len(scores), dtype=bool)
    keep[drop[scores[drop] > SCREEN_THRESHOLD]] = False
    return estimate_noise(problem.subset(keep), **options)[0]
