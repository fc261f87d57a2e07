"""The seed paper's experiment (section VI, Table I) as a definition over the protocol.

Trial ``t`` draws, from its own generator (:class:`~hexcal.simulation.protocol.TrialSeeds`)
and in this order: 25 of the 64 workspace corners (15 measured, 10 for validation), 15
random interior poses, the leg and pose noise of those 30 poses, the true machine (when
random) and the noise of the ``selected`` poses (when a row uses them). The chunks of
trials run through :func:`hexcal.simulation.runner.map_trials`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core import Geometry, NoiseModel, random_poses, workspace_corners
from hexcal.simulation.identify import campaign_bounds, identify_trials
from hexcal.simulation.protocol import TrialSeeds, simulate_campaigns, true_machines, validate
from hexcal.simulation.runner import Executor, Progress, map_trials

#: The seed paper's Table I (mean absolute parameter error, mm) and its validation claims.
PAPER_TABLE1 = {"before": 2.6652, "interior": 0.7236, "boundary": 0.3752}
PAPER_VALIDATION = {
    "before": {"position": "about 15 mm", "orientation": "about 0.05 rad"},
    "after": {"position": "below 0.03 mm", "orientation": "below 3e-6 rad"},
}
#: Labels of the rows of ``hexcal paper``.
ROW_LABELS = {
    "before": "before calibration",
    "interior": "15 random poses inside the workspace",
    "boundary": "15 of the 64 corners",
    "boundary_ml": "15 of the 64 corners, maximum likelihood",
    "selected_ml": "15 optimally selected poses, max. likelihood",
}


@dataclass(frozen=True)
class PaperExperiment:
    """Monte Carlo results of the seed paper's experiment (arrays over trials).

    Attributes
    ----------
    true_vectors : ndarray, shape (T, 42)
        True parameters of each trial.
    nominal_vector : ndarray, shape (42,)
    interior_vectors, boundary_vectors : ndarray, shape (T, 42)
        Identified parameters from 15 random interior poses and from 15 of the 64
        corners; NaN rows where identification (or the simulated campaign) failed.
    validation_targets : ndarray, shape (T, n_validation, 6)
    validation_before, validation_after : dict of ndarray, shape (T, n_validation)
        ``position`` (mm) and ``orientation`` (rad) errors of the validation poses
        with the nominal and with the boundary-identified parameters.
    method : str
    extra : dict of ndarray, shape (T, 42)
        Identified parameters of the extra rows.
    bounds : dict of ndarray, shape (T,)
        Cramér–Rao bound of the mean absolute error per pose strategy.
    row_strategies : dict of str
        The pose strategy of each row.
    """

    nominal_vector: NDArray[np.float64]
    true_vectors: NDArray[np.float64]
    interior_vectors: NDArray[np.float64]
    boundary_vectors: NDArray[np.float64]
    validation_targets: NDArray[np.float64]
    validation_before: dict[str, NDArray[np.float64]]
    validation_after: dict[str, NDArray[np.float64]]
    method: str
    extra: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    bounds: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    row_strategies: dict[str, str] = field(default_factory=dict)

    def bound_of(self, row: str) -> NDArray[np.float64] | None:
        """Per-trial Cramér–Rao bound of the mean absolute error of a row's pose sets."""
        return self.bounds.get(self.row_strategies.get(row, row))

    @property
    def trials(self) -> int:
        return int(self.true_vectors.shape[0])

    def _rows(self) -> dict[str, NDArray[np.float64]]:
        return {"interior": self.interior_vectors, "boundary": self.boundary_vectors, **self.extra}

    def mean_abs_errors(self) -> dict[str, NDArray[np.float64]]:
        """Per-trial mean absolute parameter error (mm) before and after calibration, per row."""
        out = {"before": np.mean(np.abs(self.nominal_vector - self.true_vectors), axis=1)}
        for name, vectors in self._rows().items():
            out[name] = np.mean(np.abs(vectors - self.true_vectors), axis=1)
        return out

    @property
    def failures(self) -> dict[str, int]:
        """Number of trials whose identification failed, per row."""
        return {name: int(np.sum(np.isnan(v[:, 0]))) for name, v in self._rows().items()}

    def to_dict(self, **meta: Any) -> dict[str, Any]:
        """The Table I reproduction as a JSON-ready mapping (``table1.json`` of ``hexcal paper``).

        ``meta`` (seed, machines, noise, ...) comes first. Every row (``interior``,
        ``boundary`` and any extra rows) has its mean absolute parameter error (mm) as a
        top-level number, its standard deviation over trials in ``std``, and, under
        ``bound``, the Cramér–Rao bound of that error and the efficiency (error / bound).

        Examples
        --------
        >>> from hexcal.core import preset
        >>> exp = run_paper_experiment(preset("paper-hmt"), preset("paper-hmt-true"), trials=2, rng=0)
        >>> summary = exp.to_dict(seed=0)
        >>> summary["seed"], summary["trials"], summary["failures"]
        (0, 2, {'interior': 0, 'boundary': 0})
        """
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # every trial failed: NaN, counted
            return self._summary(meta)

    def _summary(self, meta: dict[str, Any]) -> dict[str, Any]:
        errors = self.mean_abs_errors()
        summary: dict[str, Any] = dict(meta)
        bounds = {}
        for row in errors:
            b = self.bound_of(row)
            if b is not None:
                bound = float(np.mean(b))
                bounds[row] = {"bound": bound, "efficiency": float(np.nanmean(errors[row])) / bound}
        summary.update(
            {
                "trials": self.trials,
                "method": self.method,
                **{row: float(np.nanmean(values)) for row, values in errors.items()},
                "rows": {row: ROW_LABELS.get(row, row) for row in errors},
                "std": {k: float(np.nanstd(v)) for k, v in errors.items()},
                "bound": bounds,
                "failures": self.failures,
                "paper": dict(PAPER_TABLE1),
                "validation": {
                    "before": _pose_error_stats(self.validation_before),
                    "after": _pose_error_stats(self.validation_after),
                    "paper": PAPER_VALIDATION,
                    "statistics": "max: per-trial maximum over the validation poses, averaged over "
                    "trials; rms: over all validation poses of all trials; max_worst: over all",
                },
            }
        )
        return summary


