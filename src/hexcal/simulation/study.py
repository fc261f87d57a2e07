"""Monte Carlo studies of calibration campaigns: methods × pose strategies × sizes × noise.

For every combination of a pose strategy, a number of poses and a noise level, ``T``
trials are simulated with the protocol of :mod:`hexcal.simulation.campaign` (each trial on its
own child random generator); every estimator identifies the same data. Reported per
cell: the mean absolute parameter error, its Cramér–Rao bound
(:func:`hexcal.estimation.bounds.bound_mean_abs_error`), the efficiency error / bound, and
the validation pose error on random workspace poses when the controller uses the
identified parameters.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import inverse_kinematics, leg_readings
from hexcal.core.noise import NoiseModel
from hexcal.core.workspace import random_poses, workspace_corners
from hexcal.estimation.bounds import bound_mean_abs_error
from hexcal.models.pose import Measurements
from hexcal.simulation.campaign import MachineBatch, identify_batch, pose_errors, random_machines

#: Pose strategies: a function ``(nominal, n, rng) -> (n, 6)`` poses for one trial.
PoseStrategy = Callable[[Geometry, int, np.random.Generator], NDArray[np.float64]]


def _corners(nominal: Geometry, n: int, rng: np.random.Generator) -> NDArray[np.float64]:
    corners = workspace_corners(nominal)
    if n > len(corners):
        raise ValueError(f"{n} poses requested from the {len(corners)} corners")
    return corners[rng.permutation(len(corners))[:n]]


def _interior(nominal: Geometry, n: int, rng: np.random.Generator) -> NDArray[np.float64]:
    return random_poses(nominal, n, rng)


STRATEGIES: dict[str, PoseStrategy] = {"corners": _corners, "interior": _interior}


def fixed_strategy(poses_by_size: dict[int, NDArray[np.float64]]) -> PoseStrategy:
    """A strategy returning a fixed pose set per size (e.g. optimally selected poses)."""

    def strategy(nominal: Geometry, n: int, rng: np.random.Generator) -> NDArray[np.float64]:
        del nominal, rng
        if n not in poses_by_size:
            raise ValueError(f"no fixed pose set of {n} poses")
        return poses_by_size[n]

    return strategy


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
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all trials failed: NaN, counted below
            return self._row()

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


def run_study(
    nominal: Geometry,
    true: Geometry | None = None,
    methods: Sequence[str] = ("paper", "ml"),
    strategies: dict[str, PoseStrategy] | None = None,
    pose_counts: Sequence[int] = (15,),
    noises: dict[str, NoiseModel] | None = None,
    trials: int = 100,
    rng: int | None = 0,
    n_validation: int = 10,
    parameter_error: float = 5.0,
    jobs: int | None = 1,
    progress: Callable[[int, int], None] | None = None,
) -> list[StudyCell]:
    """Run a study (see the module docstring).

    Parameters
    ----------
    nominal : Geometry
        The controller's geometry, with a workspace box.
    true : Geometry, optional
        The real machine; default nominal plus uniform ±``parameter_error`` mm per trial.
    methods : sequence of str
        Estimators (:data:`hexcal.estimation.likelihood.ESTIMATORS`).
    strategies : dict of name to strategy, optional
        Default ``corners`` and ``interior`` (:data:`STRATEGIES`).
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
    progress : callable(done, total), optional

    Returns
    -------
    list of StudyCell
    """
    strategies = dict(STRATEGIES) if strategies is None else strategies
    noises = {"paper": NoiseModel()} if noises is None else noises
    entropy = np.random.SeedSequence(rng).entropy

    def trial_rng(*key: int) -> np.random.Generator:
        return np.random.default_rng(np.random.SeedSequence(entropy, spawn_key=key))

    base_rngs = [trial_rng(t) for t in range(trials)]
    euler = nominal.euler
    if true is None:
        true_vectors = random_machines(nominal, trials, parameter_error, base_rngs)
        true_gains = nominal.leg_gains
    else:
        true_vectors = np.broadcast_to(true.to_vector(), (trials, 42)).copy()
        true_gains = true.leg_gains
    machines = MachineBatch.from_vectors(true_vectors, true_gains)
    targets = np.stack([random_poses(nominal, n_validation, r) for r in base_rngs])
    cells: list[StudyCell] = []
    total = len(strategies) * len(pose_counts) * len(noises) * len(methods) * trials
    done = 0
    for s_index, (s_name, strategy) in enumerate(strategies.items()):
        for n in pose_counts:
            for z_index, (z_name, noise) in enumerate(noises.items()):
                # one generator per trial and cell, independent of the order of the cells
                rngs = [trial_rng(t, s_index, n, z_index) for t in range(trials)]
                commanded = np.stack([strategy(nominal, n, r) for r in rngs])
                leg_noise = np.stack([noise.leg_errors(r, (n,)) for r in rngs])
                pose_noise = np.stack([noise.pose_errors(r, (n,)) for r in rngs])
                readings = leg_readings(nominal, inverse_kinematics(nominal, commanded))
                actual = machines.reach(readings + leg_noise / machines.leg_gains[:, None], commanded, euler)
                measured = actual + pose_noise
                datasets = [Measurements(measured[t], readings[t]) for t in range(trials)]
                bounds = _cell_bounds(nominal, true, true_vectors, actual, noise)
                for method in methods:

                    def step(k: int, _n: int, base: int = done) -> None:
                        if progress:
                            progress(base + k, total)

                    vectors = identify_batch(nominal, datasets, method, jobs, step, noise)
                    done += trials
                    errors = np.mean(np.abs(vectors - true_vectors), axis=1)
                    pos, ang = _validate(nominal, machines, vectors, targets)
                    cells.append(StudyCell(s_name, n, z_name, method, errors, bounds, pos, ang))
    return cells


def _cell_bounds(
    nominal: Geometry,
    true: Geometry | None,
    true_vectors: NDArray[np.float64],
    actual: NDArray[np.float64],
    noise: NoiseModel,
) -> NDArray[np.float64]:
    if not np.any(noise.pose_cov()) and noise.sigmas[0] == 0:
        return np.full(len(actual), np.nan)
    if true is not None:
        return bound_mean_abs_error(true, actual, noise)
    return np.concatenate(
        [
            bound_mean_abs_error(nominal.with_vector(v), actual[t : t + 1], noise)
            for t, v in enumerate(true_vectors)
        ]
    )


def _validate(
    nominal: Geometry,
    machines: MachineBatch,
    vectors: NDArray[np.float64],
    targets: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """RMS validation pose errors per trial with the identified parameters (NaN if failed)."""
    ok = ~np.isnan(vectors[:, 0])
    safe = np.where(ok[:, None], vectors, nominal.to_vector())
    identified = MachineBatch.from_vectors(safe, nominal.leg_gains)
    commands = (
        identified.lengths(targets, nominal.euler) - identified.initial_leg_lengths[:, None]
    ) / identified.leg_gains[:, None]
    reached = machines.reach(commands, targets, nominal.euler)
    pos, ang = pose_errors(targets, reached, nominal.euler)
    pos_rms = np.sqrt(np.mean(pos**2, axis=1))
    ang_rms = np.sqrt(np.mean(ang**2, axis=1))
    pos_rms[~ok] = np.nan
    ang_rms[~ok] = np.nan
    return pos_rms, ang_rms


def format_study(cells: list[StudyCell]) -> str:
    """Text table of a study."""
    head = (
        f"  {'strategy':<10}{'poses':>6}  {'noise':<10}{'method':<8}{'error mm':>10}{'std':>8}"
        f"{'bound':>8}{'eff.':>6}{'val. pos rms':>14}{'val. ang rms':>14}"
    )
    lines = ["Mean absolute parameter error over the trials, its Cramér–Rao bound and validation", head]
    for cell in cells:
        r = cell.row()
        lines.append(
            f"  {r['strategy']:<10}{r['poses']:>6}  {r['noise']:<10}{r['method']:<8}{r['error_mean']:>10.4f}"
            f"{r['error_std']:>8.4f}{r['bound']:>8.4f}{r['efficiency']:>6.2f}"
            f"{r['position_rms']:>14.4g}{r['orientation_rms']:>14.3g}"
        )
    return "\n".join(lines)
