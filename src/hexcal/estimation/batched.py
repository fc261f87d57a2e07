"""Batched identification: many independent identifications solved together, vectorised
across trials (Monte Carlo studies).

:func:`estimate_stack` identifies the ``T`` campaigns of a
:class:`~hexcal.estimation.stacked.Stack` (one instrument, one parameter layout; any leg
model) with the ``paper``, ``length``, ``gls`` or ``ml`` estimator; :func:`estimate_batch` is the same
for ``T`` full-pose data sets given as arrays. They give the optima of
:func:`hexcal.calibration.estimate` (``with_bound=False``) one campaign at a time, without a
Python loop over trials: the residuals and Jacobians are evaluated on ``(T, m)`` stacks and
every iteration solves a stack of small normal equations.

- ``paper`` and ``length`` (instruments that give the pose): the six per-leg problems of
  every trial (:func:`hexcal.estimation.least_squares.solve_legs`);
- ``gls``: the whitened legs of every trial, twice, the weights at each estimate
  (:func:`hexcal.estimation.gls.solve_stack_gls`);
- ``ml``: variable projection (:func:`hexcal.estimation.likelihood.solve_ml`), from the
  ``length`` estimate where the instrument gives the pose, else from the start values (a frame
  registered per trial), in the directions orthogonal to the gauges.

These are the solvers of one identification too (a stack of one): every trial has its own
damping, acceptance, convergence test and status (:mod:`hexcal.estimation.levenberg`), and the
result is within rounding of the optimum. The tests compare them with
``scipy.optimize.least_squares`` followed by Gauss–Newton steps (to 1e-9 mm).

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

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.noise import NoiseModel
from hexcal.errors import IdentificationError, UsageError
from hexcal.estimation.gls import solve_stack_gls
from hexcal.estimation.least_squares import solve_legs
from hexcal.estimation.levenberg import (
    STATUS_CONVERGED,
    STATUS_MAX_ITER,
    STATUS_MESSAGES,
    STATUS_NONFINITE,
    STATUS_RANK_DEFICIENT,
)
from hexcal.estimation.likelihood import solve_ml
from hexcal.estimation.result import IdentificationResult
from hexcal.estimation.stacked import Stack, StackPart, start_poses
from hexcal.instruments.registry import full_pose

__all__ = [
    "BATCH_METHODS",
    "STATUS_CONVERGED",
    "STATUS_MAX_ITER",
    "STATUS_MESSAGES",
    "STATUS_NONFINITE",
    "STATUS_RANK_DEFICIENT",
    "estimate_batch",
    "estimate_stack",
    "full_pose_stack",
    "identify_chunk",
]

#: Estimators the batched solvers implement (every built-in one).
BATCH_METHODS = ("paper", "length", "gls", "ml")
#: Trials solved together by default (measured on a 2-core machine: larger stacks fall out of
#: the caches for the leg-separable methods; maximum likelihood gains from amortising more).
CHUNK = {"paper": 256, "length": 256, "gls": 256, "ml": 1024}


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
    block = params.span("setup.0")
    part = StackPart(
        instrument,
        block,
        readings,
        poses,
        present,
        start_poses(start, instrument, full0, params, block, readings, poses),
    )
    return Stack(start, params, full0, (part,))


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
) -> IdentificationResult:
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
    method : {"paper", "length", "gls", "ml"}
    mask : array_like of bool, optional
        Varied machine parameters (48 for linear legs; default joints and ``l0``).
    noise : NoiseModel, optional
        The noise model ``ml`` and ``gls`` assume (default the seed paper's).
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
) -> IdentificationResult:
    """Identify every campaign of a stack at once (see the module notes).

    Parameters
    ----------
    stack : Stack
    method : {"paper", "length", "gls", "ml"}
        ``paper``, ``length`` and ``gls`` need instruments that give the pose.
    noise : NoiseModel, optional
        The noise model ``ml`` and ``gls`` assume (default the seed paper's), for every session.
    xtol : float
        Step tolerance, solver units (:mod:`hexcal.estimation.levenberg`).
    max_iter : int
        Levenberg–Marquardt iterations per trial (and per leg for ``paper``/``length``).
    chunk : int, optional
        Trials solved together (default :data:`CHUNK`: stacks that stay in the CPU caches;
        the results do not depend on it beyond rounding).

    Returns
    -------
    IdentificationResult
        A batch: ``values`` ``(T, n)`` (NaN rows for failed trials), ``status``,
        ``iterations``, ``cost`` and ``rank`` ``(T,)``.
    """
    if method not in BATCH_METHODS:
        raise UsageError(f"unknown batched method {method!r}; choose from {', '.join(BATCH_METHODS)}")
    if method != "ml" and not stack.determines_pose:
        inst = next(p.instrument for p in stack.parts if not p.instrument.determines_pose)
        raise IdentificationError(
            f"the {method} estimator needs the platform pose measured at every observation; the "
            f"{inst.describe()} does not give it: use ml"
        )
    mask = stack.mask
    m = sum(p.readings.shape[1] for p in stack.parts)
    per_leg = int(np.max(mask[stack.leg_columns()].sum(axis=1)))
    if stack.determines_pose and (m < per_leg or 6 * m < mask.sum()):
        raise IdentificationError(f"{m} poses cannot determine the parameters: at least {per_leg} are needed")
    noise = NoiseModel() if noise is None else noise
    size = chunk or CHUNK[method]
    parts = [
        _identify(stack.rows(slice(k, k + size)), method, noise, xtol, max_iter)
        for k in range(0, len(stack), size)
    ]
    values, status, iterations, cost, rank = (np.concatenate(arrays) for arrays in zip(*parts, strict=True))
    return IdentificationResult(
        method,
        stack.parameters.free_names,
        values,
        status,
        iterations,
        cost,
        rank,
        stack.start,
        stack.full0[:, mask],
        model="+".join(dict.fromkeys(p.instrument.name for p in stack.parts)),
        noises=(noise,) * len(stack.parts),
    )


def _identify(stack: Stack, method: str, noise: NoiseModel, xtol: float, max_iter: int) -> tuple:
    """One chunk of :func:`estimate_stack`: ``(values, status, iterations, cost, rank)``."""
    full0 = stack.full0
    alive = np.all(np.isfinite(full0), axis=1)
    for part in stack.parts:
        alive &= np.all(np.isfinite(part.readings), axis=(1, 2))
        alive &= np.all(np.isfinite(np.where(part.present, part.observed, 0.0)), axis=(1, 2))
    # dead trials get harmless stand-in data so that no stacked solve sees NaN
    if alive.any() and not alive.all():
        stand_in = int(np.argmax(alive))
        full0[~alive] = full0[stand_in]
        for part in stack.parts:
            for array in (part.readings, part.observed, part.start_poses):
                array[~alive] = array[stand_in]
    noises = (noise,) * len(stack.parts)
    if method == "gls":
        full, status, iterations, cost, rank, _ = solve_stack_gls(
            stack, noises, alive, xtol=xtol, max_iter=max_iter
        )
    elif method == "ml":
        solution = solve_ml(stack, noises, alive, xtol, max_iter)
        full, status, iterations, cost, rank = (
            solution.full,
            solution.status,
            solution.iterations,
            solution.cost,
            solution.rank,
        )
    else:
        full, status, iterations, cost, rank = solve_legs(stack, method, alive, xtol, max_iter)
    failed = status != STATUS_CONVERGED
    values = full[:, stack.mask]
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
