"""Kernels of batched identification (:mod:`hexcal.estimation.batched`): the leg equations on
``(T, 6, m)`` stacks for any leg model, a Cholesky solver vectorised over stacks of small
systems, the Levenberg–Marquardt bookkeeping shared by the batched estimators (damping,
accept/reject with a rounding allowance) and the solver of the leg-separable ``paper`` and
``length`` problems.

Each leg's residuals depend only on that leg's parameters: its base and platform joints and its
leg-model parameters, the columns :func:`hexcal.core.machine.leg_columns` of the machine's
parameters (``L`` of them per leg: 8 for linear legs).

Imports :mod:`hexcal.core` only.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hexcal.core.conventions import rotation_matrices
from hexcal.core.legs import LegModel
from hexcal.core.linalg import RANK_RTOL

#: Status of a trial: converged; no convergence within ``max_iter``; rank-deficient start;
#: non-finite input or iterate.
STATUS_CONVERGED, STATUS_MAX_ITER, STATUS_RANK_DEFICIENT, STATUS_NONFINITE = 1, 0, -1, -2
STATUS_MESSAGES = {
    STATUS_CONVERGED: "converged",
    STATUS_MAX_ITER: "not converged: the iteration limit was reached",
    STATUS_RANK_DEFICIENT: "the poses cannot identify all parameters (rank-deficient Jacobian)",
    STATUS_NONFINITE: "non-finite measurements, start values or iterate",
}

#: Relative rounding allowed in a cost comparison, and the damping below which a step counts
#: as a Gauss–Newton step for the convergence test.
COST_ROUNDING, GN_LAMBDA, LAMBDA0 = 1e-10, 1e-2, 1e-6


# -- leg equations on (T, 6, m) stacks -------------------------------------------------------
def leg_blocks(
    params: NDArray[np.float64],
    rot: NDArray[np.float64],
    pos: NDArray[np.float64],
    readings: NDArray[np.float64],
    variant: str,
    model: LegModel,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Leg residuals and their per-leg parameter Jacobian, batched over trials.

    Parameters
    ----------
    params : ndarray, shape (T, 6, L)
        Each leg's parameters: base joint, platform joint, then its leg-model parameters
        (``values[:, leg_columns(model)]``).
    rot, pos : ndarray, shape (T, m, 3, 3) and (T, m, 3)
        Rotation matrices and positions of the poses.
    readings : ndarray, shape (T, 6, m)
        Leg readings, leg-major.
    variant : {"length", "paper"}
    model : LegModel

    Returns
    -------
    r : ndarray, shape (T, 6, m)
        Residuals (mm, or mm² for ``paper``).
    jac : ndarray, shape (T, 6, m, L)
        ``d r[t, i, j] / d params[t, i]`` in parameter units.
    """
    p = params[..., None]  # (T, 6, L, 1): broadcasts against poses (T, 1, m)
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
    # the leg model's per-leg functions take the leg axis last (its settings may be per leg)
    theta, by_pose = params[:, None, :, 6:], np.swapaxes(readings, -1, -2)  # (T, 1, 6, q), (T, m, 6)
    lengths = np.swapaxes(model.length(theta, by_pose), -1, -2)
    dmodel = np.swapaxes(model.length_jacobian(theta, by_pose), 1, 2)  # (T, 6, m, q)
    jac = np.empty((*sq.shape, params.shape[-1]))
    if variant == "paper":
        r = sq - lengths**2
        d = [2.0 * c for c in v]
        jac[..., 6:] = (-2.0 * lengths)[..., None] * dmodel
    else:
        length = np.sqrt(sq)
        r = length - lengths
        inv = 1.0 / length
        d = [c * inv for c in v]
        jac[..., 6:] = -dmodel
    for a in range(3):
        jac[..., a] = -d[a]
        # (d r / d v) R_j: column b of the rotation
        jac[..., 3 + a] = d[0] * r_[..., 0, a] + d[1] * r_[..., 1, a] + d[2] * r_[..., 2, a]
    return r, jac