def _pose_error_stats(errors: dict[str, NDArray[np.float64]]) -> dict[str, float]:
    """Per-trial max averaged over trials, and RMS over all poses of all trials."""
    out: dict[str, float] = {}
    for key in ("position", "orientation"):
        e = errors[key]
        out[f"{key}_max"] = float(np.nanmean(np.nanmax(e, axis=1)))
        out[f"{key}_rms"] = float(np.sqrt(np.nanmean(e**2)))
        out[f"{key}_max_worst"] = float(np.nanmax(e))
    return out


@dataclass(frozen=True)
class PaperDefinition:
    """Everything a chunk of trials of the paper's experiment needs (picklable)."""

    nominal: Geometry
    true: Geometry | None
    seeds: TrialSeeds
    noise: NoiseModel
    n_poses: int
    n_validation: int
    parameter_error: float
    rows: tuple[tuple[str, str, str, bool], ...]  # (name, strategy, method, assumes noise)
    selected_poses: NDArray[np.float64] | None


def paper_trials(d: PaperDefinition, indices: NDArray[np.intp]) -> dict[str, NDArray[np.float64]]:
    """Simulate, identify and validate the trials ``indices`` (the runner's chunk function)."""
    nominal, noise, n, v = d.nominal, d.noise, d.n_poses, d.n_validation
    rngs = [d.seeds.generator(t) for t in indices]
    corners = workspace_corners(nominal)
    pick = np.stack([r.permutation(64)[: n + v] for r in rngs])
    interior = np.stack([random_poses(nominal, n, r) for r in rngs])
    leg_noise = np.stack([noise.leg_errors(r, (2 * n,)) for r in rngs])
    pose_noise = np.stack([noise.pose_errors(r, (2 * n,)) for r in rngs])
    true_vectors, machines = true_machines(nominal, d.true, rngs, d.parameter_error)
    commanded = np.concatenate([interior, corners[pick[:, :n]]], axis=1)  # (c, 2 n, 6)
    main = simulate_campaigns(nominal, machines, commanded, leg_noise, pose_noise, strict=False)
    sources = {"interior": (main, slice(0, n)), "boundary": (main, slice(n, 2 * n))}
    if d.selected_poses is not None:
        m = d.selected_poses.shape[0]
        sel_leg = np.stack([noise.leg_errors(r, (m,)) for r in rngs])
        sel_pose = np.stack([noise.pose_errors(r, (m,)) for r in rngs])
        sel_cmd = np.broadcast_to(d.selected_poses, (len(rngs), m, 6))
        selected = simulate_campaigns(nominal, machines, sel_cmd, sel_leg, sel_pose, strict=False)
        sources["selected"] = (selected, slice(None))

    out: dict[str, NDArray[np.float64]] = {"true_vectors": true_vectors}
    for name, strategy, method, assumes_noise in d.rows:
        campaign, poses = sources[strategy]
        out[f"row:{name}"] = identify_trials(
            nominal, campaign, poses, method, noise if assumes_noise else None
        )
    for strategy, (campaign, poses) in sources.items():
        bound = campaign_bounds(nominal, d.true, true_vectors, campaign.reached[:, poses], noise)
        if bound is not None:
            out[f"bound:{strategy}"] = bound
    targets = corners[pick[:, n:]]
    out["targets"] = targets
    out["before:position"], out["before:orientation"] = validate(nominal, machines, targets)
    out["after:position"], out["after:orientation"] = validate(
        nominal, machines, targets, out["row:boundary"]
    )
    return out


