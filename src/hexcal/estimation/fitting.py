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
from hexcal.estimation.bounds import bound_stderr
from hexcal.estimation.problem import Problem
from hexcal.estimation.registry import DEFAULT_ESTIMATOR, get_estimator
from hexcal.estimation.result import IdentificationResult
from hexcal.estimation.robust import DEFAULT_ALPHA, identify_robust, pose_diagnostics
from hexcal.models.base import MeasurementModel


def estimate(
    start: Geometry,
    measurements: Any,
    method: str = DEFAULT_ESTIMATOR,
    mask: ArrayLike | None = None,
    noise: NoiseModel | None = None,
    with_bound: bool = True,
    *,
    model: MeasurementModel | None = None,
    parameters: ParameterSet | None = None,
    robust: bool = False,
    diagnose: bool | None = None,
    alpha: float = DEFAULT_ALPHA,
    **options: Any,
) -> IdentificationResult:
    """Identify the parameters from measurements with any registered estimator.

    Parameters
    ----------
    start : Geometry
        Start values (the nominal geometry); parameters not varied keep its values.
    measurements
        The observations (:class:`hexcal.models.pose.Measurements` for the default model).
    method : str
        A name of :data:`hexcal.estimation.registry.ESTIMATORS` (default ``"ml"``).
    mask : array_like of bool, shape (48,), optional
        Varied machine parameters (default joints and ``l0``,
        :func:`hexcal.core.parameters.select_parameters`).
    noise : NoiseModel, optional
        The measurement noise (default the seed paper's): used by the noise-weighted
        estimators and for the bound and the pose check of every estimator.
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
    **options
        Passed to the estimator (e.g. ``xtol``, ``max_nfev``).

    Returns
    -------
    IdentificationResult
    """
    noise = NoiseModel() if noise is None else noise
    estimator = get_estimator(method)
    diagnose = with_bound if diagnose is None else diagnose
    if robust:
        robust_fit = identify_robust(start, measurements, method, mask, alpha, noise=noise)
        result, used = robust_fit.result, measurements.subset(robust_fit.kept)
        flagged_idx = robust_fit.diagnostics.flagged
    else:
        problem = Problem(start, measurements, model, mask, parameters)
        result, used = estimator.fit(problem, noise, **options), measurements
        flagged_idx = np.empty(0, dtype=np.intp)
        if diagnose and problem.model.measures_pose:
            # the whitened deletion statistic follows a known F distribution on the
            # generalised least-squares fit of the same data
            gls = result if method == "gls" else get_estimator("gls").fit(problem, noise)
            flagged_idx = pose_diagnostics(gls, measurements, problem.mask, alpha, noise).flagged
    flagged = tuple(used.ids[k] for k in flagged_idx)
    bound = None
    if with_bound:
        bound = bound_stderr(result.geometry, used, noise, np.isin(PARAMETER_NAMES, result.names))
    return result.replace(bound=bound, noise=noise, flagged=flagged)
