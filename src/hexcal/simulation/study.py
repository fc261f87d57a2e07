"""Monte Carlo studies of calibration campaigns: methods × pose strategies × sizes × noise.

For every combination of a pose strategy, a number of poses and a noise level, ``T``
trials are simulated with the protocol of :mod:`hexcal.simulation.protocol`; every
estimator identifies the same data. Trial ``t`` draws its true machine and validation
poses from its own generator, and each cell's poses and noise from the sub-stream
``(t, strategy index, poses, noise index)``, so cells compare like with like and do not
depend on each other. Reported per cell: the mean absolute parameter error, its
Cramér–Rao bound (:func:`hexcal.estimation.bound_mean_abs_error`), the efficiency
error / bound, and the validation pose error on random workspace poses when the
controller uses the identified parameters.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core import Geometry, NoiseModel, random_poses, workspace_corners
from hexcal.simulation.identify import campaign_bounds, identify_trials
from hexcal.simulation.instrument_trials import InstrumentCampaign, instrument_cell
from hexcal.simulation.protocol import MachineBatch, TrialSeeds, simulate_campaigns, true_machines, validate
from hexcal.simulation.runner import Executor, Progress, map_trials

#: Pose strategies: a function ``(nominal, n, rng) -> (n, 6)`` poses for one trial
#: (module-level or picklable, to run in other processes).
PoseStrategy = Callable[[Geometry, int, np.random.Generator], NDArray[np.float64]]


def _corners(nominal: Geometry, n: int, rng: np.random.Generator) -> NDArray[np.float64]:
    corners = workspace_corners(nominal)
    if n > len(corners):
        raise ValueError(f"{n} poses requested from the {len(corners)} corners")
    return corners[rng.permutation(len(corners))[:n]]


def _interior(nominal: Geometry, n: int, rng: np.random.Generator) -> NDArray[np.float64]:
    return random_poses(nominal, n, rng)


STRATEGIES: dict[str, PoseStrategy] = {"corners": _corners, "interior": _interior}


@dataclass(frozen=True, eq=False)
class FixedStrategy:
    """A pose strategy returning a fixed pose set per size (picklable; see :func:`fixed_strategy`)."""

    poses_by_size: dict[int, NDArray[np.float64]]

    def __call__(self, nominal: Geometry, n: int, rng: np.random.Generator) -> NDArray[np.float64]:
        del nominal, rng
        if n not in self.poses_by_size:
            raise ValueError(f"no fixed pose set of {n} poses")
        return self.poses_by_size[n]


def fixed_strategy(poses_by_size: dict[int, NDArray[np.float64]]) -> PoseStrategy:
    """A strategy returning a fixed pose set per size (e.g. optimally selected poses).

    Examples
    --------
    >>> strategy = fixed_strategy({2: np.zeros((2, 6))})
    >>> strategy(None, 2, None).shape
    (2, 6)
    """
    return FixedStrategy(dict(poses_by_size))


@dataclass(frozen=True)
class StudyCell:
    """Results of one (strategy, poses, noise, method) cell over ``T`` trials."""

    strategy: str
    n_poses: int
    noise: str
    method: str
    errors: NDArray[np.float64]  # (T,) mean absolute parameter error, mm
    bounds: NDArray[np.float64]  # (T,) bound of that error, mm (NaN without noise)
    position_rms: NDArray[np.float64]  # (T,) validation position error RMS, mm
    orientation_rms: NDArray[np.float64]  # (T,) validation orientation error RMS, rad

    def row(self) -> dict[str, float | str | int]:
        """The cell's statistics over the trials (a row of ``study.json``).

        ``error_mean`` and ``error_std`` of the mean absolute parameter error (mm), its
        ``bound`` and ``efficiency`` (error / bound), the RMS validation errors and the
        number of failed trials; NaN trials (failures) are left out of the statistics.
        """
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all trials failed: NaN, counted below
            return self._row()

    def to_dict(self) -> dict[str, float | str | int]:
        """Same as :meth:`row`."""
        return self.row()

    def _row(self) -> dict[str, float | str | int]:
        err = float(np.nanmean(self.errors))
        bound = float(np.nanmean(self.bounds))
        return {
            "strategy": self.strategy,
            "poses": self.n_poses,
            "noise": self.noise,
            "method": self.method,
            "error_mean": err,
            "error_std": float(np.nanstd(self.errors)),
            "bound": bound,
            "efficiency": err / bound if bound > 0 else float("nan"),
            "position_rms": float(np.sqrt(np.nanmean(self.position_rms**2))),
            "orientation_rms": float(np.sqrt(np.nanmean(self.orientation_rms**2))),
            "failures": int(np.sum(np.isnan(self.errors))),
        }


class StudyResult(list[StudyCell]):
    """The cells of a study (a list of :class:`StudyCell`) and their JSON form.

    Examples
    --------
    >>> cell = StudyCell("corners", 15, "paper", "ml", *np.ones((4, 2)))
    >>> StudyResult([cell]).to_dict(trials=2)["cells"][0]["error_mean"]
    1.0
    """

    def to_dict(self, **meta: Any) -> dict[str, Any]:
        """``meta`` (trials, seed, noise, ...) and ``cells``, the rows of the cells (``study.json``)."""
        return {**meta, "cells": [cell.to_dict() for cell in self]}


@dataclass(frozen=True)
class StudyDefinition:
    """Everything a chunk of trials of a study needs (picklable)."""

    nominal: Geometry
    true: Geometry | None
    seeds: TrialSeeds
    methods: tuple[str, ...]
    strategies: tuple[tuple[str, PoseStrategy], ...]
    pose_counts: tuple[int, ...]
    noises: tuple[tuple[str, NoiseModel], ...]
    n_validation: int
    parameter_error: float
    campaign: InstrumentCampaign | None = None
    fit: str = "joints,l0"

    def cells(self) -> list[tuple[int, str, int, int, str, NoiseModel, str]]:
        """``(strategy index, name, poses, noise index, label, noise, method)`` of every cell, in order."""
        return [
            (s_index, s_name, n, z_index, z_name, noise, method)
            for s_index, (s_name, _) in enumerate(self.strategies)
            for n in self.pose_counts
            for z_index, (z_name, noise) in enumerate(self.noises)
            for method in self.methods
        ]


def study_trials(d: StudyDefinition, indices: NDArray[np.intp]) -> dict[str, NDArray[np.float64]]:
    """Simulate, identify and validate every cell of the trials ``indices`` (the chunk function)."""
    nominal = d.nominal
    base = [d.seeds.generator(t) for t in indices]
    true_vectors, machines = true_machines(nominal, d.true, base, d.parameter_error)
    targets = np.stack([random_poses(nominal, d.n_validation, r) for r in base])
    out: dict[str, NDArray[np.float64]] = {}
    k = 0
    for s_index, (_, strategy) in enumerate(d.strategies):
        for n in d.pose_counts:
            for z_index, (_, noise) in enumerate(d.noises):
                # one generator per trial and cell, independent of the order of the cells
                rngs = [d.seeds.generator(t, s_index, n, z_index) for t in indices]
                commanded = np.stack([strategy(nominal, n, r) for r in rngs])
                if d.campaign is not None:  # an instrument other than the full pose
                    trues = [d.true or nominal.with_vector(v) for v in true_vectors]
                    for method in d.methods:
                        cell = instrument_cell(
                            nominal, trues, d.campaign, commanded, noise, rngs, method, targets
                        )
                        out.update({f"{k}:{key}": value for key, value in cell.items()})
                        k += 1
                    continue
                leg_noise = np.stack([noise.leg_errors(r, (n,)) for r in rngs])
                pose_noise = np.stack([noise.pose_errors(r, (n,)) for r in rngs])
                campaign = simulate_campaigns(
                    nominal, machines, commanded, leg_noise, pose_noise, strict=False
                )
                params = nominal.machine_parameters(d.fit)
                lengths = np.isin(params.names, params.groups["joints"] + params.groups["l0"])
                bounds = campaign_bounds(
                    nominal, d.true, true_vectors, campaign.reached, noise, params.vary, lengths[params.vary]
                )
                for method in d.methods:
                    values = identify_trials(nominal, campaign, slice(None), method, noise, mask=params.vary)
                    full = np.tile(params.values, (len(indices), 1))
                    full[:, params.vary] = values
                    full[np.isnan(values).any(axis=1)] = np.nan
                    identified = MachineBatch.from_geometry(nominal, full)
                    vectors = full[:, lengths]
                    pos, ang = validate(nominal, machines, targets, identified=identified)
                    out[f"{k}:errors"] = np.mean(np.abs(vectors - true_vectors), axis=1)
                    out[f"{k}:bounds"] = np.full(len(indices), np.nan) if bounds is None else bounds
                    out[f"{k}:position_rms"] = np.sqrt(np.mean(pos**2, axis=1))
                    out[f"{k}:orientation_rms"] = np.sqrt(np.mean(ang**2, axis=1))
                    k += 1
    return out


#: Bytes per pose of one trial while a chunk of trials is identified together (the stacked
#: Jacobians, poses, residuals and the solvers' copies): measured about 12,000 (``simulate
#: --strategies interior --methods paper,ml --trials 2``: 35 MB more for 3,000 more poses).
POSE_TRIAL_BYTES = 16_000

#: Estimators a study compares when none are named: the seed paper's and maximum likelihood,
#: those of them the instrument allows (:func:`default_methods`).
DEFAULT_METHODS = ("paper", "ml")


def default_methods(campaign: InstrumentCampaign | None = None) -> tuple[str, ...]:
    """The estimators of :data:`DEFAULT_METHODS` that the campaign's instrument allows: a pose
    estimator needs the platform pose measured (the full pose, a tool with its orientation),
    which targets or a ballbar do not give.

    >>> default_methods()
    ('paper', 'ml')
    """
    from hexcal.estimation import get_estimator

    if campaign is None or campaign.start.determines_pose:
        return DEFAULT_METHODS
    return tuple(m for m in DEFAULT_METHODS if not get_estimator(m).needs_pose)


def run_study(
    nominal: Geometry,
    true: Geometry | None = None,
    methods: Sequence[str] | None = None,
    strategies: dict[str, PoseStrategy] | None = None,
    pose_counts: Sequence[int] = (15,),
    noises: dict[str, NoiseModel] | None = None,
    trials: int = 100,
    rng: int | None = 0,
    n_validation: int = 10,
    parameter_error: float = 5.0,
    jobs: int | None = 1,
    progress: Progress | None = None,
    *,
    executor: Executor | None = None,
    chunk_size: int | None = None,
    campaign: InstrumentCampaign | None = None,
    fit: str = "joints,l0",
) -> StudyResult:
    """Run a study (see the module docstring).

    Parameters
    ----------
    nominal : Geometry
        The controller's geometry, with a workspace box.
    true : Geometry, optional
        The real machine; default nominal plus uniform ±``parameter_error`` mm per trial.
    methods : sequence of str, optional
        Estimators (:data:`hexcal.estimation.ESTIMATORS`); default :func:`default_methods`
        of the instrument.
    strategies : dict of name to strategy, optional
        Default ``corners`` and ``interior`` (:data:`STRATEGIES`). For ``jobs > 1`` they
        must be picklable (module-level functions or :func:`fixed_strategy`).
    pose_counts : sequence of int
    noises : dict of label to NoiseModel, optional
        Default the seed paper's noise, labelled ``paper``. ``ml`` and ``gls`` assume the
        noise that generated the data.
    trials : int
    rng : int, optional
        Seed: trial ``t`` of every cell uses the ``t``-th child generator of the seed for
        the true machine and validation poses, so cells compare like with like.
    n_validation : int
        Random workspace poses per trial for the validation pose error.
    jobs : int or None
        Processes (None: all cores).
    progress : callable(done, total), optional
        Identifications done, as chunks of trials complete.
    executor : Executor, optional
        Where the chunks of trials run (see :func:`~hexcal.simulation.runner.map_trials`).
    chunk_size : int, optional
        Trials per chunk (default by the number of trials only, so that ``jobs`` and the
        executor do not change the numbers); it changes only the last digits of maximum
        likelihood (about 1e-11 mm), whose trials of a chunk are solved together.
    fit : str
        Machine parameter groups identified (``joints,l0,gains`` fits the gains too); the
        reported error is that of the joints and ``l0``.
    campaign : InstrumentCampaign, optional
        The instrument that measures (default the full pose in the base frame): its true
        setup, the start an identification begins from, the machine groups fitted
        (:mod:`hexcal.simulation.instrument_trials`).

    Returns
    -------
    StudyResult
        A list of :class:`StudyCell`, one per (strategy, poses, noise, method), in that
        nesting order. A trial whose simulated machine cannot reach a commanded pose
        counts as failed (NaN).

    Examples
    --------
    >>> from hexcal.core import preset
    >>> cells = run_study(preset("paper-hmt"), preset("paper-hmt-true"), methods=("length",), trials=2)
    >>> [(c.strategy, c.n_poses, c.method, c.row()["failures"]) for c in cells]
    [('corners', 15, 'length', 0), ('interior', 15, 'length', 0)]
    """
    strategies = dict(STRATEGIES) if strategies is None else strategies
    noises = {"paper": NoiseModel()} if noises is None else noises
    methods = default_methods(campaign) if methods is None else methods
    from hexcal.core.resources import check_memory
    from hexcal.simulation.runner import default_chunk_size

    largest = max((int(n) for n in pose_counts), default=0)
    per_chunk = default_chunk_size(trials) if chunk_size is None else max(1, int(chunk_size))
    what = f"{largest:,} poses in each of {per_chunk} trial(s) at once"
    check_memory("--poses", POSE_TRIAL_BYTES * largest * per_chunk, what)
    if campaign is not None:
        from hexcal.errors import UsageError
        from hexcal.estimation import get_estimator

        for method in methods:
            if get_estimator(method).needs_pose and not campaign.start.determines_pose:
                raise UsageError(
                    f"method {method}: it needs the platform pose measured, and the "
                    f"{campaign.true.describe()} does not give it; use ml"
                )
    definition = StudyDefinition(
        nominal,
        true,
        TrialSeeds.from_seed(rng),
        tuple(methods),
        tuple(strategies.items()),
        tuple(int(n) for n in pose_counts),
        tuple(noises.items()),
        n_validation,
        parameter_error,
        campaign,
        fit,
    )
    cells = definition.cells()
    schedule = {"jobs": jobs, "executor": executor, "chunk_size": chunk_size, "progress": progress}
    out = map_trials(study_trials, definition, trials, weight=len(cells), **schedule)
    return StudyResult(
        StudyCell(
            s_name,
            n,
            z_name,
            method,
            out[f"{k}:errors"],
            out[f"{k}:bounds"],
            out[f"{k}:position_rms"],
            out[f"{k}:orientation_rms"],
        )
        for k, (_, s_name, n, _, z_name, _, method) in enumerate(cells)
    )