def pose_frames_batch(
    poses: NDArray[np.float64], euler: str
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rotation matrices ``(..., 3, 3)`` and positions ``(..., 3)`` of poses ``(..., 6)``."""
    return rotation_matrices(poses[..., 3:], euler), np.ascontiguousarray(poses[..., :3])


def cholesky_lower(a: NDArray[np.float64]) -> NDArray[np.float64]:
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


def forward_substitute(lo: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    """``L⁻¹ y`` for factors of :func:`cholesky_lower` and ``y`` of shape ``(n, ...)``, in place."""
    with np.errstate(invalid="ignore", divide="ignore"):
        for j in range(lo.shape[0]):
            y[j] = (y[j] - np.einsum("k...,k...->...", lo[j, :j], y[:j])) / lo[j, j]
    return y


def cholesky_solve(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """``a⁻¹ b`` for stacks ``(..., n, n)`` of symmetric positive definite systems and ``b``
    ``(..., n)`` (:func:`cholesky_lower`; NaN for a member that is not positive definite)."""
    lo = cholesky_lower(a)
    y = forward_substitute(lo, np.array(np.moveaxis(b, -1, 0)))
    with np.errstate(invalid="ignore", divide="ignore"):
        for j in range(lo.shape[0] - 1, -1, -1):
            y[j] = (y[j] - np.einsum("k...,k...->...", lo[j + 1 :, j], y[j + 1 :])) / lo[j, j]
    return np.moveaxis(y, 0, -1)


def damped(h: NDArray[np.float64], lam: NDArray[np.float64]) -> NDArray[np.float64]:
    """``H + λ diag(H)`` (Marquardt's scaling; the diagonal floored to stay positive)."""
    diag = np.diagonal(h, axis1=-2, axis2=-1)
    floor = 1e-12 * np.max(diag, axis=-1, keepdims=True) + 1e-300
    out = h.copy()
    idx = np.arange(h.shape[-1])
    out[..., idx, idx] += lam[..., None] * np.maximum(diag, floor)
    return out


def update_damping(lam, nu, accept, gain):
    """Nielsen's rule (shrinking at most tenfold): shrink ``λ`` after a good step, double the
    growth after a bad one."""
    shrink = np.maximum(0.1, 1.0 - (2.0 * np.clip(gain, 0.0, 1.0) - 1.0) ** 3)
    lam = np.where(accept, np.maximum(lam * shrink, 1e-15), np.minimum(lam * nu, 1e20))
    nu = np.where(accept, 2.0, nu * 2.0)
    return lam, nu


def acceptable(cost: NDArray, cost_new: NDArray, floor: NDArray) -> NDArray[np.bool_]:
    """A step is taken when it does not raise the cost beyond the rounding of the sum of squares
    (relative, or ``floor`` from the size of the terms that cancel in the residuals): near the
    optimum the cost cannot tell steps apart; the gradient, and so Gauss–Newton, can."""
    return np.isfinite(cost_new) & (cost_new <= cost * (1.0 + COST_ROUNDING) + floor)


def rounding_floor(magnitude: NDArray[np.float64], axes: tuple[int, ...]) -> NDArray[np.float64]:
    """Rounding level of ``0.5 sum(r²)`` for residuals that are differences of terms of size
    ``magnitude``."""
    return 0.5 * np.sum((64 * np.finfo(float).eps * magnitude) ** 2, axis=axes)


# -- the leg-separable estimators ------------------------------------------------------------
def block_rank(h: NDArray[np.float64], free: NDArray[np.bool_], js: NDArray[np.float64]) -> NDArray:
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


def solve_legs(
    full0: NDArray[np.float64],
    rot: NDArray[np.float64],
    pos: NDArray[np.float64],
    readings: NDArray[np.float64],
    mask: NDArray[np.bool_],
    variant: str,
    alive: NDArray[np.bool_],
    xtol: float,
    max_iter: int,
    model: LegModel,
    cols: NDArray[np.intp],
    scales: NDArray[np.float64],
) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray]:
    """Levenberg–Marquardt on the ``(T, 6)`` stack of per-leg problems.

    ``full0`` ``(T, P)`` machine start values, ``mask`` ``(P,)`` the varied ones, ``cols`` the
    leg columns ``(6, L)`` and ``scales`` ``(P,)`` the solver scales. Returns ``(full, status,
    iterations, cost, rank)``; ``alive`` marks trials to solve.
    """
    t = full0.shape[0]
    width = cols.shape[1]
    free = mask[cols]
    col = scales[cols] * free  # solver units; 0 for fixed parameters
    eye = np.eye(width) * np.where(free, 0.0, 1.0)[:, None, :]  # fixed parameters: identity rows
    p0 = full0[:, cols]
    p = p0.copy()
    r, jac = leg_blocks(p, rot, pos, readings, variant, model)
    js = jac * col[:, None, :]
    h = np.matmul(js.transpose(0, 1, 3, 2), js) + eye
    rank = block_rank(h, free, js)
    status = np.where(alive, STATUS_MAX_ITER, STATUS_NONFINITE)
    status[alive & (rank < mask.sum())] = STATUS_RANK_DEFICIENT
    active = np.repeat((status == STATUS_MAX_ITER)[:, None], 6, axis=1)
    done = np.zeros((t, 6), dtype=bool)
    iterations = np.zeros((t, 6), dtype=int)
    lam, nu = np.full((t, 6), LAMBDA0), np.full((t, 6), 2.0)
    cost = 0.5 * np.sum(r**2, axis=2)
    size = np.abs(np.swapaxes(model.length(p0[:, None, :, 6:], np.swapaxes(readings, -1, -2)), -1, -2))
    floor = rounding_floor(np.abs(r) + (size**2 if variant == "paper" else size), (2,))
    unit = np.where(col > 0, col, 1.0)
    for _ in range(max_iter):
        if not active.any():
            break
        g = np.einsum("tijk,tij->tik", js, r)
        g[~active], h[~active] = 0.0, np.eye(width)
        dx = -cholesky_solve(damped(h, lam), g)
        x = (p - p0) / unit * free
        small = np.linalg.norm(dx, axis=2) <= xtol * (xtol + np.linalg.norm(x, axis=2))
        p_new = p + dx * col
        r_new, jac_new = leg_blocks(p_new, rot, pos, readings, variant, model)
        cost_new = 0.5 * np.sum(r_new**2, axis=2)
        predicted = -np.einsum("tik,tik->ti", g, dx) - 0.5 * np.einsum("tik,tikl,til->ti", dx, h, dx)
        gain = (cost - cost_new) / np.where(predicted > 0, predicted, np.inf)
        accept = active & acceptable(cost, cost_new, floor)
        iterations += active
        lam, nu = update_damping(lam, nu, accept, gain)
        small &= lam <= GN_LAMBDA
        p = np.where(accept[..., None], p_new, p)
        r = np.where(accept[..., None], r_new, r)
        js = np.where(accept[..., None, None], jac_new * col[:, None, :], js)
        cost = np.where(accept, cost_new, cost)
        done |= active & small
        active &= ~small
        h = np.matmul(js.transpose(0, 1, 3, 2), js) + eye
    full = full0.copy()
    full[:, cols] = p
    status[(status == STATUS_MAX_ITER) & done.all(axis=1)] = STATUS_CONVERGED
    status[(status == STATUS_CONVERGED) & ~np.all(np.isfinite(full), axis=1)] = STATUS_NONFINITE
    return full, status, iterations.max(axis=1), cost.sum(axis=1), rank
