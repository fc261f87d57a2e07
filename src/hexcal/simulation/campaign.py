"""Simulation of calibration campaigns (the seed paper's section VI).

The protocol, with ``T`` Monte Carlo trials each on its own child random generator
(so results do not depend on how trials are scheduled or split across processes):

1. the true machine is a given geometry, or the nominal one plus uniform errors;
2. leg readings come from the nominal inverse kinematics of the commanded poses,
   ``dl = (IK_nominal(pose) - l0_nominal) / g_nominal``;
3. the machine really reaches the forward kinematics of the true geometry at
   ``l0_true + g_true dl + e`` with the leg sensor error ``e``;
4. the measured pose is that pose plus the measurement noise;
5. identification starts from the nominal geometry;
6. validation commands further poses with the nominal and with the identified
   parameters and compares where the true machine goes with the targets.

The data generation and validation are batched over all trials; only the
identifications themselves (one ``least_squares`` call each) run trial by trial,
optionally in several processes.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from hexcal.core.conventions import orientation_error
from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import (
    forward_kinematics_from_arrays,
    inverse_kinematics,
    leg_readings,
    leg_vectors_from_arrays,
)
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import N_BASE_PARAMETERS, select_parameters
from hexcal.core.workspace import random_poses, workspace_corners
from hexcal.errors import IdentificationError, SimulationError
from hexcal.estimation.bounds import bound_mean_abs_error
from hexcal.estimation.fitting import estimate
from hexcal.models.pose import Measurements

Progress = Callable[[int, int], None]




@dataclass(frozen=True)
class MachineBatch:
    """Kinematic parameters of ``T`` machines as arrays (one per trial)."""

    base_joints: NDArray[np.float64]  # (T, 6, 3)
    platform_joints: NDArray[np.float64]  # (T, 6, 3)
    initial_leg_lengths: NDArray[np.float64]  # (T, 6)
    leg_gains: NDArray[np.float64]  # (T, 6)

    @classmethod
    def from_vectors(cls, vectors: NDArray[np.float64], gains: NDArray[np.float64]) -> MachineBatch:
        t = vectors.shape[0]
        return cls(
            vectors[:, :18].reshape(t, 6, 3),
            vectors[:, 18:36].reshape(t, 6, 3),
            vectors[:, 36:42],
            np.broadcast_to(gains, (t, 6)),
        )

    def lengths(self, poses: NDArray[np.float64], euler: str) -> NDArray[np.float64]:
        """Leg lengths of poses ``(T, n, 6)`` on each trial's machine."""
        legs, _ = leg_vectors_from_arrays(
            self.base_joints[:, None], self.platform_joints[:, None], poses, euler
        )
        return np.linalg.norm(legs, axis=-1)

    def reach(
        self, readings: NDArray[np.float64], guess: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        """Poses the machines reach for readings ``(T, n, 6)`` (forward kinematics)."""
        lengths = self.initial_leg_lengths[:, None] + self.leg_gains[:, None] * readings
        result = forward_kinematics_from_arrays(
            self.base_joints[:, None], self.platform_joints[:, None], lengths, guess, euler
        )
        if not result.all_converged:
            bad = int(np.sum(~result.converged))
            raise SimulationError(
                f"forward kinematics did not converge for {bad} simulated pose(s): "
                "the commanded poses are not reachable by the simulated machine"
            )
        return result.poses


def simulate_measurements(
    nominal: Geometry,
    true: Geometry,
    poses: NDArray[np.float64],
    noise: NoiseModel | None = None,
    rng: np.random.Generator | int | None = None,
    ids: tuple[str, ...] | None = None,
) -> Measurements:
    """Simulated measurements of commanded poses on a true machine (the paper's protocol).

    Leg readings come from the nominal inverse kinematics; the true machine reaches the
    forward kinematics of its leg lengths plus the leg sensor error; the measured pose
    adds the pose measurement noise.

    Parameters
    ----------
    nominal, true : Geometry
    poses : array_like, shape (m, 6)
        Commanded poses.
    noise : NoiseModel, optional
        Default the paper's.
    rng : Generator, int or None
    ids : tuple of str, optional
    """
    noise = NoiseModel() if noise is None else noise
    rng = np.random.default_rng(rng)
    poses = np.asarray(poses, dtype=float).reshape(-1, 6)
    m = poses.shape[0]
    readings = leg_readings(nominal, inverse_kinematics(nominal, poses))
    machine = MachineBatch.from_vectors(true.to_vector()[None], true.leg_gains)
    sensor = noise.leg_errors(rng, (m,))
    reached = machine.reach((readings + sensor / true.leg_gains)[None], poses[None], true.euler)[0]
    return Measurements(reached + noise.pose_errors(rng, (m,)), readings, ids or ())


def pose_errors(
    targets: NDArray[np.float64], reached: NDArray[np.float64], euler: str
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Position error (mm) and orientation error (rad, rotation angle) of each pose."""
    position = np.linalg.norm(reached[..., :3] - targets[..., :3], axis=-1)
    return position, orientation_error(targets[..., 3:], reached[..., 3:], euler)


def _identify_many(
    start: Geometry, datasets: list[Measurements], method: str, noise: NoiseModel | None = None
) -> NDArray[np.float64]:
    """Identified 42-vectors of several data sets; NaN rows where identification failed."""
    mask = select_parameters()
    out = np.full((len(datasets), N_BASE_PARAMETERS), np.nan)
    for k, data in enumerate(datasets):
        try:
            out[k] = estimate(start, data, method, mask, noise, with_bound=False).values
        except IdentificationError:
            pass
    return out


def identify_batch(
    start: Geometry,
    datasets: list[Measurements],
    method: str = "paper",
    jobs: int | None = 1,
    progress: Progress | None = None,
    noise: NoiseModel | None = None,
) -> NDArray[np.float64]:
    """Identify many data sets, in ``jobs`` processes (``None``: all cores).

    ``method`` is any of :data:`hexcal.estimation.likelihood.ESTIMATORS`; ``noise`` is the noise
    model the ``ml`` and ``gls`` estimators assume. Returns the identified 42-vectors,
    shape ``(len(datasets), 42)``, with NaN rows where an identification failed.
    """
    jobs = (os.cpu_count() or 1) if jobs is None else max(1, int(jobs))
    n = len(datasets)
    chunk = max(1, min(50, -(-n // (4 * jobs))))
    pieces = [datasets[i : i + chunk] for i in range(0, n, chunk)]
    results: list[NDArray[np.float64]] = []
    done = 0
    if jobs == 1 or len(pieces) == 1:
        for piece in pieces:
            results.append(_identify_many(start, piece, method, noise))
            done += len(piece)
            if progress:
                progress(done, n)
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = [pool.submit(_identify_many, start, piece, method, noise) for piece in pieces]
            for piece, future in zip(pieces, futures, strict=True):
                results.append(future.result())
                done += len(piece)
                if progress:
                    progress(done, n)
    return np.concatenate(results) if results else np.empty((0, N_BASE_PARAMETERS))


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
        corners; NaN rows where identification failed.
    validation_targets : ndarray, shape (T, n_validation, 6)
    validation_before, validation_after : dict of ndarray, shape (T, n_validation)
        ``position`` (mm) and ``orientation`` (rad) errors of the validation poses
        with the nominal and with the boundary-identified parameters.
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


def random_machines(
    nominal: Geometry, trials: int, error: float, rngs: list[np.random.Generator]
) -> NDArray[np.float64]:
    """True 42-vectors: nominal plus uniform errors in ``[-error, error]`` mm, one per rng."""
    base = nominal.to_vector()
    return np.stack([base + r.uniform(-error, error, base.size) for r in rngs[:trials]])


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
        Seed; each trial gets a spawned child generator.
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
        Processes for the identifications (None: all cores).
    progress : callable(done, total), optional
    extra_rows : tuple of (name, strategy, method)
        Further rows on the same trials: ``strategy`` is ``"interior"`` or ``"boundary"``
        (the very same data as those rows) or ``"selected"`` (the fixed
        ``selected_poses`` measured with fresh noise in every trial); ``method`` any
        estimator of :data:`hexcal.estimation.likelihood.ESTIMATORS` (``ml`` and ``gls`` assume
        ``noise``).
    selected_poses : ndarray, shape (n, 6), optional
        Poses of the ``"selected"`` strategy (e.g. optimally selected ones).

    Returns
    -------
    PaperExperiment
    """
    if trials < 1:
        raise ValueError(f"trials must be at least 1, got {trials}")
    corners = workspace_corners(nominal)
    if n_poses + n_validation > len(corners):
        raise ValueError(f"{n_poses} measurement and {n_validation} validation corners exceed the 64 corners")
    noise = NoiseModel() if noise is None else noise
    seq = rng if isinstance(rng, np.random.SeedSequence) else np.random.SeedSequence(rng)
    rngs = [np.random.default_rng(child) for child in seq.spawn(trials)]
    euler = nominal.euler

    # per-trial random choices, each from the trial's own generator
    pick = np.stack([r.permutation(64)[: n_poses + n_validation] for r in rngs])
    interior = np.stack([random_poses(nominal, n_poses, r) for r in rngs])
    leg_noise = np.stack([noise.leg_errors(r, (2 * n_poses,)) for r in rngs])
    pose_noise = np.stack([noise.pose_errors(r, (2 * n_poses,)) for r in rngs])
    if true is None:
        true_vectors = random_machines(nominal, trials, parameter_error, rngs)
        true_gains = nominal.leg_gains
    else:
        true_vectors = np.broadcast_to(true.to_vector(), (trials, N_BASE_PARAMETERS)).copy()
        true_gains = true.leg_gains
    machines = MachineBatch.from_vectors(true_vectors, true_gains)
    strategies = {row[1] for row in extra_rows}
    if not strategies <= {"interior", "boundary", "selected"}:
        raise ValueError(f"unknown pose strategy in {sorted(strategies)}")
    if "selected" in strategies:
        if selected_poses is None:
            raise ValueError("the 'selected' strategy needs selected_poses")
        selected = np.asarray(selected_poses, dtype=float).reshape(-1, 6)
        n_sel = selected.shape[0]
        sel_leg = np.stack([noise.leg_errors(r, (n_sel,)) for r in rngs])
        sel_pose = np.stack([noise.pose_errors(r, (n_sel,)) for r in rngs])
        sel_cmd = np.broadcast_to(selected, (trials, n_sel, 6))
        sel_readings = leg_readings(nominal, inverse_kinematics(nominal, sel_cmd))
        sel_actual = machines.reach(sel_readings + sel_leg / machines.leg_gains[:, None], sel_cmd, euler)
        sel_measured = sel_actual + sel_pose

    boundary = corners[pick[:, :n_poses]]
    targets = corners[pick[:, n_poses:]]
    commanded = np.concatenate([interior, boundary], axis=1)  # (T, 2 n, 6)
    readings = leg_readings(nominal, inverse_kinematics(nominal, commanded))
    actual = machines.reach(readings + leg_noise / machines.leg_gains[:, None], commanded, euler)
    measured = actual + pose_noise

    def datasets(sl: slice) -> list[Measurements]:
        return [Measurements(measured[t, sl], readings[t, sl]) for t in range(trials)]

    total = (2 + len(extra_rows)) * trials
    offset = [0]

    def step(done: int, _n: int) -> None:
        if progress:
            progress(offset[0] + done, total)

    interior_vectors = identify_batch(nominal, datasets(slice(0, n_poses)), method, jobs, step)
    offset[0] = trials
    boundary_vectors = identify_batch(nominal, datasets(slice(n_poses, 2 * n_poses)), method, jobs, step)
    extra: dict[str, NDArray[np.float64]] = {}
    for k, (name, strategy, row_method) in enumerate(extra_rows):
        offset[0] = (2 + k) * trials
        if strategy == "selected":
            sets = [Measurements(sel_measured[t], sel_readings[t]) for t in range(trials)]
        else:
            sets = datasets(slice(0, n_poses) if strategy == "interior" else slice(n_poses, 2 * n_poses))
        extra[name] = identify_batch(nominal, sets, row_method, jobs, step, noise)

    pose_sets = {"interior": actual[:, :n_poses], "boundary": actual[:, n_poses:]}
    if "selected" in strategies:
        pose_sets["selected"] = sel_actual
    bounds = _bounds(nominal, true, true_vectors, pose_sets, noise)

    # validation: the nominal controller, and the controller with the identified parameters
    before_readings = leg_readings(nominal, inverse_kinematics(nominal, targets))
    reached_before = machines.reach(before_readings, targets, euler)
    ok = ~np.isnan(boundary_vectors[:, 0])
    identified = MachineBatch.from_vectors(
        np.where(ok[:, None], boundary_vectors, true_vectors), nominal.leg_gains
    )
    after_readings = (
        identified.lengths(targets, euler) - identified.initial_leg_lengths[:, None]
    ) / identified.leg_gains[:, None]
    reached_after = machines.reach(after_readings, targets, euler)
    pos_b, ang_b = pose_errors(targets, reached_before, euler)
    pos_a, ang_a = pose_errors(targets, reached_after, euler)
    pos_a[~ok], ang_a[~ok] = np.nan, np.nan
    return PaperExperiment(
        nominal_vector=nominal.to_vector(),
        true_vectors=true_vectors,
        interior_vectors=interior_vectors,
        boundary_vectors=boundary_vectors,
        validation_targets=targets,
        validation_before={"position": pos_b, "orientation": ang_b},
        validation_after={"position": pos_a, "orientation": ang_a},
        method=method,
        extra=extra,
        bounds=bounds,
        row_strategies={"interior": "interior", "boundary": "boundary"}
        | {name: strategy for name, strategy, _ in extra_rows},
    )


def _bounds(
    nominal: Geometry,
    true: Geometry | None,
    true_vectors: NDArray[np.float64],
    pose_sets: dict[str, NDArray[np.float64]],
    noise: NoiseModel,
) -> dict[str, NDArray[np.float64]]:
    """Per-trial bound of the mean absolute error for each pose strategy (empty without noise)."""
    if not np.any(noise.pose_cov()) and noise.sigmas[0] == 0:
        return {}
    out = {}
    for name, sets in pose_sets.items():
        if true is not None:
            out[name] = bound_mean_abs_error(true, sets, noise)
        else:  # a different machine in every trial
            out[name] = np.concatenate(
                [
                    bound_mean_abs_error(nominal.with_vector(v), sets[t : t + 1], noise)
                    for t, v in enumerate(true_vectors)
                ]
            )
    return out
