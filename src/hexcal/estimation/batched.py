"""Batched identification: many independent identifications solved together, vectorised
across trials (Monte Carlo studies).

:func:`estimate_batch` identifies ``T`` data sets of the full-pose measurement (``m`` poses
each, the same ``m`` and parameter mask for all) with the ``paper``, ``length`` or ``ml``
estimator. It gives the optima of :func:`hexcal.estimation.estimate` (``with_bound=False``)
one data set at a time, without a Python loop over trials: the residuals and Jacobians are
evaluated on ``(T, m)`` stacks and every iteration solves a stack of small normal equations.

- ``paper`` and ``length``: each leg's residuals depend only on that leg's parameters
  (``u_i, s_i, l0_i, g_i``), so the normal equations of one data set are block diagonal and
  the problem splits into six independent least-squares problems of at most eight
  parameters. Levenberg–Marquardt runs on the ``(T, 6)`` stack of those problems, with its own
  damping, accept/reject and convergence test for every trial and leg (the same optimum as
  the one solver over all parameters; the path differs).
- ``ml``: variable projection as in :mod:`hexcal.estimation.likelihood`; the inner
  Gauss–Newton pose solve runs on ``(T, m)`` stacks of 6×6 systems, the outer
  Levenberg–Marquardt on ``(T, n, n)`` stacks with the projected (Kaufman) Jacobian, per-trial
  damping, accept/reject and convergence; it starts from the batched ``length`` estimate.

**Tolerance.** An iteration stops when its step (solver units: mm, and 1e-3 for gains) has
``|dx| <= xtol (xtol + |x|)`` with ``x`` the deviation from the start (the criterion of
``scipy.optimize.least_squares``); Gauss–Newton converges quadratically near the optimum, so
the result is then within rounding (about 1e-12 mm) of the optimum, not within ``xtol |x|`` of
it. Two solvers that both iterate to such a step therefore agree to rounding although their
paths differ; compare with the one-at-a-time solver at a tight ``xtol`` (1e-12 or less).

**Failures** do not spoil the other trials: a trial with non-finite input, a rank-deficient
start Jacobian (the rank rule of :mod:`hexcal.core.linalg`, judged as the one-at-a-time
solver does), or no convergence within ``max_iter`` iterations gets NaN values and its
status (:data:`STATUS_MESSAGES`).

>>> from hexcal.core.presets import preset
>>> from hexcal.core.workspace import workspace_corners
>>> from hexcal.estimation.bounds import planned_measurements
>>> nominal, real = preset("paper-hmt"), preset("paper-hmt-true")
>>> data = planned_measurements(real, workspace_corners(nominal)[::4])   # exact, noise-free
>>> batch = estimate_batch(nominal, data.readings[None], data.poses[None], "length")
>>> batch.values.shape, batch.status.tolist()
((1, 42), [1])
>>> round(float(batch.values[0, 0]), 4)    # the real machine's u1.x
305.2599
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.conventions import rotation_matrices
from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import pose_jacobian_from_arrays
from hexcal.core.linalg import RANK_RTOL, floored_whitener
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import (
    MIN_POSES,
    N_ALL_PARAMETERS,
    PARAMETER_NAMES,
    PARAMETER_SCALE,
    select_parameters,
)
from hexcal.errors import IdentificationError, UsageError
from hexcal.estimation.bounds import LEG_SIGMA_FLOOR, POSE_VARIANCE_FLOOR

#: Status of a trial: converged; no convergence within ``max_iter``; rank-deficient start;
#: non-finite input or iterate.
STATUS_CONVERGED, STATUS_MAX_ITER, STATUS_RANK_DEFICIENT, STATUS_NONFINITE = 1, 0, -1, -2
STATUS_MESSAGES = {
    STATUS_CONVERGED: "converged",
    STATUS_MAX_ITER: "not converged: the iteration limit was reached",
    STATUS_RANK_DEFICIENT: "the poses cannot identify all parameters (rank-deficient Jacobian)",
    STATUS_NONFINITE: "non-finite measurements, start values or iterate",
}
#: Estimators :func:`estimate_batch` implements.
BATCH_METHODS = ("paper", "length", "ml")

#: Parameter index of leg ``i``'s block columns ``(u_i, s_i, l0_i, g_i)``, shape (6, 8).
LEG_INDEX = np.array(
    [[3 * i, 3 * i + 1, 3 * i + 2, 18 + 3 * i, 19 + 3 * i, 20 + 3 * i, 36 + i, 42 + i] for i in range(6)]
)
_INNER_MAX_ITER = 20
_INNER_TOL = 1e-12
#: Relative rounding allowed in a cost comparison, and the damping below which a step counts
#: as a Gauss–Newton step for the convergence test.
_COST_ROUNDING, _GN_LAMBDA, _LAMBDA0 = 1e-10, 1e-2, 1e-6
#: Maximum likelihood starts from a ``length`` estimate to this step tolerance, near enough
#: for its outer iteration to start with almost no damping.
_ML_START_XTOL, _ML_LAMBDA0 = 1e-6, 1e-9


@dataclass(frozen=True, eq=False)
class BatchResult:
    """Outcome of :func:`estimate_batch` (arrays over trials).

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
        Numerical rank of the start Jacobian (column-normalised).
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


