"""Batched maximum likelihood (variable projection) of the full-pose measurement: the inner
pose solve on ``(T, m)`` stacks of 6×6 systems and the outer Levenberg–Marquardt on ``(T, n, n)``
stacks with the projected (Kaufman) Jacobian. Used by :func:`hexcal.estimation.batched.estimate_batch`.
"""

from __future__ import annotations

import numpy as np

from hexcal.core.kinematics import pose_jacobian_from_arrays
from hexcal.core.linalg import floored_whitener
from hexcal.core.parameters import N_ALL_PARAMETERS, PARAMETER_SCALE
from hexcal.estimation.batched_solver import (
    GN_LAMBDA,
    LEG_INDEX,
    STATUS_CONVERGED,
    STATUS_MAX_ITER,
    STATUS_NONFINITE,
    acceptable,
    cholesky_lower,
    cholesky_solve,
    damped,
    forward_substitute,
    leg_blocks,
    pose_frames_batch,
    rounding_floor,
    update_damping,
)
from hexcal.estimation.uncertainty import LEG_SIGMA_FLOOR, POSE_VARIANCE_FLOOR

#: Gauss–Newton iterations and relative step tolerance of the inner pose solve (as in
#: :mod:`hexcal.estimation.likelihood`).
_INNER_MAX_ITER = 20
_INNER_TOL = 1e-12
#: A pose step below this (relative) is rounding: the equations before it are final.
_SETTLED = 1e-14
#: Maximum likelihood starts from a ``length`` estimate to this step tolerance, near enough
#: for its outer iteration to start with almost no damping.
ML_START_XTOL, ML_LAMBDA0 = 1e-6, 1e-9


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
        and :meth:`equations` there. Each iteration works on the trials not yet settled."""
        poses = np.array(poses)
        out: list[np.ndarray] = []
        todo = np.arange(len(idx))
        last = np.zeros(len(idx), dtype=bool)  # converged: only the equations at the last step are due
        for _ in range(_INNER_MAX_ITER + 1):
            eqs = self.equations(full[todo], poses[todo], idx[todo])
            if not out:
                out = [np.empty((len(idx), *e.shape[1:])) for e in eqs]
            for whole, part in zip(out, eqs, strict=True):
                whole[todo] = part
            e_leg, e_inst, b_leg, hess = eqs
            step = cholesky_solve(hess, np.einsum("tmki,tmk->tmi", b_leg, e_leg) + e_inst @ self.w)
            size = np.max(np.abs(step), axis=(1, 2))
            scale = 1.0 + np.max(np.abs(poses[todo]), axis=(1, 2))
            # a trial moves on unless its step is below rounding (the equations here are final),
            # not finite, or it converged at the previous step
            moving = np.isfinite(size) & (size >= _SETTLED * scale) & ~last[todo]
            poses[todo[moving]] -= step[moving]
            last[todo[moving]] = size[moving] < _INNER_TOL * scale[moving]
            todo = todo[moving]
            if todo.size == 0:
                break
        return poses, *out


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
    rot, pos = pose_frames_batch(poses, inner.euler)
    _, jac = leg_blocks(full[:, LEG_INDEX], rot, pos, inner.readings[idx].transpose(0, 2, 1), "length")
    js = jac * (PARAMETER_SCALE[LEG_INDEX] / inner.sigma)[:, None, :]  # (k, 6, m, 8)
    lo = cholesky_lower(hess)  # (6, 6, k, m)
    qt = forward_substitute(lo, np.array(b_leg.transpose(3, 2, 0, 1)))  # Qᵀ's leg columns: (6 l, 6 i, k, m)
    bte = np.einsum("tmki,tmk->itm", b_leg, e_leg) + np.einsum("tmk,ki->itm", e_inst, inner.w)
    qte = forward_substitute(lo, bte)  # (6 l, k, m)
    # C[t, (i, c), (j, l)] = A[t, i, j, c] Q[t, j, i, l]: leg i, column c, pose j, basis vector l
    fr = free.reshape(6, 8)
    same = bool((fr == fr[0]).all())  # the same parameters of every leg: select before the product
    a_t = np.ascontiguousarray(js.transpose(0, 1, 3, 2)[:, :, fr[0]] if same else js.transpose(0, 1, 3, 2))
    c = a_t[..., None] * np.ascontiguousarray(qt.transpose(2, 1, 3, 0))[:, :, None]
    c = c.reshape(k, -1, 6 * m) if same else c.reshape(k, N_ALL_PARAMETERS, 6 * m)[:, free]
    h = -np.matmul(c, c.transpose(0, 2, 1))
    g = -np.einsum("tcr,tr->tc", c, qte.transpose(1, 2, 0).reshape(k, -1))
    blocks = np.matmul(js.transpose(0, 1, 3, 2), js)
    ate = np.einsum("tijc,tji->tic", js, e_leg)
    start = 0
    for i in range(6):
        cols = np.flatnonzero(fr[i])
        span = slice(start, start + cols.size)
        h[:, span, span] += blocks[:, i][:, cols][:, :, cols]
        g[:, span] += ate[:, i, cols]
        start += cols.size
    return g, h, js


def solve_ml(full0, full, observed, readings, euler, mask, noise, alive, xtol, max_iter):
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
    floor = rounding_floor(np.abs(eqs[0]) + full[:, None, 36:42] / sigma, (1, 2)) + rounding_floor(
        np.abs(observed @ inner.w.T), (1, 2)
    )
    active = alive & np.isfinite(cost)
    status = np.where(active, STATUS_MAX_ITER, STATUS_NONFINITE)
    iterations = np.zeros(t, dtype=int)
    lam, nu = np.full(t, ML_LAMBDA0), np.full(t, 2.0)
    g, h = np.zeros((t, cols.size)), np.zeros((t, cols.size, cols.size))
    # the leg rows of the parameter Jacobian, the pose Jacobian and bᵀb at the current poses:
    # they predict the poses of the next parameters (the implicit function's derivative)
    js, b_leg, hess = np.zeros((t, 6, poses.shape[1], 8)), eqs[2].copy(), eqs[3].copy()
    idx = np.flatnonzero(active)
    g[idx], h[idx], js[idx] = _ml_normal_equations(
        full[idx], poses[idx], [e[idx] for e in eqs], inner, idx, free
    )
    for _ in range(max_iter):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        gi, hi = g[idx], h[idx]
        dx = -cholesky_solve(damped(hi, lam[idx]), gi)
        x = (full[idx] - full0[idx])[:, cols] / scale
        small = np.linalg.norm(dx, axis=1) <= xtol * (xtol + np.linalg.norm(x, axis=1))
        trial = full[idx].copy()
        trial[:, cols] += dx * scale
        step = np.zeros((idx.size, N_ALL_PARAMETERS))
        step[:, free] = dx
        de = np.einsum("tijc,tic->tji", js[idx], step.reshape(-1, 6, 8))  # change of e_leg, (k, m, 6)
        guess = poses[idx] - cholesky_solve(hess[idx], np.einsum("tmil,tmi->tml", b_leg[idx], de))
        trial_poses, *trial_eqs = inner.solve(trial, guess, idx)
        cost_new = cost_of(trial_eqs)
        predicted = -np.einsum("ti,ti->t", gi, dx) - 0.5 * np.einsum("ti,tij,tj->t", dx, hi, dx)
        gain = (cost[idx] - cost_new) / np.where(predicted > 0, predicted, np.inf)
        accept = acceptable(cost[idx], cost_new, floor[idx])
        iterations[idx] += 1
        lam[idx], nu[idx] = update_damping(lam[idx], nu[idx], accept, gain)
        small &= lam[idx] <= GN_LAMBDA
        took = idx[accept]
        full[took], poses[took], cost[took] = trial[accept], trial_poses[accept], cost_new[accept]
        status[idx[small]] = STATUS_CONVERGED
        active[idx[small]] = False
        again = accept & ~small
        if again.any():
            new = idx[again]
            g[new], h[new], js[new] = _ml_normal_equations(
                trial[again], trial_poses[again], [e[again] for e in trial_eqs], inner, new, free
            )
            b_leg[new], hess[new] = trial_eqs[2][again], trial_eqs[3][again]
    return full, status, iterations, cost
