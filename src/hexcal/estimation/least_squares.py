"""Least squares on the leg residuals at the measured poses: the ``length`` and ``paper``
estimators, and the whitened residuals of ``gls``.

- ``"paper"``: the seed paper's cost (Agheli & Nategh 2009, eq. 3, after Zhuang et al. 1998
  and Chiu & Perng 2004): ``r_ij = |v_ij|² - (l0_i + g_i dl_ij)²`` (mm²);
- ``"length"``: the leg length residual ``r_ij = |v_ij| - (l0_i + g_i dl_ij)`` (mm);
- whitened (:mod:`hexcal.estimation.gls`): each pose's six length residuals times a matrix
  ``W_j`` (their inverse covariance's square root).

They need instruments whose observation determines the pose. Each leg's residuals depend only on
that leg's parameters (its base and platform joints and its leg-model parameters,
:func:`hexcal.core.machine.leg_columns`), so the ``paper`` and ``length`` problems split into six
independent least-squares problems per campaign (of at most eight parameters for linear legs):
:class:`LegProblems` is the batch of those ``(T, 6)`` problems, :class:`WhitenedLegs` the batch
of ``T`` whitened ones (the whitening couples the legs). Both are solved by the one
Levenberg–Marquardt solver (:func:`hexcal.estimation.levenberg.minimise`); one identification is
a stack of one (:meth:`hexcal.estimation.stacked.Stack.of_problem`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.linalg import RANK_RTOL
from hexcal.core.machine import leg_equations, pose_frames
from hexcal.core.noise import NoiseModel
from hexcal.errors import IdentificationError
from hexcal.estimation.covariance import finish_result
from hexcal.estimation.levenberg import (
    STATUS_CONVERGED,
    STATUS_MAX_ITER,
    STATUS_NONFINITE,
    STATUS_RANK_DEFICIENT,
    Convergence,
    minimise,
    rounding_floor,
)
from hexcal.estimation.problem import Problem
from hexcal.estimation.result import IdentificationResult, rms
from hexcal.estimation.stacked import Stack


def measured_frames(stack: Stack) -> tuple[NDArray, NDArray, NDArray]:
    """Rotations ``(T, m, 3, 3)``, positions ``(T, m, 3)`` and readings ``(T, m, 6)`` of the
    measured platform poses of every session (instruments that determine the pose)."""
    poses = np.concatenate(
        [p.instrument.platform_from(stack.full0[:, p.block], p.observed, stack.euler) for p in stack.parts],
        axis=1,
    )
    rot, pos = pose_frames(poses, stack.euler)
    return rot, pos, np.concatenate([p.readings for p in stack.parts], axis=1)


# -- the leg-separable problems ---------------------------------------------------------------
def block_rank(h: NDArray[np.float64], free: NDArray[np.bool_], js: NDArray[np.float64]) -> NDArray:
    """Rank of each trial's column-normalised Jacobian (union of its legs' singular values).

    ``h`` ``(T, 6, L, L)`` the legs' Gram matrices (identity rows for fixed parameters), ``js``
    ``(T, 6, m, L)`` their Jacobians. A cheap sound screen first: with ``H`` the normalised Gram
    matrix of a leg (unit diagonal), ``λ_min(H) >= 1 / trace(H⁻¹)``; trials whose every leg
    clears ``1e-12`` (far above the rank rule's ``RANK_RTOL² ≈ 1e-16`` of ``λ_max <= 8``) have
    full rank. The others get the exact SVD rule.
    """
    t, n_free = h.shape[0], int(free.sum())
    diag = np.sqrt(np.diagonal(h, axis1=-2, axis2=-1))
    hn = h / (diag[..., :, None] * diag[..., None, :])
    try:
        trace = np.trace(np.linalg.inv(hn), axis1=-2, axis2=-1)
        sure = np.all(
            np.isfinite(trace) & (trace > 0) & (1.0 / np.where(trace > 0, trace, 1.0) > 1e-12), axis=1
        )
    except np.linalg.LinAlgError:
        sure = np.zeros(t, dtype=bool)
    rank = np.full(t, n_free)
    doubt = np.flatnonzero(~sure)
    if doubt.size:
        sub = js[doubt]
        norms = np.linalg.norm(sub, axis=2)
        sv = np.linalg.svd(sub / np.where(norms > 0, norms, 1.0)[:, :, None], compute_uv=False)
        sv = sv.reshape(doubt.size, -1)
        rank[doubt] = np.sum(sv > RANK_RTOL * sv.max(axis=1, keepdims=True), axis=1)
    return rank


class LegProblems:
    """The ``(T, 6)`` per-leg least-squares problems of a stack, flattened to ``B = 6 T``
    (problem ``6 t + i`` is leg ``i`` of trial ``t``): the :class:`~hexcal.estimation.levenberg.Model`
    of the ``paper`` and ``length`` estimators.

    Parameters
    ----------
    table0 : ndarray, shape (T, 6, L)
        Each trial's leg table at its start values.
    rot, pos, readings
        The measured pose frames and readings (:func:`measured_frames`).
    free : ndarray of bool, shape (6, L)
        Each leg's varied parameters.
    scales : ndarray, shape (6, L)
        Their solver scales.
    """

    def __init__(self, table0, rot, pos, readings, free, scales, variant, model) -> None:
        self.rot, self.pos, self.readings, self.variant, self.model = rot, pos, readings, variant, model
        self.width = table0.shape[-1]
        self.free = free
        self.col = (scales * free).reshape(1, 6, -1)  # solver units; 0 for fixed parameters
        self.unit = np.where(self.col > 0, self.col, 1.0).reshape(6, -1)
        self.eye = np.eye(self.width) * np.where(free, 0.0, 1.0)[:, None, :]  # fixed: identity rows
        self.p0 = table0
        self.p = np.array(table0)
        t = len(table0)
        r, js = self._evaluate(np.arange(t), self.p)
        self.r, self.js = r.reshape(6 * t, -1), js.reshape(6 * t, *js.shape[2:])
        self.cost = 0.5 * np.sum(self.r**2, axis=1)
        self.g = np.einsum("bjk,bj->bk", self.js, self.r)
        self.h = np.matmul(self.js.transpose(0, 2, 1), self.js) + np.tile(self.eye, (t, 1, 1))

    def _evaluate(self, trials: NDArray[np.intp], p: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        """Residuals ``(k, 6, m)`` and scaled Jacobians ``(k, 6, m, L)`` of trials' legs."""
        r, jac = leg_equations(
            p,
            self.model,
            self.rot[trials],
            self.pos[trials],
            self.readings[trials],
            self.variant,
            legs_first=True,
        )
        return r, jac * self.col[:, :, None, :]

    def floor(self) -> NDArray[np.float64]:
        """Rounding level of each leg's cost ``(6 T,)``."""
        size = np.abs(self.model.length(self.p0[:, None, :, 6:], self.readings))  # (T, m, 6)
        size = np.swapaxes(size**2 if self.variant == "paper" else size, 1, 2)
        return rounding_floor(np.abs(self.r) + size.reshape(self.r.shape), (1,))

    def deviation(self, idx: NDArray[np.intp]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        t, i = np.divmod(idx, 6)
        return (self.p[t, i] - self.p0[t, i]) / self.unit[i] * self.free[i], self.p[t, i] / self.unit[
            i
        ] * self.free[i]

    def trial(self, idx: NDArray[np.intp], dx: NDArray[np.float64]) -> Any:
        t, i = np.divmod(idx, 6)
        trials, where = np.unique(t, return_inverse=True)
        p = self.p[trials]
        p[where, i] += dx * self.col[0, i]
        r, js = self._evaluate(trials, p)
        return _LegTrial(p[where, i], r[where, i], js[where, i])

    def take(self, idx, trial, accept, again) -> None:
        took = idx[accept]
        t, i = np.divmod(took, 6)
        self.p[t, i] = trial.p[accept]
        self.r[took], self.js[took], self.cost[took] = trial.r[accept], trial.js[accept], trial.cost[accept]
        new = idx[again]
        js = self.js[new]
        self.g[new] = np.einsum("bjk,bj->bk", js, self.r[new])
        self.h[new] = np.matmul(js.transpose(0, 2, 1), js) + self.eye[new % 6]


class _LegTrial:
    def __init__(self, p, r, js) -> None:
        self.p, self.r, self.js = p, r, js
        self.cost = 0.5 * np.sum(r**2, axis=1)


def _leg_problems(stack: Stack, variant: str) -> tuple[LegProblems, NDArray[np.intp], NDArray[np.bool_]]:
    """The per-leg problems of a stack at its start values, with the leg columns and their flags."""
    cols = stack.leg_columns()
    free = stack.mask[cols]
    rot, pos, readings = measured_frames(stack)
    model = LegProblems(
        stack.full0[:, cols], rot, pos, readings, free, stack.scales[cols], variant, stack.start.leg_model
    )
    return model, cols, free


def _rank(model: LegProblems, free: NDArray[np.bool_], t: int) -> NDArray[np.intp]:
    h, js = model.h.reshape(t, 6, *model.h.shape[1:]), model.js.reshape(t, 6, *model.js.shape[1:])
    return block_rank(h, free, js)


def leg_rank(stack: Stack) -> NDArray[np.intp]:
    """Rank of each trial's leg Jacobian at its start values (:func:`block_rank`)."""
    model, _, free = _leg_problems(stack, "length")
    return _rank(model, free, len(stack))


def solve_legs(
    stack: Stack,
    variant: str,
    alive: NDArray[np.bool_] | None = None,
    xtol: float = 1e-10,
    max_iter: int = 100,
) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray]:
    """Least squares of the leg residual ``variant`` at the measured poses of every trial of a
    stack (instruments that determine the pose; the instruments' quantities held).

    Returns ``(full (T, N), status (T,), iterations (T,), cost (T,), rank (T,))``: a trial has
    converged when all six of its legs have, its iterations are those of its slowest leg, its
    cost the sum of its legs'; ``alive`` marks the trials to solve.
    """
    t = len(stack)
    alive = np.ones(t, dtype=bool) if alive is None else alive
    mask, full0 = stack.mask, stack.full0
    model, cols, free = _leg_problems(stack, variant)
    rank = _rank(model, free, t)
    status = np.where(alive, STATUS_MAX_ITER, STATUS_NONFINITE)
    status[alive & (rank < mask[stack.machine].sum())] = STATUS_RANK_DEFICIENT
    active = np.repeat(status == STATUS_MAX_ITER, 6)
    legs, iterations = minimise(model, active, model.floor(), xtol, max_iter)
    legs = legs.reshape(t, 6)
    solved = status == STATUS_MAX_ITER
    status[solved] = legs[solved].min(axis=1)  # the worst leg's
    full = np.array(full0)
    full[:, cols] = model.p
    status[(status == STATUS_CONVERGED) & ~np.all(np.isfinite(full), axis=1)] = STATUS_NONFINITE
    return full, status, iterations.reshape(t, 6).max(axis=1), model.cost.reshape(t, 6).sum(axis=1), rank


# -- the whitened legs (generalised least squares) --------------------------------------------
class WhitenedLegs:
    """``T`` problems of whitened leg residuals ``W_j r_j`` at the measured poses (``gls``): the
    :class:`~hexcal.estimation.levenberg.Model` over the machine's parameters in the legs' order
    (leg after leg, each its table's columns; held ones kept at their values by identity rows).

    ``weights`` ``(T, m, 6, 6)``; the start is ``full`` ``(T, N)``. The normal equations use the
    legs' block structure: ``JᵀJ`` has the blocks ``Σ_j A_jiᵀ (WᵀW)_j,ik A_jk`` of legs ``i, k``.
    """

    def __init__(self, stack: Stack, full: NDArray, weights: NDArray, rot, pos, readings) -> None:
        self.stack, self.weights = stack, weights
        self.gram = np.matmul(np.swapaxes(weights, -1, -2), weights)  # WᵀW (T, m, 6, 6)
        self.rot, self.pos, self.readings = rot, pos, readings
        self.leg_cols = stack.leg_columns()  # (6, L)
        free = stack.mask[self.leg_cols]
        self.free = free.ravel()
        self.col = (stack.scales[self.leg_cols] * free).ravel()  # solver units; 0 where held
        self.unit = np.where(self.col > 0, self.col, 1.0)
        self.eye = np.diag(np.where(self.free, 0.0, 1.0))
        self.full = np.array(full)
        t = len(full)
        self.r, self.local = self._evaluate(np.arange(t), self.full)
        self.cost = 0.5 * np.sum(self.r**2, axis=(1, 2))
        self.g, self.h = self._normal(np.arange(t), self.r, self.local)

    def _evaluate(self, trials: NDArray[np.intp], full: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        """Whitened residuals ``(k, m, 6)`` and each leg's scaled Jacobian ``(k, m, 6, L)``."""
        r, local = leg_equations(
            full[:, self.leg_cols],
            self.stack.start.leg_model,
            self.rot[trials],
            self.pos[trials],
            self.readings[trials],
        )
        width = local.shape[-1]
        return np.einsum("tmij,tmj->tmi", self.weights[trials], r), local * self.col.reshape(6, width)

    def _normal(self, trials: NDArray[np.intp], r: NDArray, local: NDArray) -> tuple[NDArray, NDArray]:
        k, m, _, width = local.shape
        gram = self.gram[trials]
        wtr = np.einsum("tmji,tmj->tmi", self.weights[trials], r)  # Wᵀ (W r)
        g = np.einsum("tmic,tmi->tic", local, wtr).reshape(k, 6 * width)
        # (WᵀW)_ik A_k of every pose: (k, 6 i, m, 6 k, L), then A_iᵀ times it, summed over poses
        b = (
            (gram[..., :, :, None] * local[:, :, None, :, :])
            .transpose(0, 2, 1, 3, 4)
            .reshape(k, 6, m, 6 * width)
        )
        h = np.matmul(local.transpose(0, 2, 3, 1), b)  # (k, 6 i, L, 6 k L)
        return g, h.reshape(k, 6 * width, 6 * width) + self.eye

    def floor(self) -> NDArray[np.float64]:
        st = self.stack
        table = st.full0[:, self.leg_cols]
        size = np.abs(st.start.leg_model.length(table[:, None, :, 6:], self.readings))
        return rounding_floor(np.abs(self.r) + np.einsum("tmij,tmj->tmi", np.abs(self.weights), size), (1, 2))

    def deviation(self, idx: NDArray[np.intp]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        full = self.full[idx][:, self.leg_cols].reshape(len(idx), -1)
        start = self.stack.full0[idx][:, self.leg_cols].reshape(len(idx), -1)
        return (full - start) / self.unit * self.free, full / self.unit * self.free

    def trial(self, idx: NDArray[np.intp], dx: NDArray[np.float64]) -> Any:
        full = self.full[idx].copy()
        full[:, self.leg_cols.ravel()] += dx * self.col
        r, local = self._evaluate(idx, full)
        return _WhitenedTrial(full, r, local)

    def take(self, idx, trial, accept, again) -> None:
        took = idx[accept]
        self.full[took], self.r[took], self.local[took] = (
            trial.full[accept],
            trial.r[accept],
            trial.local[accept],
        )
        self.cost[took] = trial.cost[accept]
        new = idx[again]
        if new.size:
            self.g[new], self.h[new] = self._normal(new, self.r[new], self.local[new])


class _WhitenedTrial:
    def __init__(self, full, r, local) -> None:
        self.full, self.r, self.local = full, r, local
        self.cost = 0.5 * np.sum(r**2, axis=(1, 2))


def solve_whitened(
    stack: Stack,
    weights: NDArray[np.float64],
    full: NDArray[np.float64],
    alive: NDArray[np.bool_] | None = None,
    xtol: float = 1e-10,
    max_iter: int = 100,
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Least squares of the whitened leg residuals of every trial from ``full`` ``(T, N)``:
    ``(full, status, iterations, cost)``."""
    rot, pos, readings = measured_frames(stack)
    model = WhitenedLegs(stack, full, weights, rot, pos, readings)
    alive = np.ones(len(stack), dtype=bool) if alive is None else alive
    status, iterations = minimise(model, alive & np.isfinite(model.cost), model.floor(), xtol, max_iter)
    return model.full, status, iterations, model.cost


# -- the estimators -----------------------------------------------------------------------------
def converged_or_raise(status: int, truncate: bool = False) -> None:
    """Refuse, in one line, a solve that did not converge (with ``truncate``, one that ran out of
    iterations counts: a refit that only compares residuals)."""
    if status == STATUS_CONVERGED or (truncate and status == STATUS_MAX_ITER):
        return
    from hexcal.estimation.levenberg import STATUS_MESSAGES

    raise IdentificationError(f"the solver did not converge: {STATUS_MESSAGES[status]}")


def fit_least_squares(
    problem: Problem,
    variant: str = "length",
    xtol: float = 1e-10,
    max_nfev: int | None = None,
    polish: int = 0,
    truncate: bool = False,
) -> IdentificationResult:
    """Least squares of the leg residual ``variant`` at the measured poses (a stack of one for
    :func:`solve_legs`).

    ``max_nfev`` limits the iterations (default 100); with ``truncate`` a solve out of iterations
    keeps its last iterate instead of failing. ``polish`` is accepted for compatibility: the
    solver reaches the optimum within rounding.

    The covariance is ``s² V S⁻² Vᵀ`` from the SVD of the column-normalised Jacobian at the
    solution, with ``s²`` the residual variance ``sum(r²) / (6 m - n)``.
    """
    del polish
    problem.check_size()
    fun, jac = problem.least_squares_functions(variant)
    x0 = np.zeros(problem.n_free)
    problem.check_rank(jac(x0))
    r0 = fun(x0)
    full, status, iterations, cost, _ = solve_legs(
        Stack.of_problem(problem), variant, xtol=xtol, max_iter=100 if max_nfev is None else max_nfev
    )
    converged_or_raise(int(status[0]), truncate)
    x = (full[0, problem.mask] - problem.full0[problem.mask]) / problem.scale
    sol = Convergence(status[0], iterations[0], cost[0])
    return finish_result(problem, variant, full[0], fun(x), jac(x), rms(r0), sol)


def fit_length(problem: Problem, noise: NoiseModel | None = None, **options: Any) -> IdentificationResult:
    """The ``length`` estimator (registry signature; ``noise`` is not used)."""
    return fit_least_squares(problem, "length", **options)


def fit_paper(problem: Problem, noise: NoiseModel | None = None, **options: Any) -> IdentificationResult:
    """The ``paper`` estimator (registry signature; ``noise`` is not used)."""
    return fit_least_squares(problem, "paper", **options)
