"""Batched maximum likelihood (variable projection) of a :class:`~hexcal.estimation.stacked.Stack`:
the inner pose solve on ``(T, m)`` stacks of 6×6 systems and the outer Levenberg–Marquardt on
``(T, n, n)`` stacks with the projected (Kaufman) Jacobian, for any instrument and leg model.
Used by :func:`hexcal.estimation.batched.estimate_stack`.

The equations are those of :meth:`hexcal.estimation.problem.Problem.observation_equations`:
per observation the six whitened leg residuals (the leg model's lengths) and the instrument's
whitened residuals ``W r(θ_s, P, y)`` (masked where a value is missing). The parameter Jacobian
has the leg rows, block diagonal over legs in each leg's own columns, and the instrument rows in
the instrument's free quantities (none for the full pose); the normal equations exploit both.
With gauge freedoms (an instrument in its own frame) each trial moves only in the directions
orthogonal to its gauges, and ends under the gauge convention.
"""

from __future__ import annotations

import numpy as np

from hexcal.core.kinematics import pose_jacobian_from_arrays
from hexcal.core.linalg import floored_whitener
from hexcal.estimation.batched_solver import (
    GN_LAMBDA,
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
from hexcal.estimation.gauge import apply_convention, complement_basis
from hexcal.estimation.uncertainty import LEG_SIGMA_FLOOR, POSE_VARIANCE_FLOOR

#: Gauss–Newton iterations and relative step tolerance of the inner pose solve (as in
#: :mod:`hexcal.estimation.likelihood`).
_INNER_MAX_ITER = 20
_INNER_TOL = 1e-12
#: A pose step below this (relative) is rounding: the equations before it are final.
_SETTLED = 1e-14
#: Maximum likelihood starts from a ``length`` estimate to this step tolerance, near enough
#: for its outer iteration to start with almost no damping; from the start values (an
#: instrument that does not give the pose) it starts damped.
ML_START_XTOL, ML_LAMBDA0, ML_LAMBDA_COLD = 1e-6, 1e-9, 1e-3


class _Poses:
    """The inner problem of variable projection on ``(T, m)`` stacks: true poses for given
    parameters (whitened leg and instrument equations)."""

    def __init__(self, stack, sigma, whitener) -> None:
        self.stack, self.euler = stack, stack.euler
        self.y, self.present, self.readings = stack.observed, stack.present, stack.readings
        self.model, self.instrument = stack.start.leg_model, stack.instrument
        self.sigma, self.w = sigma, whitener
        self.wtw = whitener.T @ whitener
        # the full pose: the instrument rows of the pose Jacobian are the whitener itself
        self.constant = stack.instrument.constant_pose_jacobian and bool(stack.present.all())

    def equations(self, full, poses, idx):
        """Leg errors ``(k, m, 6)``, instrument errors ``(k, m, K)``, the leg and instrument rows
        of the pose Jacobian (``None`` for the instrument when they are the whitener) and
        ``bᵀb``, for trials ``idx``."""
        t, st = full.shape[0], self.stack
        joints = full[:, st.joints]
        u, s = joints[:, None, :18].reshape(t, 1, 6, 3), joints[:, None, 18:36].reshape(t, 1, 6, 3)
        lengths, jp = pose_jacobian_from_arrays(u, s, poses, self.euler)
        model = self.model.lengths(full[:, None, st.legs], self.readings[idx])
        e_leg = (lengths - model) / self.sigma
        b_leg = jp / self.sigma
        leg_hess = np.matmul(b_leg.transpose(0, 1, 3, 2), b_leg)
        if self.constant:
            return e_leg, (poses - self.y[idx]) @ self.w.T, b_leg, None, leg_hess + self.wtw
        present = self.present[idx]
        setup = full[:, st.setup]
        r = np.where(present, self.instrument.residual(setup, poses, self.euler, self.y[idx]), 0.0)
        dh = self.instrument.whitened_pose_jacobian(setup, poses, self.euler, self.w)
        b_inst = np.where(present[..., None], dh, 0.0)
        e_inst = np.where(present, r @ self.w.T, 0.0)
        return e_leg, e_inst, b_leg, b_inst, leg_hess + np.matmul(b_inst.transpose(0, 1, 3, 2), b_inst)

    def rhs(self, e_leg, e_inst, b_leg, b_inst):
        """``bᵀ e`` of each pose ``(k, m, 6)``."""
        inst = e_inst @ self.w if b_inst is None else np.einsum("tmki,tmk->tmi", b_inst, e_inst)
        return np.einsum("tmki,tmk->tmi", b_leg, e_leg) + inst

    def solve(self, full, poses, idx):
        """Gauss–Newton over every pose of trials ``idx``, warm-started at ``poses``: the poses
        and :meth:`equations` there. Each iteration works on the trials not yet settled."""
        poses = np.array(poses)
        out: list = []
        todo = np.arange(len(idx))
        last = np.zeros(len(idx), dtype=bool)  # converged: only the equations at the last step are due
        for _ in range(_INNER_MAX_ITER + 1):
            eqs = self.equations(full[todo], poses[todo], idx[todo])
            if not out:
                out = [None if e is None else np.empty((len(idx), *e.shape[1:])) for e in eqs]
            for whole, part in zip(out, eqs, strict=True):
                if whole is not None:
                    whole[todo] = part
            step = cholesky_solve(eqs[4], self.rhs(*eqs[:4]))
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


class _Layout:
    """The solver's variables: each leg's free columns, leg after leg, then the instrument's
    free quantities; their full-vector positions, scales and the Problem order they map to."""

    def __init__(self, stack) -> None:
        mask, scales = stack.mask, stack.scales
        self.leg_cols = stack.leg_columns()  # (6, L)
        self.leg_free = mask[self.leg_cols]  # (6, L)
        setup = np.arange(stack.setup.start, stack.setup.stop)
        self.setup_cols = setup[mask[setup]]
        self.cols = np.concatenate([self.leg_cols[self.leg_free], self.setup_cols])
        self.scale = scales[self.cols]
        self.n_leg = int(self.leg_free.sum())
        order = np.flatnonzero(mask)
        self.problem_order = np.searchsorted(order, self.cols)  # kernel variable -> Problem variable


def _normal_equations(full, poses, eqs, inner, idx, layout):
    """Gradient ``(k, n)``, Gauss–Newton matrix ``(k, n, n)`` and the parameter rows of the
    projected problem for trials ``idx``, in the variables of ``layout`` (solver units).

    ``Jᵀ J = Aᵀ A - Cᵀ C`` with ``A`` the parameter Jacobian (leg rows block diagonal over legs,
    instrument rows in the instrument's quantities) and ``C = Qᵀ A``, ``Q = b L⁻ᵀ`` (``L`` the
    Cholesky factor of each pose's ``bᵀb``) an orthonormal basis of the pose Jacobian; the
    gradient is ``Aᵀ e - Cᵀ Qᵀ e`` with ``Qᵀ e = L⁻¹ bᵀ e``.
    """
    e_leg, e_inst, b_leg, b_inst, hess = eqs
    k, m = poses.shape[:2]
    st = inner.stack
    rot, pos = pose_frames_batch(poses, inner.euler)
    _, jac = leg_blocks(
        full[:, layout.leg_cols], rot, pos, inner.readings[idx].transpose(0, 2, 1), "length", inner.model
    )
    js = jac * (st.scales[layout.leg_cols] / inner.sigma)[:, None, :]  # (k, 6, m, L)
    lo = cholesky_lower(hess)  # (6, 6, k, m)
    qt = forward_substitute(lo, np.array(b_leg.transpose(3, 2, 0, 1)))  # Qᵀ's leg columns: (6 l, 6 i, k, m)
    qte = forward_substitute(lo, np.moveaxis(inner.rhs(e_leg, e_inst, b_leg, b_inst), -1, 0))  # (6 l, k, m)
    # C[t, (i, c), (j, l)] = A[t, i, j, c] Q[t, j, i, l]: leg i, column c, pose j, basis vector l
    fr = layout.leg_free
    width = fr.shape[1]
    same = bool((fr == fr[0]).all())  # the same parameters of every leg: select before the product
    a_t = np.ascontiguousarray(js.transpose(0, 1, 3, 2)[:, :, fr[0]] if same else js.transpose(0, 1, 3, 2))
    c = a_t[..., None] * np.ascontiguousarray(qt.transpose(2, 1, 3, 0))[:, :, None]
    c = c.reshape(k, -1, 6 * m) if same else c.reshape(k, 6 * width, 6 * m)[:, fr.ravel()]
    a_inst = None
    if layout.setup_cols.size:
        setup = full[:, st.setup]
        d = np.matmul(inner.w, inst_jacobian(inner, setup, poses, idx))[
            ..., layout.setup_cols - st.setup.start
        ]
        a_inst = d * st.scales[layout.setup_cols]  # (k, m, K, q)
        b_i = np.broadcast_to(inner.w, (k, m, *inner.w.shape)) if b_inst is None else b_inst
        qt_i = forward_substitute(lo, np.array(b_i.transpose(3, 2, 0, 1)))  # (6 l, K, k, m)
        c_s = np.einsum("lrtj,tjrq->tqjl", qt_i, a_inst).reshape(k, -1, 6 * m)
        c = np.concatenate([c, c_s], axis=1)
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
    if a_inst is not None:
        n = layout.n_leg
        h[:, n:, n:] += np.einsum("tjrq,tjrp->tqp", a_inst, a_inst)
        g[:, n:] += np.einsum("tjrq,tjr->tq", a_inst, e_inst)
    return g, h, js, a_inst


def inst_jacobian(inner, setup, poses, idx):
    """The instrument residuals' Jacobian in its quantities ``(k, m, K, q)``, masked."""
    d = inner.instrument.setup_jacobian(setup, poses, inner.euler)
    return np.where(inner.present[idx][..., None], d, 0.0)


def solve_ml(stack, full, noise, alive, xtol, max_iter, warm=True):
    """Outer Levenberg–Marquardt of maximum likelihood from ``full`` (``warm``: a least-squares
    estimate, else the start values), each iteration on the trials still active.

    Returns ``(full, status, iterations, cost)``; with gauge freedoms the values are under the
    gauge convention.
    """
    t = full.shape[0]
    sigma = max(noise.sigmas[0], LEG_SIGMA_FLOOR)
    inner = _Poses(stack, sigma, floored_whitener(stack.instrument.covariance(noise), POSE_VARIANCE_FLOOR))
    layout = _Layout(stack)
    cols, scale = layout.cols, layout.scale
    labels, generators = stack.gauges()
    basis = None
    if labels:  # each trial's directions orthogonal to its gauges, in the solver's variables
        gens = generators[:, layout.problem_order]
        basis = np.stack([complement_basis(_Gens(gen)) for gen in gens])
    everyone = np.arange(t)
    start_poses = _start_poses(stack, full)
    poses, *eqs = inner.solve(full, start_poses, everyone)

    def cost_of(eq):
        return 0.5 * (np.sum(eq[0] ** 2, axis=(1, 2)) + np.sum(eq[1] ** 2, axis=(1, 2)))

    cost = cost_of(eqs)
    model = inner.model.lengths(full[:, None, stack.legs], stack.readings)
    floor = rounding_floor(np.abs(eqs[0]) + np.abs(model) / sigma, (1, 2)) + rounding_floor(
        np.abs(np.where(stack.present, stack.observed, 0.0) @ inner.w.T), (1, 2)
    )
    active = alive & np.isfinite(cost)
    status = np.where(active, STATUS_MAX_ITER, STATUS_NONFINITE)
    iterations = np.zeros(t, dtype=int)
    lam, nu = np.full(t, ML_LAMBDA0 if warm else ML_LAMBDA_COLD), np.full(t, 2.0)
    n = cols.size
    g, h = np.zeros((t, n)), np.zeros((t, n, n))
    # the leg rows of the parameter Jacobian, the pose Jacobian and bᵀb at the current poses:
    # they predict the poses of the next parameters (the implicit function's derivative)
    width = layout.leg_cols.shape[1]
    js = np.zeros((t, 6, poses.shape[1], width))
    a_inst = np.zeros((t, *stack.present.shape[1:], layout.setup_cols.size))
    b_leg, b_inst, hess = eqs[2].copy(), None if eqs[3] is None else eqs[3].copy(), eqs[4].copy()
    idx = np.flatnonzero(active)
    g[idx], h[idx], js[idx], a = _normal_equations(
        full[idx], poses[idx], [_take(e, idx) for e in eqs], inner, idx, layout
    )
    if a is not None:
        a_inst[idx] = a
    for _ in range(max_iter):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        gi, hi = g[idx], h[idx]
        if basis is None:
            dx = -cholesky_solve(damped(hi, lam[idx]), gi)
        else:
            b = basis[idx]
            hz = np.swapaxes(b, 1, 2) @ hi @ b
            dz = -cholesky_solve(damped(hz, lam[idx]), (np.swapaxes(b, 1, 2) @ gi[..., None])[..., 0])
            dx = (b @ dz[..., None])[..., 0]
        x = (full[idx] - stack.full0[idx])[:, cols] / scale
        small = np.linalg.norm(dx, axis=1) <= xtol * (xtol + np.linalg.norm(x, axis=1))
        trial = full[idx].copy()
        trial[:, cols] += dx * scale
        guess = poses[idx] - cholesky_solve(
            hess[idx],
            _pose_change(
                inner, js[idx], a_inst[idx], dx, layout, b_leg[idx], None if b_inst is None else b_inst[idx]
            ),
        )
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
        status[idx[~np.all(np.isfinite(dx), axis=1)]] = STATUS_NONFINITE
        active[idx[small | ~np.all(np.isfinite(dx), axis=1)]] = False
        again = accept & ~small
        if again.any():
            new = idx[again]
            g[new], h[new], js[new], a = _normal_equations(
                trial[again], trial_poses[again], [_take(e, again) for e in trial_eqs], inner, new, layout
            )
            if a is not None:
                a_inst[new] = a
            b_leg[new], hess[new] = trial_eqs[2][again], trial_eqs[4][again]
            if b_inst is not None:
                b_inst[new] = trial_eqs[3][again]
    if labels:  # every converged trial under the gauge convention (joints closest to the start's)
        ok = status == STATUS_CONVERGED
        full[ok] = apply_convention(stack.template(0), full[ok], labels)
    return full, status, iterations, cost


def _take(e, idx):
    return None if e is None else e[idx]


def _pose_change(inner, js, a_inst, dx, layout, b_leg, b_inst):
    """``bᵀ δe`` of each pose for the parameter step ``dx``: the change of the poses' equations
    that predicts where the poses of the next parameters are."""
    k, m = js.shape[0], js.shape[2]
    step = np.zeros((k, *layout.leg_free.shape))
    step[:, layout.leg_free] = dx[:, : layout.n_leg]
    de = np.einsum("tijc,tic->tji", js, step)  # change of e_leg, (k, m, 6)
    out = np.einsum("tmil,tmi->tml", b_leg, de)
    if layout.setup_cols.size:
        de_i = np.einsum("tjrq,tq->tjr", a_inst, dx[:, layout.n_leg :])
        b_i = np.broadcast_to(inner.w, (k, m, *inner.w.shape)) if b_inst is None else b_inst
        out = out + np.einsum("tmrl,tmr->tml", b_i, de_i)
    return out


def _start_poses(stack, full):
    """Each observation's start pose: the measured platform pose where the instrument gives
    it, else the forward kinematics of its readings on each trial's start machine."""
    inst = stack.instrument
    if inst.determines_pose:
        return inst.platform_from(full[:, stack.setup], stack.observed, stack.euler)
    from hexcal.core.kinematics import forward_kinematics_from_arrays

    joints = full[:, stack.joints]
    t = len(full)
    u, s = joints[:, None, :18].reshape(t, 1, 6, 3), joints[:, None, 18:36].reshape(t, 1, 6, 3)
    lengths = stack.start.leg_model.lengths(full[:, None, stack.legs], stack.readings)
    home = stack.start.home_pose if stack.start.home_pose is not None else np.zeros(6)
    fk = forward_kinematics_from_arrays(
        u, s, lengths, np.broadcast_to(home, (*lengths.shape[:-1], 6)), stack.euler
    )
    return np.where(fk.converged[..., None], fk.poses, home)


class _Gens:
    """Generators as :func:`complement_basis` reads them."""

    def __init__(self, generators) -> None:
        self.generators = generators
