"""Batched identification: many independent identifications solved together, vectorised
across trials (Monte Carlo studies).

:func:`estimate_stack` identifies the ``T`` campaigns of a
:class:`~hexcal.estimation.stacked.Stack` (one instrument, one parameter layout; any leg
model) with the ``paper``, ``length`` or ``ml`` estimator; :func:`estimate_batch` is the same
for ``T`` full-pose data sets given as arrays. They give the optima of
:func:`hexcal.calibration.estimate` (``with_bound=False``) one campaign at a time, without a
Python loop over trials: the residuals and Jacobians are evaluated on ``(T, m)`` stacks and
every iteration solves a stack of small normal equations.

- ``paper`` and ``length`` (instruments that give the pose): each leg's residuals depend only
  on that leg's parameters (``u_i, s_i`` and its leg-model parameters), so the normal equations
  of one data set are block diagonal and the problem splits into six independent least-squares
  problems (of at most eight parameters for linear legs). Levenberg–Marquardt runs on the
  ``(T, 6)`` stack of those problems, with its own damping, accept/reject and convergence test
  for every trial and leg (the same optimum as the one solver over all parameters; the path
  differs).
- ``ml``: variable projection as in :mod:`hexcal.estimation.likelihood`; the inner
  Gauss–Newton pose solve runs on ``(T, m)`` stacks of 6×6 systems, the outer
  Levenberg–Marquardt on ``(T, n, n)`` stacks with the projected (Kaufman) Jacobian, per-trial
  damping, accept/reject and convergence (:mod:`hexcal.estimation.batched_ml`); it starts
  from the batched ``length`` estimate where the instrument gives the pose, else from the
  start values (a frame registered per trial), in the directions orthogonal to the gauges.

**Tolerance.** An iteration stops when it takes a step (solver units: mm, and 1e-3 for gains)
with ``|dx| <= xtol (xtol + |x|)`` (default ``xtol`` 1e-10), ``x`` the deviation from the start,
while the damping is negligible (a Gauss–Newton step); ``dx`` is then applied. The iterates
converge fast near the optimum, so the result is within rounding of the optimum (about 1e-11
mm in the tests), not merely within ``xtol |x|`` of it. A step is accepted when the cost does
not rise beyond the rounding of the sum of squares: near the optimum the cost cannot tell
steps apart (``paper`` residuals are differences of squares of 800 mm lengths) but the
gradient can. ``scipy.optimize.least_squares`` decides by the cost alone, and so stops up to
about 1e-5 mm short of the optimum in weakly determined directions; the one-at-a-time
reference of the tests is therefore ``estimate(..., with_bound=False, polish=5)`` (LM, then
Gauss–Newton steps), and both solvers agree to 1e-9 mm (measured: below 3e-11 mm).

Trials are solved in chunks (:data:`CHUNK`, ``chunk``) that stay in the CPU caches. Every
trial has its own damping, acceptance, convergence test and status (and, for ``paper`` and
``length``, every leg of it); the trials of a chunk share only the loop over iterations, so
a result does not depend on the other trials beyond rounding.

**Failures** do not spoil the other trials: a trial with non-finite input, a rank-deficient
start Jacobian (the rank rule of :mod:`hexcal.core.linalg`, judged as the one-at-a-time
solver does), or no convergence within ``max_iter`` iterations gets NaN values and its
status (:data:`STATUS_MESSAGES`).

>>> from hexcal.core.presets import preset
>>> from hexcal.core.workspace import workspace_corners
>>> from hexcal.estimation.uncertainty import planned_measurements
>>> nominal, real = preset("paper-hmt"), preset("paper-hmt-true")
>>> data = planned_measurements(real, workspace_corners(nominal)[::3])   # exact, noise-free
>>> batch = estimate_batch(nominal, data.readings[None], data.poses[None], "length")
>>> batch.values.shape, batch.status.tolist()
((1, 42), [1])
>>> round(float(batch.values[0, 0]), 4)    # the real machine's u1.x
305.2599
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.noise import NoiseModel
from hexcal.errors import IdentificationError, UsageError
from hexcal.estimation.batched_ml import ML_START_XTOL, solve_ml
from hexcal.estimation.batched_solver import (
    STATUS_CONVERGED,
    STATUS_MAX_ITER,
    STATUS_MESSAGES,
    STATUS_NONFINITE,
    STATUS_RANK_DEFICIENT,
    pose_frames_batch,
    solve_legs,
)
from hexcal.estimation.stacked import Stack
from hexcal.instruments.registry import full_pose

__all__ = [
    "BATCH_METHODS",
    "STATUS_CONVERGED",
    "STATUS_MAX_ITER",
    "STATUS_MESSAGES",
    "STATUS_NONFINITE",
    "STATUS_RANK_DEFICIENT",
    "BatchResult",
    "estimate_batch",
    "estimate_stack",
    "full_pose_stack",
    "identify_chunk",
]

#: Estimators the batched solvers implement.
BATCH_METHODS = ("paper", "length", "ml")
#: Trials solved together by default (measured on a 2-core machine: larger stacks fall out of
#: the caches for the leg-separable methods; maximum likelihood gains from amortising more).
CHUNK = {"paper": 256, "length": 256, "ml": 1024}


@dataclass(frozen=True, eq=False)
class BatchResult:
    """Outcome of :func:`estimate_stack` (arrays over trials).

    Attributes
    ----------
    method : str
    names : tuple of str
        Names of the varied parameters.
    values : ndarray, shape (T, n)
        Identified values (mm; gains dimensionless); NaN rows for failed trials.
    status : ndarray of int, shape (T,)
        :data:`STATUS_CONVERGED` (1), or a failure (<= 0, :data:`STATUS_MESSAGES`).
    iterations : ndarray of int, shape (T,)
        Levenberg–Marquardt iterations (the most of the six legs for ``paper``/``length``).
    cost : ndarray, shape (T,)
        ``0.5 * sum(residuals**2)`` at the solution (the method's residuals; NaN if failed).
    rank : ndarray of int, shape (T,)
        Numerical rank of the start Jacobian (column-normalised; the leg-separable methods).
    """

    method: str
    names: tuple[str, ...]
    values: NDArray[np.float64]
    status: NDArray[np.int_]
    iterations: NDArray[np.int_]
    cost: NDArray[np.float64]
    rank: NDArray[np.int_]

    def __len__(self) -> int:
        return int(self.status.shape[0])

    @property
    def converged(self) -> NDArray[np.bool_]:
        """Whether each trial converged (its values are the identified ones)."""
        return self.status == STATUS_CONVERGED

    @property
    def message(self) -> tuple[str, ...]:
        """One message per trial."""
        return tuple(STATUS_MESSAGES[int(s)] for s in self.status)


def full_pose_stack(
    start: Geometry,
    readings: ArrayLike,
    poses: ArrayLike,
    mask: ArrayLike | None = None,
    starts: ArrayLike | None = None,
) -> Stack:
    """The stack of ``T`` full-pose data sets: readings and measured poses ``(T, m, 6)``,
    ``mask`` over the machine's parameters (default joints and ``l0``), per-trial machine start
    values ``starts`` ``(T, 36 + p)`` (default ``start``'s)."""
    readings = np.array(readings, dtype=float)
    poses = np.array(poses, dtype=float)
    if poses.ndim != 3 or poses.shape[-1] != 6 or readings.shape != poses.shape:
        raise UsageError(
            f"readings and poses must both have shape (T, m, 6), got {readings.shape}, {poses.shape}"
        )
    from hexcal.estimation.sessions import problem_parameters
    from hexcal.instruments.base import Session
    from hexcal.instruments.data import Measurements

    instrument = full_pose()
    template = Measurements(np.zeros((1, 6)), np.zeros((1, 6)))
    params = problem_parameters(start, [Session(template, instrument)], mask)
    t = len(poses)
    full0 = np.tile(np.asarray(params.values), (t, 1))
    machine = slice(params.span("joints").start, params.span("legs").stop)
    if starts is not None:
        full0[:, machine] = np.broadcast_to(
            np.asarray(starts, dtype=float), (t, machine.stop - machine.start)
        )
    present = np.ones(poses.shape, dtype=bool)
    return Stack(start, instrument, params, full0, readings, poses, present)


def estimate_batch(
    start: Geometry,
    readings: ArrayLike,
    poses: ArrayLike,
    method: str = "paper",
    mask: ArrayLike | None = None,
    noise: NoiseModel | None = None,
    *,
    starts: ArrayLike | None = None,
    xtol: float = 1e-10,
    max_iter: int = 100,
    chunk: int | None = None,
) -> BatchResult:
    """Identify ``T`` full-pose data sets at once (:func:`estimate_stack` of
    :func:`full_pose_stack`).

    Parameters
    ----------
    start : Geometry
        Start values (the nominal geometry), leg model and Euler convention, shared.
    readings : array_like, shape (T, m, 6)
        Leg readings of every trial.
    poses : array_like, shape (T, m, 6)
        Measured poses of every trial, mm and rad.
    method : {"paper", "length", "ml"}
    mask : array_like of bool, optional
        Varied machine parameters (48 for linear legs; default joints and ``l0``).
    noise : NoiseModel, optional
        The noise model ``ml`` assumes (default the seed paper's).
    starts : array_like, shape (T, 36 + p), optional
        Per-trial start values of the machine's parameters, replacing ``start``'s.
    xtol, max_iter, chunk
        As :func:`estimate_stack`.
    """
    stack = full_pose_stack(start, readings, poses, mask, starts)
    return estimate_stack(stack, method, noise, xtol=xtol, max_iter=max_iter, chunk=chunk)


def estimate_stack(
    stack: Stack,
    method: str = "ml",
    noise: NoiseModel | None = None,
    *,
    xtol: float = 1e-10,
    max_iter: int = 100,
    chunk: int | None = None,
) -> BatchResult:
    """Identify every campaign of a stack at once (see the module notes).

    Parameters
    ----------
    stack : Stack
    method : {"paper", "length", "ml"}
        ``paper`` and ``length`` need an instrument that gives the pose.
    noise : NoiseModel, optional
        The noise model ``ml`` assumes (default the seed paper's).
    xtol : float
        Step tolerance, solver units (module notes).
    max_iter : int
        Levenberg–Marquardt iterations per trial (and per leg for ``paper``/``length``).
    chunk : int, optional
        Trials solved together (default :data:`CHUNK`: stacks that stay in the CPU caches;
        the results do not depend on it beyond rounding).

    Returns
    -------
    BatchResult
    """
    if method not in BATCH_METHODS:
        raise UsageError(f"unknown batched method {method!r}; choose from {', '.join(BATCH_METHODS)}")
    inst = stack.instrument
    if method != "ml" and not inst.determines_pose:
        raise IdentificationError(
            f"the {method} estimator needs the platform pose measured at every observation; the "
            f"{inst.describe()} does not give it: use ml"
        )
    mask = stack.mask
    m = stack.readings.shape[1]
    per_leg = int(np.max(mask[stack.leg_columns()].sum(axis=1)))
    if inst.determines_pose and (m < per_leg or 6 * m < mask.sum()):
        raise IdentificationError(f"{m} poses cannot determine the parameters: at least {per_leg} are needed")
    noise = NoiseModel() if noise is None else noise
    size = chunk or CHUNK[method]
    parts = [
        _identify(_rows(stack, slice(k, k + size)), method, noise, xtol, max_iter)
        for k in range(0, len(stack), size)
    ]
    values, status, iterations, cost, rank = (np.concatenate(arrays) for arrays in zip(*parts, strict=True))
    names = stack.parameters.free_names
    return BatchResult(method, names, values, status, iterations, cost, rank)


def _rows(stack: Stack, rows: slice) -> Stack:
    sessions = None if stack.sessions is None else stack.sessions[rows]
    return replace(
        stack,
        full0=np.array(stack.full0[rows]),
        readings=np.array(stack.readings[rows]),
        observed=np.array(stack.observed[rows]),
        present=stack.present[rows],
        sessions=sessions,
    )


def _identify(stack: Stack, method: str, noise: NoiseModel, xtol: float, max_iter: int) -> tuple:
    """One chunk of :func:`estimate_stack`: ``(values, status, iterations, cost, rank)``."""
    full0, readings, observed = stack.full0, stack.readings, stack.observed
    alive = np.all(np.isfinite(full0), axis=1) & np.all(np.isfinite(readings), axis=(1, 2))
    alive &= np.all(np.isfinite(np.where(stack.present, observed, 0.0)), axis=(1, 2))
    # dead trials get harmless stand-in data so that no stacked solve sees NaN
    stand_in = int(np.argmax(alive)) if alive.any() else None
    if stand_in is not None:
        full0[~alive], readings[~alive], observed[~alive] = (
            full0[stand_in],
            readings[stand_in],
            observed[stand_in],
        )
    inst = stack.instrument
    mask = stack.mask
    t = len(stack)
    ml = method == "ml" and np.any(inst.covariance(noise) != 0)
    full = np.array(full0)
    status = np.where(alive, STATUS_CONVERGED, STATUS_NONFINITE)
    iterations = np.zeros(t, dtype=int)
    cost = np.full(t, np.nan)
    rank = np.full(t, int(mask.sum()))
    warm = False
    if inst.determines_pose:
        platform = inst.platform_from(full0[:, stack.setup], observed, stack.euler)
        rot, pos = pose_frames_batch(platform, stack.euler)
        machine = stack.machine
        solved, status, iterations, cost, rank = solve_legs(
            full0[:, machine],
            rot,
            pos,
            readings.transpose(0, 2, 1),
            mask[machine],
            "paper" if method == "paper" else "length",
            alive,
            ML_START_XTOL if ml else xtol,
            max_iter,
            stack.start.leg_model,
            stack.leg_columns() - machine.start,
            stack.scales[machine],
        )
        full[:, machine] = solved
        warm = True
    if ml:
        ok = status == STATUS_CONVERGED
        full, ml_status, ml_iterations, cost = solve_ml(stack, full, noise, ok, xtol, max_iter, warm)
        status = np.where(ok, ml_status, status)
        iterations = iterations + ml_iterations
    failed = status != STATUS_CONVERGED
    values = full[:, mask]
    values[failed] = np.nan
    return values, status, iterations, np.where(failed, np.nan, cost), rank


def identify_chunk(
    start: Geometry,
    readings: ArrayLike,
    poses: ArrayLike,
    methods: tuple[str, ...] = ("paper",),
    mask: ArrayLike | None = None,
    noise: NoiseModel | None = None,
) -> dict[str, NDArray[np.float64]]:
    """Identified values ``(T, n)`` of a chunk of simulated full-pose trials by each method (NaN
    rows where an identification failed): the unit of work of a study's executor."""
    return {name: estimate_batch(start, readings, poses, name, mask, noise).values for name in methods}