def run_paper_experiment(
    nominal: Geometry,
    true: Geometry | None = None,
    trials: int = 100,
    rng: int | np.random.SeedSequence | None = None,
    noise: NoiseModel | None = None,
    n_poses: int = 15,
    n_validation: int = 10,
    parameter_error: float = 5.0,
    method: str = "paper",
    jobs: int | None = 1,
    progress: Progress | None = None,
    extra_rows: tuple[tuple[str, str, str], ...] = (),
    selected_poses: NDArray[np.float64] | None = None,
    *,
    executor: Executor | None = None,
    chunk_size: int | None = None,
) -> PaperExperiment:
    """Monte Carlo simulation of the seed paper's Table I and validation.

    Parameters
    ----------
    nominal : Geometry
        The controller's geometry; must have a workspace box.
    true : Geometry, optional
        The real machine; default a new ``nominal + U(-parameter_error, parameter_error)``
        in every trial.
    trials : int
    rng : int or SeedSequence, optional
        Seed; trial ``t`` uses its ``t``-th child (:class:`~hexcal.simulation.protocol.TrialSeeds`).
    noise : NoiseModel, optional
        Default the paper's (±0.01 mm legs, ±0.025 mm position, ±0.001 rad angles).
    n_poses : int
        Measurement poses per campaign (15 in the paper).
    n_validation : int
        Validation corners, drawn from the corners not measured (10 in the paper).
    parameter_error : float
        Half-width of the uniform true parameter errors when ``true`` is None, mm.
    method : {"paper", "length"}
        Identification residual.
    jobs : int or None
        Processes (None: all cores).
    progress : callable(done, total), optional
        Identifications done, as chunks of trials complete.
    extra_rows : tuple of (name, strategy, method)
        Further rows on the same trials: ``strategy`` is ``"interior"`` or ``"boundary"``
        (the very same data as those rows) or ``"selected"`` (the fixed
        ``selected_poses`` measured with fresh noise in every trial); ``method`` any
        estimator of :data:`hexcal.estimation.ESTIMATORS` (``ml`` and ``gls`` assume
        ``noise``).
    selected_poses : ndarray, shape (n, 6), optional
        Poses of the ``"selected"`` strategy (e.g. optimally selected ones).
    executor : Executor, optional
        Where the chunks of trials run (default by ``jobs``; see
        :func:`~hexcal.simulation.runner.map_trials`).
    chunk_size : int, optional
        Trials per chunk (default by the number of trials only, so that ``jobs`` and the
        executor do not change the numbers); it changes only the last digits of maximum
        likelihood (about 1e-11 mm), whose trials of a chunk are solved together.

    Returns
    -------
    PaperExperiment
        A trial whose simulated machine cannot reach a commanded pose counts as failed
        (NaN rows, counted in ``failures``).

    Examples
    --------
    >>> from hexcal.core import preset
    >>> exp = run_paper_experiment(preset("paper-hmt"), preset("paper-hmt-true"), trials=2, rng=0)
    >>> exp.boundary_vectors.shape, exp.validation_after["position"].shape
    ((2, 42), (2, 10))
    """
    if trials < 1:
        raise ValueError(f"trials must be at least 1, got {trials}")
    if n_poses + n_validation > len(workspace_corners(nominal)):
        raise ValueError(f"{n_poses} measurement and {n_validation} validation corners exceed the 64 corners")
    strategies = {row[1] for row in extra_rows}
    if not strategies <= {"interior", "boundary", "selected"}:
        raise ValueError(f"unknown pose strategy in {sorted(strategies)}")
    selected = None
    if "selected" in strategies:
        if selected_poses is None:
            raise ValueError("the 'selected' strategy needs selected_poses")
        selected = np.asarray(selected_poses, dtype=float).reshape(-1, 6)
    rows = (
        ("interior", "interior", method, False),
        ("boundary", "boundary", method, False),
        *((name, strategy, row_method, True) for name, strategy, row_method in extra_rows),
    )
    definition = PaperDefinition(
        nominal,
        true,
        TrialSeeds.from_seed(rng),
        NoiseModel() if noise is None else noise,
        n_poses,
        n_validation,
        parameter_error,
        rows,
        selected,
    )
    schedule = {"jobs": jobs, "executor": executor, "chunk_size": chunk_size, "progress": progress}
    out = map_trials(paper_trials, definition, trials, weight=len(rows), **schedule)
    return PaperExperiment(
        nominal_vector=nominal.to_vector(),
        true_vectors=out["true_vectors"],
        interior_vectors=out["row:interior"],
        boundary_vectors=out["row:boundary"],
        validation_targets=out["targets"],
        validation_before={"position": out["before:position"], "orientation": out["before:orientation"]},
        validation_after={"position": out["after:position"], "orientation": out["after:orientation"]},
        method=method,
        extra={name: out[f"row:{name}"] for name, _, _ in extra_rows},
        bounds={k.removeprefix("bound:"): v for k, v in out.items() if k.startswith("bound:")},
        row_strategies={name: strategy for name, strategy, _, _ in rows},
    )