# -- leg equations on (T, 6, m) stacks -------------------------------------------------------
def leg_blocks(
    params: NDArray[np.float64],
    rot: NDArray[np.float64],
    pos: NDArray[np.float64],
    readings: NDArray[np.float64],
    variant: str,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Leg residuals and their per-leg parameter Jacobian, batched over trials.

    Parameters
    ----------
    params : ndarray, shape (T, 6, 8)
        Each leg's parameters ``(u_i, s_i, l0_i, g_i)`` (``values[:, LEG_INDEX]``).
    rot, pos : ndarray, shape (T, m, 3, 3) and (T, m, 3)
        Rotation matrices and positions of the poses.
    readings : ndarray, shape (T, 6, m)
        Leg readings, leg-major, mm.
    variant : {"length", "paper"}

    Returns
    -------
    r : ndarray, shape (T, 6, m)
        Residuals (mm, or mm² for ``paper``).
    jac : ndarray, shape (T, 6, m, 8)
        ``d r[t, i, j] / d (u_i, s_i, l0_i, g_i)`` in parameter units.
    """
    p = params[..., None]  # (T, 6, 8, 1): broadcasts against poses (T, 1, m)
    r_ = rot[:, None]  # (T, 1, m, 3, 3)
    # v[t, i, j] = R[t, j] s[t, i] + o[t, j] - u[t, i], by components
    v = [
        r_[..., a, 0] * p[:, :, 3]
        + r_[..., a, 1] * p[:, :, 4]
        + r_[..., a, 2] * p[:, :, 5]
        + (pos[:, None, :, a] - p[:, :, a])
        for a in range(3)
    ]
    sq = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    model = p[:, :, 6] + p[:, :, 7] * readings
    jac = np.empty((*sq.shape, 8))
    if variant == "paper":
        r = sq - model**2
        d = [2.0 * c for c in v]
        jac[..., 6] = -2.0 * model
    else:
        length = np.sqrt(sq)
        r = length - model
        inv = 1.0 / length
        d = [c * inv for c in v]
        jac[..., 6] = -1.0
    for a in range(3):
        jac[..., a] = -d[a]
        # (d r / d v) R_j: column b of the rotation
        jac[..., 3 + a] = d[0] * r_[..., 0, a] + d[1] * r_[..., 1, a] + d[2] * r_[..., 2, a]
    jac[..., 7] = jac[..., 6] * readings
    return r, jac


def _frames(poses: NDArray[np.float64], euler: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    return rotation_matrices(poses[..., 3:], euler), np.ascontiguousarray(poses[..., :3])


def _cholesky(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Lower Cholesky factors of a stack ``(..., n, n)``, returned as ``(n, n, ...)`` (row, column,
    stack), vectorised over the stack (a loop over ``n``). A member that is not numerically
    positive definite gets NaN, and no exception, so that one bad trial cannot stop the others."""
    n = a.shape[-1]
    lo = np.ascontiguousarray(np.moveaxis(a, (-2, -1), (0, 1)))
    with np.errstate(invalid="ignore", divide="ignore"):
        for j in range(n):
            row = lo[j, :j]
            d = np.sqrt(lo[j, j] - np.einsum("k...,k...->...", row, row))
            lo[j, j] = d
            if j + 1 < n:
                lo[j + 1 :, j] = (lo[j + 1 :, j] - np.einsum("ik...,k...->i...", lo[j + 1 :, :j], row)) / d
    return lo


def _forward(lo: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    """``L⁻¹ y`` for factors of :func:`_cholesky` and ``y`` of shape ``(n, ...)``, in place."""
    with np.errstate(invalid="ignore", divide="ignore"):
        for j in range(lo.shape[0]):
            y[j] = (y[j] - np.einsum("k...,k...->...", lo[j, :j], y[:j])) / lo[j, j]
    return y


def _chol_solve(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """``a⁻¹ b`` for stacks ``(..., n, n)`` of symmetric positive definite systems and ``b``
    ``(..., n)`` (:func:`_cholesky`; NaN for a member that is not positive definite)."""
    lo = _cholesky(a)
    y = _forward(lo, np.array(np.moveaxis(b, -1, 0)))
    with np.errstate(invalid="ignore", divide="ignore"):
        for j in range(lo.shape[0] - 1, -1, -1):
            y[j] = (y[j] - np.einsum("k...,k...->...", lo[j + 1 :, j], y[j + 1 :])) / lo[j, j]
    return np.moveaxis(y, 0, -1)


def _damped(h: NDArray[np.float64], lam: NDArray[np.float64]) -> NDArray[np.float64]:
    """``H + λ diag(H)`` (Marquardt's scaling; the diagonal floored to stay positive)."""
    diag = np.diagonal(h, axis1=-2, axis2=-1)
    floor = 1e-12 * np.max(diag, axis=-1, keepdims=True) + 1e-300
    out = h.copy()
    idx = np.arange(h.shape[-1])
    out[..., idx, idx] += lam[..., None] * np.maximum(diag, floor)
    return out


def _update_damping(lam, nu, accept, gain):
    """Nielsen's rule (shrinking at most tenfold): shrink ``λ`` after a good step, double the
    growth after a bad one."""
    shrink = np.maximum(0.1, 1.0 - (2.0 * np.clip(gain, 0.0, 1.0) - 1.0) ** 3)
    lam = np.where(accept, np.maximum(lam * shrink, 1e-15), np.minimum(lam * nu, 1e20))
    nu = np.where(accept, 2.0, nu * 2.0)
    return lam, nu


def _acceptable(cost: NDArray, cost_new: NDArray, floor: NDArray) -> NDArray[np.bool_]:
    """A step is taken when it does not raise the cost beyond the rounding of the sum of squares
    (relative, or ``floor`` from the size of the terms that cancel in the residuals): near the
    optimum the cost cannot tell steps apart; the gradient, and so Gauss–Newton, can."""
    return np.isfinite(cost_new) & (cost_new <= cost * (1.0 + _COST_ROUNDING) + floor)


def _floor(magnitude: NDArray[np.float64], axes: tuple[int, ...]) -> NDArray[np.float64]:
    """Rounding level of ``0.5 sum(r²)`` for residuals that are differences of terms of size
    ``magnitude``."""
    return 0.5 * np.sum((64 * np.finfo(float).eps * magnitude) ** 2, axis=axes)


# -- the leg-separable estimators ------------------------------------------------------------
def _block_rank(h: NDArray[np.float64], free: NDArray[np.bool_], js: NDArray[np.float64]) -> NDArray:
    """Rank of each trial's column-normalised Jacobian (union of its legs' singular values).

    A cheap sound screen first: with ``H`` the normalised Gram matrix of a leg (unit diagonal),
    ``λ_min(H) >= 1 / trace(H⁻¹)``; trials whose every leg clears ``1e-12`` (far above the
    rank rule's ``RANK_RTOL² ≈ 1e-16`` of ``λ_max <= 8``) have full rank. The others get the
    exact SVD rule.
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


def _solve_legs(
    full0: NDArray[np.float64],
    rot: NDArray[np.float64],
    pos: NDArray[np.float64],
    readings: NDArray[np.float64],
    mask: NDArray[np.bool_],
    variant: str,
    alive: NDArray[np.bool_],
    xtol: float,
    max_iter: int,
) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray]:
    """Levenberg–Marquardt on the ``(T, 6)`` stack of per-leg problems.

    Returns ``(full, status, iterations, cost, rank)``; ``alive`` marks trials to solve.
    """
    t = full0.shape[0]
    free = mask[LEG_INDEX]
    col = PARAMETER_SCALE[LEG_INDEX] * free  # solver units; 0 for fixed parameters
    eye = np.eye(8) * np.where(free, 0.0, 1.0)[:, None, :]  # fixed parameters: identity rows
    p0 = full0[:, LEG_INDEX]
    p = p0.copy()
    r, jac = leg_blocks(p, rot, pos, readings, variant)
    js = jac * col[:, None, :]
    h = np.matmul(js.transpose(0, 1, 3, 2), js) + eye
    rank = _block_rank(h, free, js)
    status = np.where(alive, STATUS_MAX_ITER, STATUS_NONFINITE)
    status[alive & (rank < mask.sum())] = STATUS_RANK_DEFICIENT
    active = np.repeat((status == STATUS_MAX_ITER)[:, None], 6, axis=1)
    done = np.zeros((t, 6), dtype=bool)
    iterations = np.zeros((t, 6), dtype=int)
    lam, nu = np.full((t, 6), _LAMBDA0), np.full((t, 6), 2.0)
    cost = 0.5 * np.sum(r**2, axis=2)
    size = np.abs(p0[..., 6:7]) + np.abs(p0[..., 7:8] * readings)
    floor = _floor(np.abs(r) + (size**2 if variant == "paper" else size), (2,))
    unit = np.where(col > 0, col, 1.0)
    for _ in range(max_iter):
        if not active.any():
            break
        g = np.einsum("tijk,tij->tik", js, r)
        g[~active], h[~active] = 0.0, np.eye(8)
        dx = -_chol_solve(_damped(h, lam), g)
        x = (p - p0) / unit * free
        small = np.linalg.norm(dx, axis=2) <= xtol * (xtol + np.linalg.norm(x, axis=2))
        p_new = p + dx * col
        r_new, jac_new = leg_blocks(p_new, rot, pos, readings, variant)
        cost_new = 0.5 * np.sum(r_new**2, axis=2)
        predicted = -np.einsum("tik,tik->ti", g, dx) - 0.5 * np.einsum("tik,tikl,til->ti", dx, h, dx)
        gain = (cost - cost_new) / np.where(predicted > 0, predicted, np.inf)
        accept = active & _acceptable(cost, cost_new, floor)
        iterations += active
        lam, nu = _update_damping(lam, nu, accept, gain)
        small &= lam <= _GN_LAMBDA
        p = np.where(accept[..., None], p_new, p)
        r = np.where(accept[..., None], r_new, r)
        js = np.where(accept[..., None, None], jac_new * col[:, None, :], js)
        cost = np.where(accept, cost_new, cost)
        done |= active & small
        active &= ~small
        h = np.matmul(js.transpose(0, 1, 3, 2), js) + eye
    full = full0.copy()
    full[:, LEG_INDEX] = p
    status[(status == STATUS_MAX_ITER) & done.all(axis=1)] = STATUS_CONVERGED
    status[(status == STATUS_CONVERGED) & ~np.all(np.isfinite(full), axis=1)] = STATUS_NONFINITE
    return full, status, iterations.max(axis=1), cost.sum(axis=1), rank


# -- maximum likelihood ----------------------------------------------------------------------
class _Poses:
    """The inner problem of variable projection on ``(T, m)`` stacks: true poses for given
    parameters (whitened leg and pose-instrument equations of the full-pose model)."""

    def __init__(self, observed, readings, euler, sigma, whitener) -> None:
        self.y, self.readings, self.euler = observed, readings, euler
        self.sigma, self.w = sigma, whitener
        self.wtw = whitener.T @ whitener

    def equations(self, full, poses, idx):
        """Leg and instrument errors ``(k, m, 6)`` each, the leg rows of the pose Jacobian
        ``(k, m, 6, 6)`` (the instrument rows are the whitener) and ``bᵀb``, for trials ``idx``."""
        t = full.shape[0]
        u, s = full[:, None, :18].reshape(t, 1, 6, 3), full[:, None, 18:36].reshape(t, 1, 6, 3)
        lengths, jp = pose_jacobian_from_arrays(u, s, poses, self.euler)
        model = full[:, None, 36:42] + full[:, None, 42:48] * self.readings[idx]
        e_leg = (lengths - model) / self.sigma
        e_inst = (poses - self.y[idx]) @ self.w.T
        b_leg = jp / self.sigma
        hess = np.matmul(b_leg.transpose(0, 1, 3, 2), b_leg) + self.wtw
        return e_leg, e_inst, b_leg, hess

    def solve(self, full, poses, idx):
        """Gauss–Newton over every pose of trials ``idx``, warm-started at ``poses``: the poses
        and :meth:`equations` there."""
        poses = poses.copy()
        for _ in range(_INNER_MAX_ITER):
            eqs = self.equations(full, poses, idx)
            e_leg, e_inst, b_leg, hess = eqs
            step = _chol_solve(hess, np.einsum("tmki,tmk->tmi", b_leg, e_leg) + e_inst @ self.w)
            size = np.max(np.abs(step), axis=(1, 2))
            scale = 1.0 + np.max(np.abs(poses), axis=(1, 2))
            settled = ~np.isfinite(size)
            if np.all(settled | (size < 1e-4 * _INNER_TOL * scale)):
                return poses, *eqs  # the step is below rounding: the equations here are final
            poses = poses - step
            if np.all(settled | (size < _INNER_TOL * scale)):
                break
        return poses, *self.equations(full, poses, idx)


def _ml_normal_equations(full, poses, eqs, inner, idx, free):
    """Gradient ``(k, n)`` and Gauss–Newton matrix ``(k, n, n)`` of the projected problem for
    trials ``idx``, in the variables ``full[:, LEG_INDEX.ravel()[free]]`` (solver units).

    ``Jᵀ J = Aᵀ A - Cᵀ C`` with ``A`` the leg rows of the parameter Jacobian (block diagonal over
    legs) and ``C = Qᵀ A``, ``Q = b L⁻ᵀ`` (``L`` the Cholesky factor of each pose's ``bᵀb``) an
    orthonormal basis of the pose Jacobian; the gradient is ``Aᵀ e_leg - Cᵀ Qᵀ e`` with
    ``Qᵀ e = L⁻¹ bᵀ e``.
    """
    e_leg, e_inst, b_leg, hess = eqs
    k, m = poses.shape[:2]
    rot, pos = _frames(poses, inner.euler)
    _, jac = leg_blocks(full[:, LEG_INDEX], rot, pos, inner.readings[idx].transpose(0, 2, 1), "length")
    js = jac * (PARAMETER_SCALE[LEG_INDEX] / inner.sigma)[:, None, :]  # (k, 6, m, 8)
    lo = _cholesky(hess)  # (6, 6, k, m)
    qt = _forward(lo, np.array(b_leg.transpose(3, 2, 0, 1)))  # Qᵀ's leg columns: (6 l, 6 i, k, m)
    bte = np.einsum("tmki,tmk->itm", b_leg, e_leg) + np.einsum("tmk,ki->itm", e_inst, inner.w)
    qte = _forward(lo, bte)  # (6 l, k, m)
    # C[t, (i, c), (j, l)] = A[t, i, j, c] Q[t, j, i, l]: leg i, column c, pose j, basis vector l
    c = js.transpose(0, 1, 3, 2)[..., None] * qt.transpose(2, 1, 3, 0)[:, :, None]
    c = c.reshape(k, N_ALL_PARAMETERS, 6 * m)[:, free]
    h = -np.matmul(c, c.transpose(0, 2, 1))
    g = -np.einsum("tcr,tr->tc", c, qte.transpose(1, 2, 0).reshape(k, -1))
    blocks = np.matmul(js.transpose(0, 1, 3, 2), js)
    ate = np.einsum("tijc,tji->tic", js, e_leg)
    fr = free.reshape(6, 8)
    start = 0
    for i in range(6):
        cols = np.flatnonzero(fr[i])
        span = slice(start, start + cols.size)
        h[:, span, span] += blocks[:, i][:, cols][:, :, cols]
        g[:, span] += ate[:, i, cols]
        start += cols.size
    return g, h


def _solve_ml(full0, full, observed, readings, euler, mask, noise, alive, xtol, max_iter):
    """Outer Levenberg–Marquardt of maximum likelihood from ``full`` (the ``length`` estimate),
    each iteration on the trials still active."""
    t = full.shape[0]
    sigma = max(noise.sigmas[0], LEG_SIGMA_FLOOR)
    inner = _Poses(observed, readings, euler, sigma, floored_whitener(noise.pose_cov(), POSE_VARIANCE_FLOOR))
    perm = LEG_INDEX.ravel()
    free = mask[perm]
    cols = perm[free]
    scale = PARAMETER_SCALE[cols]
    everyone = np.arange(t)
    poses, *eqs = inner.solve(full, observed, everyone)

    def cost_of(eq):
        return 0.5 * (np.sum(eq[0] ** 2, axis=(1, 2)) + np.sum(eq[1] ** 2, axis=(1, 2)))

    cost = cost_of(eqs)
    floor = _floor(np.abs(eqs[0]) + full[:, None, 36:42] / sigma, (1, 2)) + _floor(
        np.abs(observed @ inner.w.T), (1, 2)
    )
    active = alive & np.isfinite(cost)
    status = np.where(active, STATUS_MAX_ITER, STATUS_NONFINITE)
    iterations = np.zeros(t, dtype=int)
    lam, nu = np.full(t, _ML_LAMBDA0), np.full(t, 2.0)
    g, h = np.zeros((t, cols.size)), np.zeros((t, cols.size, cols.size))
    idx = np.flatnonzero(active)
    g[idx], h[idx] = _ml_normal_equations(full[idx], poses[idx], [e[idx] for e in eqs], inner, idx, free)
    for _ in range(max_iter):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        gi, hi = g[idx], h[idx]
        dx = -_chol_solve(_damped(hi, lam[idx]), gi)
        x = (full[idx] - full0[idx])[:, cols] / scale
        small = np.linalg.norm(dx, axis=1) <= xtol * (xtol + np.linalg.norm(x, axis=1))
        trial = full[idx].copy()
        trial[:, cols] += dx * scale
        trial_poses, *trial_eqs = inner.solve(trial, poses[idx], idx)
        cost_new = cost_of(trial_eqs)
        predicted = -np.einsum("ti,ti->t", gi, dx) - 0.5 * np.einsum("ti,tij,tj->t", dx, hi, dx)
        gain = (cost[idx] - cost_new) / np.where(predicted > 0, predicted, np.inf)
        accept = _acceptable(cost[idx], cost_new, floor[idx])
        iterations[idx] += 1
        lam[idx], nu[idx] = _update_damping(lam[idx], nu[idx], accept, gain)
        small &= lam[idx] <= _GN_LAMBDA
        took = idx[accept]
        full[took], poses[took], cost[took] = trial[accept], trial_poses[accept], cost_new[accept]
        status[idx[small]] = STATUS_CONVERGED
        active[idx[small]] = False
        again = accept & ~small
        if again.any():
            g[idx[again]], h[idx[again]] = _ml_normal_equations(
                trial[again], trial_poses[again], [e[again] for e in trial_eqs], inner, idx[again], free
            )
    return full, status, iterations, cost


# -- entry points ----------------------------------------------------------------------------
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
) -> BatchResult:
    """Identify ``T`` full-pose data sets at once (see the module notes).

    Parameters
    ----------
    start : Geometry
        Start values (the nominal geometry) and Euler convention, shared by the trials.
    readings : array_like, shape (T, m, 6)
        Leg readings of every trial, mm.
    poses : array_like, shape (T, m, 6)
        Measured poses of every trial, mm and rad.
    method : {"paper", "length", "ml"}
    mask : array_like of bool, shape (48,), optional
        Varied machine parameters (default joints and ``l0``).
    noise : NoiseModel, optional
        The noise model ``ml`` assumes (default the seed paper's).
    starts : array_like, shape (T, 48), optional
        Per-trial start values of the 48 machine parameters, replacing ``start``'s.
    xtol : float
        Step tolerance, solver units (module notes).
    max_iter : int
        Levenberg–Marquardt iterations per trial (and per leg for ``paper``/``length``).

    Returns
    -------
    BatchResult
    """
    if method not in BATCH_METHODS:
        raise UsageError(f"unknown batched method {method!r}; choose from {', '.join(BATCH_METHODS)}")
    readings = np.array(readings, dtype=float)
    poses = np.array(poses, dtype=float)
    if poses.ndim != 3 or poses.shape[-1] != 6 or readings.shape != poses.shape:
        raise UsageError(
            f"readings and poses must both have shape (T, m, 6), got {readings.shape}, {poses.shape}"
        )
    t, m = poses.shape[:2]
    mask = np.asarray(select_parameters() if mask is None else mask, dtype=bool)
    if mask.shape != (N_ALL_PARAMETERS,):
        raise UsageError(f"mask must have shape (48,), got {mask.shape}")
    min_poses = MIN_POSES + (1 if mask[42:].any() else 0)
    if m < min_poses or 6 * m < mask.sum():
        raise IdentificationError(
            f"{m} poses cannot determine the parameters: at least {min_poses} are needed"
        )
    full0 = np.broadcast_to(
        start.to_vector(gains=True) if starts is None else np.asarray(starts, float), (t, 48)
    )
    full0 = np.array(full0)
    alive = np.all(np.isfinite(full0), axis=1) & np.all(np.isfinite(readings), axis=(1, 2))
    alive &= np.all(np.isfinite(poses), axis=(1, 2))
    # dead trials get harmless stand-in data so that no stacked solve sees NaN
    stand_in = int(np.argmax(alive)) if alive.any() else None
    if stand_in is not None:
        full0[~alive], readings[~alive], poses[~alive] = full0[stand_in], readings[stand_in], poses[stand_in]
    rot, pos = _frames(poses, start.euler)
    noise = NoiseModel() if noise is None else noise
    ml = method == "ml" and noise.has_pose_noise
    full, status, iterations, cost, rank = _solve_legs(
        full0,
        rot,
        pos,
        readings.transpose(0, 2, 1),
        mask,
        "paper" if method == "paper" else "length",
        alive,
        _ML_START_XTOL if ml else xtol,
        max_iter,
    )
    if ml:
        ok = status == STATUS_CONVERGED
        full, ml_status, ml_iterations, cost = _solve_ml(
            full0, full, poses, readings, start.euler, mask, noise, ok, xtol, max_iter
        )
        status = np.where(ok, ml_status, status)
        iterations = iterations + ml_iterations
    failed = status != STATUS_CONVERGED
    values = full[:, mask]
    values[failed] = np.nan
    cost = np.where(failed, np.nan, cost)
    names = tuple(np.asarray(PARAMETER_NAMES)[mask].tolist())
    return BatchResult(method, names, values, status, iterations, cost, rank)


def identify_chunk(
    start: Geometry,
    readings: ArrayLike,
    poses: ArrayLike,
    methods: tuple[str, ...] = ("paper",),
    mask: ArrayLike | None = None,
    noise: NoiseModel | None = None,
) -> dict[str, NDArray[np.float64]]:
    """Identified values ``(T, n)`` of a chunk of simulated trials by each method (NaN rows
    where an identification failed): the unit of work of a study's executor."""
    return {name: estimate_batch(start, readings, poses, name, mask, noise).values for name in methods}
