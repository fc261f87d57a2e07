"""Step 5 of the protocol and the bound: identification of simulated campaigns.

Identification starts from the nominal geometry with any estimator of
:data:`hexcal.estimation.ESTIMATORS`; a failed identification (or a campaign with an
unreachable pose) gives a NaN row, counted as a failure, never an error. The Cramér–Rao
bound of the mean absolute parameter error is computed at the poses really reached.

:func:`identify_trials` identifies all trials of a chunk together with
:func:`hexcal.estimation.estimate_batch` for the estimators it implements (every built-in
one: ``paper``, ``length``, ``gls``, ``ml``), and one trial at a time with
:func:`hexcal.calibration.estimate` for any other. Both use the same solvers (one
identification is a batch of one), so the two paths agree to rounding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hexcal.core import N_BASE_PARAMETERS, Geometry, NoiseModel, select_parameters
from hexcal.errors import IdentificationError
from hexcal.instruments import Measurements
from hexcal.simulation.protocol import CampaignData
from hexcal.simulation.runner import Executor, Progress, map_trials


def identify_trials(
    start: Geometry,
    campaign: CampaignData,
    poses: slice,
    method: str,
    noise: NoiseModel | None,
    batched: bool = True,
    mask: NDArray[np.bool_] | None = None,
) -> NDArray[np.float64]:
    """Step 5: identified values ``(T, n)`` of each trial's data (``poses`` of its campaign):
    the machine parameters of ``mask`` (default joints and ``l0``: the 42-vectors).

    NaN rows where the identification failed or the campaign has an unreachable pose.
    ``batched`` (default) solves the trials together when ``method`` is one of
    :data:`hexcal.estimation.BATCH_METHODS`; ``False`` identifies one trial at a time.
    """
    from hexcal.estimation import BATCH_METHODS, estimate_batch  # deferred, as in identify_or_nan

    mask = select_parameters() if mask is None else np.asarray(mask, dtype=bool)
    reachable = ~np.any(np.isnan(campaign.reached[:, poses]), axis=(1, 2))
    out = np.full((len(reachable), int(mask.sum())), np.nan)
    if not batched or method not in BATCH_METHODS:
        for t in np.flatnonzero(reachable):
            out[t] = identify_or_nan(start, campaign.dataset(t, poses), method, noise, mask)
        return out
    ok = np.flatnonzero(reachable)
    if ok.size:
        try:
            batch = estimate_batch(
                start,
                campaign.readings[ok][:, poses],
                campaign.measured[ok][:, poses],
                method,
                mask,
                noise,
            )
        except IdentificationError:  # too few poses: every trial fails, as one at a time
            return out
        out[ok] = batch.values
    return out


def identify_or_nan(
    start: Geometry, data: Measurements, method: str, noise: NoiseModel | None, mask: NDArray | None = None
) -> NDArray[np.float64]:
    """The identified values (default the 42-vector) of one data set, NaN if it failed."""
    from hexcal.calibration import estimate  # deferred: importing the protocol needs no scipy

    mask = select_parameters() if mask is None else mask
    try:
        result = estimate(start, data, method=method, mask=mask, noise=noise, with_bound=False)
    except IdentificationError:
        return np.full(int(np.sum(mask)), np.nan)
    return result.values


@dataclass(frozen=True)
class BatchDefinition:
    """Data sets to identify, for :func:`identify_batch` (picklable)."""

    start: Geometry
    datasets: tuple[Measurements, ...]
    method: str
    noise: NoiseModel | None


def identify_chunk(d: BatchDefinition, indices: NDArray[np.intp]) -> dict[str, NDArray[np.float64]]:
    """The runner's chunk function of :func:`identify_batch`."""
    vectors = [identify_or_nan(d.start, d.datasets[k], d.method, d.noise) for k in indices]
    return {"vectors": np.reshape(vectors, (len(indices), N_BASE_PARAMETERS))}


def identify_batch(
    start: Geometry,
    datasets: list[Measurements],
    method: str = "paper",
    jobs: int | None = 1,
    progress: Progress | None = None,
    noise: NoiseModel | None = None,
    *,
    executor: Executor | None = None,
) -> NDArray[np.float64]:
    """Identify many data sets, in ``jobs`` processes (``None``: all cores).

    ``method`` is any of :data:`hexcal.estimation.ESTIMATORS`; ``noise`` is the noise
    model the ``ml`` and ``gls`` estimators assume. Returns the identified 42-vectors,
    shape ``(len(datasets), 42)``, with NaN rows where an identification failed.

    Examples
    --------
    >>> from hexcal.core import preset
    >>> identify_batch(preset("paper-hmt"), []).shape
    (0, 42)
    """
    definition = BatchDefinition(start, tuple(datasets), method, noise)
    out = map_trials(
        identify_chunk, definition, len(datasets), jobs=jobs, executor=executor, progress=progress
    )
    return out.get("vectors", np.empty((0, N_BASE_PARAMETERS)))


def campaign_bounds(
    nominal: Geometry,
    true: Geometry | None,
    true_vectors: NDArray[np.float64],
    reached: NDArray[np.float64],
    noise: NoiseModel,
    mask: NDArray[np.bool_] | None = None,
    rows: NDArray[np.bool_] | None = None,
) -> NDArray[np.float64] | None:
    """Per-trial Cramér–Rao bound ``(T,)`` of the mean absolute error of the pose sets.

    ``reached`` ``(T, n, 6)`` are the poses really measured; ``None`` without noise; NaN
    for trials with an unreachable pose. ``mask`` are the identified machine parameters
    (default joints and ``l0``) and ``rows`` those of them the mean is over (default all).
    """
    from hexcal.core.stroke_legs import with_leg_model
    from hexcal.estimation import bound_mean_abs_error

    if not np.any(noise.pose_cov()) and noise.sigmas[0] == 0:
        return None
    ok = ~np.any(np.isnan(reached), axis=(1, 2))
    out = np.full(len(reached), np.nan)
    if true is not None and true.leg_model != nominal.leg_model:  # the fitted model's bound
        true = with_leg_model(true, nominal.leg_model)
    if true is not None:
        if ok.all():
            return bound_mean_abs_error(true, reached, noise, mask, rows)
        if ok.any():
            out[ok] = bound_mean_abs_error(true, reached[ok], noise, mask, rows)
        return out
    for t in np.flatnonzero(ok):  # a different machine in every trial
        machine = nominal.with_vector(true_vectors[t])
        out[t] = bound_mean_abs_error(machine, reached[t : t + 1], noise, mask, rows)[0]
    return out
