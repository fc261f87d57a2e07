"""Maximum likelihood (``"ml"``): the parameters and every true pose, errors in variables.

The unknowns are the parameters ``θ`` (the machine's and every session's instrument's) and
the true pose ``P_j`` of every observation. With Gaussian noise the negative log-likelihood
is half the sum of squares of the whitened observation equations of
:mod:`hexcal.estimation.equations`: per observation ``j``

    e_leg,j  = (|o(P_j) + R(P_j) s_i - u_i| - f(θ_i, dl_ij)) / σ_leg      (6 values)
    e_inst,j = W (h(θ, P_j) - y_j),    Wᵀ W = Σ_inst⁻¹                  (k values)

(for the full-pose instrument ``h(P) = P``; ``f`` the leg model). Each ``P_j`` touches only
its own equations, so the problem is solved by variable projection (Golub & Pereyra 1973,
doi:10.1137/0710036; with Kaufman's Jacobian, 1975, doi:10.1007/BF01932995): for given
``θ`` all poses are found at once by a vectorised Gauss–Newton iteration (6 × 6 systems,
:class:`PoseSolver`), and Levenberg–Marquardt (:func:`hexcal.estimation.levenberg.minimise`)
works on ``θ`` alone with the projected Jacobian ``(I - Q_j Q_jᵀ) ∂e_j/∂θ``, ``Q_j`` an
orthonormal basis of ``∂e_j/∂P_j``. Its normal equations exploit the structure: the leg rows
are block diagonal over legs in each leg's own columns, the instrument rows lie in the
instrument's quantities. Time and memory grow linearly with the number of observations.

One solver serves one identification and a stack of ``T`` (:class:`~hexcal.estimation.stacked.Stack`,
a Monte Carlo study's trials): :func:`solve_ml`. It starts from the ``length`` estimate where
every instrument gives the pose (with no instrument noise at all it is the answer), else from the
start values, or from values given (:func:`fit_ml`'s ``start``: the noise estimate's first fit
starts from the generalised least-squares estimate, the same estimator to first order).

With instruments in their own frames, some combinations of parameters change no prediction
(the gauge freedoms, :mod:`hexcal.estimation.gauge`): the solver varies only the directions
orthogonal to them, and the solution is reported under the gauge convention.

:class:`Projection` gives one problem's projected residuals and Jacobian as dense arrays (the
noise estimate, the outlier statistics and the covariance use them).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.noise import NoiseModel
from hexcal.errors import IdentificationError
from hexcal.estimation.covariance import finish_result
from hexcal.estimation.equations import (
    Equations,
    Observations,
    model_lengths,
    observation_equations,
    parameter_rows,
    session_weights,
)
from hexcal.estimation.gauge import apply_convention, complement_basis, gauge_freedoms, unidentifiable
from hexcal.estimation.least_squares import converged_or_raise, fit_least_squares, solve_legs
from hexcal.estimation.levenberg import (
    STATUS_CONVERGED,
    STATUS_NONFINITE,
    Convergence,
    cholesky_lower,
    cholesky_solve,
    forward_substitute,
    minimise,
    rounding_floor,
    solve_small,
)
from hexcal.estimation.problem import Part, Problem, session_noises
from hexcal.estimation.result import IdentificationResult, rms
from hexcal.estimation.stacked import Stack

#: Gauss–Newton iterations and relative step tolerance of the inner pose solve.
_INNER_MAX_ITER = 20
_INNER_TOL = 1e-12
#: A pose step below this (relative) is rounding: the equations before it are final.
_SETTLED = 1e-14
#: Maximum likelihood starts from a ``length`` estimate to this step tolerance, near enough for
#: its outer iteration to start with almost no damping; from the start values (an instrument that
#: does not give the pose) it starts damped.
ML_START_XTOL, ML_LAMBDA0, ML_LAMBDA_COLD = 1e-6, 1e-9, 1e-3


# -- the inner problem: the true poses for given parameters -----------------------------------
class PoseSolver:
    """The true poses of one session of a stack for given parameters: Gauss–Newton on every
    pose at once (``(k, m)`` stacks of 6 × 6 systems).

    ``obs`` are the session's observations over the stack's trials (leading axis ``T``).
    """

    def __init__(self, obs: Observations, joints: slice, legs: slice, block: slice) -> None:
        self.obs, self.joints, self.legs, self.block = obs, joints, legs, block
        self.whitener = obs.whitener
        self._all = len(obs.readings)

    def observations(self, idx: NDArray[np.intp]) -> Observations:
        """The observations of trials ``idx``."""
        if len(idx) == self._all and np.array_equal(idx, np.arange(self._all)):
            return self.obs
        return self.obs.take(idx)

    def equations(
        self, full: NDArray, poses: NDArray, idx: NDArray[np.intp], lengths: NDArray | None = None
    ) -> Equations:
        """The equations of trials ``idx`` at ``poses`` ``(k, m, 6)`` for ``full`` ``(k, N)``
        (``lengths``: the leg model's lengths of the readings, when known)."""
        obs = self.observations(idx)
        joints, legs, setup = full[:, self.joints], full[:, self.legs], full[:, self.block]
        return observation_equations(obs, joints, legs, setup, poses, lengths)

    def solve(
        self, full: NDArray, poses: NDArray, idx: NDArray[np.intp]
    ) -> tuple[NDArray, Equations, NDArray]:
        """Gauss–Newton over every pose of trials ``idx``, warm-started at ``poses``: the poses,
        the equations there and each pose's ``bᵀb``. Each iteration works on the trials not yet
        settled."""
        poses = np.array(poses)
        out: Equations | None = None
        gram = np.empty(0)
        todo = np.arange(len(idx))
        everyone = True  # every trial still moves: the last equations are the whole result
        lengths = model_lengths(self.observations(idx), full[:, self.legs])  # constant over the solve
        last = np.zeros(len(idx), dtype=bool)  # converged: only the equations at the last step are due
        for _ in range(_INNER_MAX_ITER + 1):
            eqs = self.equations(full[todo], poses[todo], idx[todo], lengths[todo])
            hess = eqs.gram(self.whitener)
            if everyone:
                out, gram = eqs, hess
            else:
                out.put(todo, eqs)
                gram[todo] = hess
            step = solve_small(hess, eqs.rhs(self.whitener))
            size = np.max(np.abs(step), axis=(1, 2))
            scale = 1.0 + np.max(np.abs(poses[todo]), axis=(1, 2))
            # a trial moves on unless its step is below rounding (the equations here are final),
            # not finite, or it converged at the previous step
            moving = np.isfinite(size) & (size >= _SETTLED * scale) & ~last[todo]
            poses[todo[moving]] -= step[moving]
            last[todo[moving]] = size[moving] < _INNER_TOL * scale[moving]
            everyone &= bool(moving.all())
            todo = todo[moving]
            if todo.size == 0:
                break
        return poses, out, gram


# -- the outer problem on a stack -------------------------------------------------------------
class Layout:
    """The solver's variables: each leg's free columns, leg after leg, then each session's free
    instrument quantities; their full-vector positions, scales and the Problem order they map to."""

    def __init__(self, stack: Stack) -> None:
        mask, scales = stack.mask, stack.scales
        self.leg_cols = stack.leg_columns()  # (6, L)
        self.leg_free = mask[self.leg_cols]  # (6, L)
        self.n_leg = int(self.leg_free.sum())
        self.part_cols, self.part_local, self.spans = [], [], []
        start = self.n_leg
        for part in stack.parts:
            block = np.arange(part.block.start, part.block.stop)
            cols = block[mask[block]]
            self.part_cols.append(cols)
            self.part_local.append(cols - part.block.start)
            self.spans.append(slice(start, start + cols.size))
            start += cols.size
        self.cols = np.concatenate([self.leg_cols[self.leg_free], *self.part_cols])
        self.scale = scales[self.cols]
        self.n = self.cols.size
        order = np.flatnonzero(mask)
        self.problem_order = np.searchsorted(order, self.cols)  # solver variable -> Problem variable


class _Point:
    """One session's state at some parameters of trials (poses, equations, ``bᵀb``)."""

    def __init__(self, poses: NDArray, eqs: Equations, gram: NDArray) -> None:
        self.poses, self.eqs, self.gram = poses, eqs, gram

    def take(self, sel: Any) -> _Point:
        return _Point(self.poses[sel], self.eqs.take(sel), self.gram[sel])

    def put(self, idx: NDArray[np.intp], other: _Point) -> None:
        self.poses[idx] = other.poses
        self.eqs.put(idx, other.eqs)
        self.gram[idx] = other.gram


def _cost(points: Sequence[_Point]) -> NDArray[np.float64]:
    return sum(
        0.5 * (np.sum(p.eqs.e_leg**2, axis=(1, 2)) + np.sum(p.eqs.e_inst**2, axis=(1, 2))) for p in points
    )


class _Trial:
    def __init__(self, full: NDArray, points: list[_Point]) -> None:
        self.full, self.points = full, points
        self.cost = _cost(points)


class MaximumLikelihood:
    """The variable-projection problems of a stack's trials: the
    :class:`~hexcal.estimation.levenberg.Model` of the ``ml`` estimator.

    ``full`` ``(T, N)`` are the start values, ``noises`` one noise model per session.
    """

    def __init__(self, stack: Stack, full: NDArray, noises: Sequence[NoiseModel], alive: NDArray) -> None:
        self.stack, self.full0 = stack, stack.full0
        self.layout = layout = Layout(stack)
        self.solvers = []
        for part, noise in zip(stack.parts, noises, strict=True):
            obs = part.observations(stack.start, noise)
            self.solvers.append(PoseSolver(obs, stack.joints, stack.legs, part.block))
        self.full = np.array(full)
        t = len(full)
        everyone = np.arange(t)
        self.points = [
            _Point(*solver.solve(self.full, part.start_poses, everyone))
            for solver, part in zip(self.solvers, stack.parts, strict=True)
        ]
        self.cost = _cost(self.points)
        self.g, self.h = np.zeros((t, layout.n)), np.zeros((t, layout.n, layout.n))
        # each session's leg rows of the parameter Jacobian and its instrument rows at the current
        # point: with the pose Jacobian and bᵀb they predict the poses of the next parameters
        width = layout.leg_cols.shape[1]
        self.js = [np.zeros((t, 6, p.readings.shape[1], width)) for p in stack.parts]
        self.a_inst = [
            np.zeros((t, *p.present.shape[1:], cols.size))
            for p, cols in zip(stack.parts, layout.part_cols, strict=True)
        ]
        active = np.flatnonzero(alive & np.isfinite(self.cost))
        if active.size:
            self._normal(self.full[active], [p.take(active) for p in self.points], active)

    def floor(self) -> NDArray[np.float64]:
        """Rounding level of each trial's cost."""
        out = 0.0
        st = self.stack
        for solver, point in zip(self.solvers, self.points, strict=True):
            obs = solver.obs
            model = st.start.leg_model.lengths(self.full[:, None, st.legs], obs.readings)
            observed = np.where(obs.present, obs.observed, 0.0) @ obs.whitener.T
            out = out + rounding_floor(np.abs(point.eqs.e_leg) + np.abs(model) / obs.sigma, (1, 2))
            out = out + rounding_floor(np.abs(observed), (1, 2))
        return out

    def active(self, alive: NDArray[np.bool_]) -> NDArray[np.bool_]:
        return alive & np.isfinite(self.cost)

    # -- the normal equations ----------------------------------------------------------------
    def _normal(self, full: NDArray, points: list[_Point], idx: NDArray[np.intp]) -> None:
        """Gradient, Gauss–Newton matrix and the parameter rows of the projected problem for
        trials ``idx`` at ``full`` ``(k, N)``, in the layout's variables (solver units).

        ``Jᵀ J = Aᵀ A - Cᵀ C`` with ``A`` the parameter Jacobian (leg rows block diagonal over legs,
        instrument rows in the instrument's quantities) and ``C = Qᵀ A``, ``Q = b L⁻ᵀ`` (``L`` the
        Cholesky factor of each pose's ``bᵀb``) an orthonormal basis of the pose Jacobian; the
        gradient is ``Aᵀ e - Cᵀ Qᵀ e`` with ``Qᵀ e = L⁻¹ bᵀ e``.
        """
        st, layout = self.stack, self.layout
        k = len(idx)
        n, fr = layout.n, layout.leg_free
        width = fr.shape[1]
        same = bool((fr == fr[0]).all())  # the same parameters of every leg: select before the product
        table = full[:, layout.leg_cols]
        leg_scale = st.scales[layout.leg_cols]
        h = g = blocks = ate = None  # sums over the sessions
        for p, (solver, point) in enumerate(zip(self.solvers, points, strict=True)):
            obs = solver.observations(idx)
            eqs, m = point.eqs, point.poses.shape[1]
            js, a_inst = parameter_rows(
                obs, table, full[:, solver.block], point.poses, leg_scale, layout.part_local[p]
            )
            lo = cholesky_lower(point.gram)  # (6, 6, k, m)
            qt = forward_substitute(
                lo, np.array(eqs.b_leg.transpose(3, 2, 0, 1))
            )  # Qᵀ's leg columns (6 l, 6 i, k, m)
            qte = forward_substitute(lo, np.moveaxis(eqs.rhs(solver.whitener), -1, 0))  # (6 l, k, m)
            # C[t, (i, c), (j, l)] = A[t, i, j, c] Q[t, j, i, l]: leg i, column c, pose j, basis vector l
            a_t = np.ascontiguousarray(
                js.transpose(0, 1, 3, 2)[:, :, fr[0]] if same else js.transpose(0, 1, 3, 2)
            )
            c = a_t[..., None] * np.ascontiguousarray(qt.transpose(2, 1, 3, 0))[:, :, None]
            c = c.reshape(k, -1, 6 * m) if same else c.reshape(k, 6 * width, 6 * m)[:, fr.ravel()]
            span = layout.spans[p]
            if a_inst is not None:
                a_inst = a_inst * st.scales[layout.part_cols[p]]  # (k, m, K, q)
                b_i = eqs.b_inst
                if b_i is None:
                    b_i = np.broadcast_to(solver.whitener, (k, m, *solver.whitener.shape))
                qt_i = forward_substitute(lo, np.array(b_i.transpose(3, 2, 0, 1)))  # (6 l, K, k, m)
                c_s = np.einsum("lrtj,tjrq->tqjl", qt_i, a_inst).reshape(k, -1, 6 * m)
                c = np.concatenate([c, c_s], axis=1)
            if c.shape[1] < n:  # several sessions: this one's rows among all the variables
                whole = np.zeros((k, n, 6 * m))
                whole[:, : layout.n_leg] = c[:, : layout.n_leg]
                whole[:, span] = c[:, layout.n_leg :]
                c = whole
            cct = np.matmul(c, c.transpose(0, 2, 1))
            cqe = np.einsum("tcr,tr->tc", c, qte.transpose(1, 2, 0).reshape(k, -1))
            jtj = np.matmul(js.transpose(0, 1, 3, 2), js)
            jte = np.einsum("tijc,tji->tic", js, eqs.e_leg)
            if h is None:
                h, g, blocks, ate = -cct, -cqe, jtj, jte
            else:
                h, g, blocks, ate = h - cct, g - cqe, blocks + jtj, ate + jte
            if a_inst is not None:
                h[:, span, span] += np.einsum("tjrq,tjrp->tqp", a_inst, a_inst)
                g[:, span] += np.einsum("tjrq,tjr->tq", a_inst, eqs.e_inst)
                self.a_inst[p][idx] = a_inst
            self.js[p][idx] = js
        start = 0
        for i in range(6):
            cols = np.flatnonzero(fr[i])
            span = slice(start, start + cols.size)
            h[:, span, span] += blocks[:, i][:, cols][:, :, cols]
            g[:, span] += ate[:, i, cols]
            start += cols.size
        self.g[idx], self.h[idx] = g, h

    def _pose_change(self, p: int, idx: NDArray[np.intp], dx: NDArray) -> NDArray[np.float64]:
        """``bᵀ δe`` of each pose of session ``p`` for the parameter step ``dx``: the change of the
        poses' equations that predicts where the poses of the next parameters are."""
        layout, point = self.layout, self.points[p]
        js = self.js[p][idx]
        k, m = js.shape[0], js.shape[2]
        step = np.zeros((k, *layout.leg_free.shape))
        step[:, layout.leg_free] = dx[:, : layout.n_leg]
        de = np.einsum("tijc,tic->tji", js, step)  # change of e_leg, (k, m, 6)
        out = np.einsum("tmil,tmi->tml", point.eqs.b_leg[idx], de)
        span = layout.spans[p]
        if span.stop > span.start:
            de_i = np.einsum("tjrq,tq->tjr", self.a_inst[p][idx], dx[:, span])
            b_i = point.eqs.b_inst
            w = self.solvers[p].whitener
            b_i = np.broadcast_to(w, (k, m, *w.shape)) if b_i is None else b_i[idx]
            out = out + np.einsum("tmrl,tmr->tml", b_i, de_i)
        return out

    # -- the Model protocol --------------------------------------------------------------------
    def deviation(self, idx: NDArray[np.intp]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        full, layout = self.full[idx], self.layout
        return (full - self.full0[idx])[:, layout.cols] / layout.scale, full[:, layout.cols] / layout.scale

    def trial(self, idx: NDArray[np.intp], dx: NDArray[np.float64]) -> _Trial:
        full = self.full[idx].copy()
        full[:, self.layout.cols] += dx * self.layout.scale
        points = []
        for p, (solver, point) in enumerate(zip(self.solvers, self.points, strict=True)):
            guess = point.poses[idx] - cholesky_solve(point.gram[idx], self._pose_change(p, idx, dx))
            points.append(_Point(*solver.solve(full, guess, idx)))
        return _Trial(full, points)

    def take(self, idx: NDArray[np.intp], trial: _Trial, accept: NDArray, again: NDArray) -> None:
        took = idx[accept]
        self.full[took], self.cost[took] = trial.full[accept], trial.cost[accept]
        for point, new in zip(self.points, trial.points, strict=True):
            point.put(took, new.take(accept) if not accept.all() else new)
        if again.any():
            self._normal(trial.full[again], [p.take(again) for p in trial.points], idx[again])


class Solution:
    """The outcome of :func:`solve_ml` over a stack: values ``full`` ``(T, N)``, ``status``,
    ``iterations``, ``cost`` and ``rank`` ``(T,)``, and each session's estimated true poses."""

    def __init__(self, full, status, iterations, cost, rank, poses) -> None:
        self.full, self.status, self.iterations, self.cost, self.rank, self.poses = (
            full,
            status,
            iterations,
            cost,
            rank,
            poses,
        )


def solve_ml(
    stack: Stack,
    noises: Sequence[NoiseModel],
    alive: NDArray[np.bool_] | None = None,
    xtol: float = 1e-10,
    max_iter: int = 100,
    start: NDArray[np.float64] | None = None,
) -> Solution:
    """Maximum likelihood of every trial of a stack (see the module), one noise model per
    session: from ``start`` ``(T, N)`` when given (a solution under other noise), else from the
    ``length`` estimate where every instrument gives the pose, else from the start values
    (damped).
    With gauge freedoms the values are under the gauge convention."""
    t = len(stack)
    alive = np.ones(t, dtype=bool) if alive is None else np.asarray(alive, dtype=bool)
    full = np.array(stack.full0)
    rank = np.full(t, int(stack.mask.sum()))
    iterations = np.zeros(t, dtype=int)
    noisy = any(np.any(p.instrument.covariance(n) != 0) for p, n in zip(stack.parts, noises, strict=True))
    lam0 = ML_LAMBDA_COLD
    status = np.where(alive, STATUS_CONVERGED, STATUS_NONFINITE)
    if stack.determines_pose and not noisy:  # exact poses: least squares on the legs is the answer
        full, status, iterations, cost, rank = solve_legs(stack, "length", alive, xtol, max_iter)
        return Solution(full, status, iterations, cost, rank, [p.start_poses for p in stack.parts])
    if start is not None:
        full, lam0 = np.array(start, dtype=float), ML_LAMBDA0
    elif stack.determines_pose:
        full, status, iterations, cost, rank = solve_legs(stack, "length", alive, ML_START_XTOL, max_iter)
        alive = status == STATUS_CONVERGED
        lam0 = ML_LAMBDA0
    model = MaximumLikelihood(stack, full, noises, alive)
    labels, generators = stack.gauges()
    basis = None
    if labels:  # each trial's directions orthogonal to its gauges, in the solver's variables
        gens = generators[:, model.layout.problem_order]
        basis = np.stack([complement_basis(_Generators(gen)) for gen in gens])
    ml_status, ml_iterations = minimise(
        model, model.active(alive), model.floor(), xtol, max_iter, lam0, basis
    )
    status = np.where(alive, ml_status, status)
    full = model.full
    ok = status == STATUS_CONVERGED
    if (
        labels and ok.any()
    ):  # every converged trial under the gauge convention (joints closest to the start's)
        full[ok] = apply_convention(stack.template(0), full[ok], labels)
    return Solution(
        full, status, iterations + ml_iterations, model.cost, rank, [p.poses for p in model.points]
    )


class _Generators:
    """Generators as :func:`complement_basis` reads them."""

    def __init__(self, generators: NDArray[np.float64]) -> None:
        self.generators = generators


# -- one problem: dense views and the estimator -----------------------------------------------
class PoseProjection:
    """The inner problem of variable projection for one session: true poses for given
    parameters.

    Caches the last evaluation (the residual and the Jacobian are asked for at the same point)
    and warm-starts each pose solve from the last poses.
    """

    def __init__(self, problem: Problem, part: Part, noise: NoiseModel) -> None:
        self.problem, self.part = problem, part
        self.sigma, self.whitener = session_weights(part.instrument, noise)
        obs = Observations.of(
            part.instrument,
            problem.euler,
            problem.legs,
            part.readings[None],
            part.observed[None],
            part.present[None],
            self.sigma,
            self.whitener,
        )
        self._solver = PoseSolver(obs, problem.joints, problem.leg_block, part.block)
        self.start = problem.start_poses(part)
        self.poses = self.start.copy()
        self.x: NDArray[np.float64] | None = None
        self.e = self.b = np.empty(0)
        self._basis: tuple[NDArray, NDArray] | None = None

    def reset(self) -> None:
        """Start the next pose solve from the initial poses again."""
        self.poses, self.x = self.start.copy(), None

    def evaluate(self, x: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray]:
        """``(poses, e, b)`` at solver variables ``x`` (Gauss–Newton over all poses at once)."""
        if self.x is not None and np.array_equal(self.x, x):
            return self.poses, self.e, self.b
        full = self.problem.unpack(x)
        poses, eqs, _ = self._solver.solve(full[None], self.poses[None], np.zeros(1, dtype=np.intp))
        e, b = eqs.residuals()[0], eqs.pose_rows(self.whitener)[0]
        self.x, self.poses, self.e, self.b = x.copy(), poses[0], e, b
        return self.poses, e, b

    def basis(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """An orthonormal basis ``Q`` ``(m, 6 + k, 6)`` of each pose Jacobian at ``x`` (cached)."""
        _, _, b = self.evaluate(x)
        if self._basis is None or self._basis[0] is not b:
            self._basis = (b, np.linalg.qr(b)[0])
        return self._basis[1]

    def jacobian(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """The projected Jacobian ``(I - Q Qᵀ) ∂e/∂θ`` of this session, ``(m (6 + k), n_free)``."""
        poses = self.evaluate(x)[0]
        full = self.problem.unpack(x)
        a = self.problem.eiv_parameter_jacobian(self.part, full, poses, self.sigma, self.whitener)
        q = self.basis(x)
        proj = a - np.matmul(q, np.matmul(q.transpose(0, 2, 1), a))
        return proj.reshape(-1, a.shape[-1])


class Projection:
    """Variable projection over every session of a problem (one :class:`PoseProjection` each)."""

    def __init__(self, problem: Problem, noise: NoiseModel | Sequence[NoiseModel] | None) -> None:
        self.problem = problem
        self.noises = session_noises(problem, noise)
        self.parts = [PoseProjection(problem, p, n) for p, n in zip(problem.parts, self.noises, strict=True)]

    def reset(self) -> None:
        for part in self.parts:
            part.reset()

    def evaluate(self, x: NDArray[np.float64]) -> list[tuple[NDArray, NDArray, NDArray]]:
        """``(poses, e, b)`` of every session at ``x``."""
        return [part.evaluate(x) for part in self.parts]

    def residuals(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.concatenate([part.evaluate(x)[1].ravel() for part in self.parts])

    def jacobian(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """The projected Jacobian of all sessions stacked, solver units."""
        return np.concatenate([part.jacobian(x) for part in self.parts])

    def poses(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """The estimated true poses ``(m, 6)`` of every observation at ``x``."""
        return np.concatenate([part.evaluate(x)[0] for part in self.parts])

    def leg_residuals(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Leg residuals (mm) at the estimated true poses, ``(m, 6)``."""
        return np.concatenate([part.evaluate(x)[1][:, :6] * part.sigma for part in self.parts])

    def blocks(self, x: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """Every session's whitened residuals ``(m_s, 6 + k_s)``."""
        return [part.evaluate(x)[1] for part in self.parts]

    def seed(self, poses: Sequence[NDArray[np.float64]]) -> None:
        """Start the next pose solve of each session from ``poses`` (a solution's)."""
        for part, own in zip(self.parts, poses, strict=True):
            part.poses, part.x = np.array(own), None


def _solve_one(
    problem: Problem,
    noises: Sequence[NoiseModel],
    xtol: float,
    max_iter: int,
    start: NDArray | None = None,
    poses: Sequence[NDArray[np.float64]] | None = None,
) -> Solution:
    """:func:`solve_ml` of one problem (a stack of one), from solver variables ``start`` and the
    true poses ``poses`` of each session (default the instruments' start poses)."""
    full = None if start is None else problem.unpack(np.asarray(start, dtype=float))[None]
    return solve_ml(Stack.of_problem(problem, poses), noises, xtol=xtol, max_iter=max_iter, start=full)


def fit_ml(
    problem: Problem,
    noise: NoiseModel | Sequence[NoiseModel] | None = None,
    xtol: float = 1e-10,
    max_nfev: int | None = 500,
    polish: int = 0,
    start: NDArray[np.float64] | None = None,
    truncate: bool = False,
    **_: Any,
) -> IdentificationResult:
    """Maximum-likelihood identification with the poses as nuisance parameters.

    Parameters
    ----------
    problem : Problem
    noise : NoiseModel or sequence of NoiseModel, optional
        One for every session or one each; default the seed paper's.
    xtol : float
        Step tolerance of the solver (:mod:`hexcal.estimation.levenberg`).
    max_nfev : int, optional
        Limit on iterations (a well-posed fit needs about ten).
    polish : int
        Accepted for compatibility: the solver reaches the optimum within rounding.
    start : ndarray, shape (n_free,), optional
        Solver variables to start from (a fit of the same problem under other noise, a ``gls``
        estimate), instead of the ``length`` estimate or the start values.
    truncate : bool
        A solve out of iterations gives its last iterate (its ``status`` and ``message`` say so)
        instead of failing.

    Returns
    -------
    IdentificationResult
        ``method`` ``"ml"``; ``residuals`` the whitened leg and instrument residuals of every
        observation; the covariance from the projected Jacobian (gauge-fixed), with the
        independent residuals (``k`` per observation) less the identifiable parameters as
        degrees of freedom, so that the residual variance is close to 1 under a correct noise
        model.
    """
    del polish
    problem.check_size()
    noises = session_noises(problem, noise)
    quiet = not any(
        np.any(p.instrument.covariance(n) != 0) for p, n in zip(problem.parts, noises, strict=True)
    )
    if problem.determines_pose and quiet:
        return fit_least_squares(problem, "length").replace(method="ml")
    inner = Projection(problem, noises)
    x0 = np.zeros(problem.n_free)
    gauge = gauge_freedoms(problem, problem.full0)
    if problem.determines_pose:
        # identifiability of the pose set as measured (the inner solve would otherwise hide a
        # rank deficiency behind the small pose freedom the noise model allows)
        problem.check_rank(problem.leg_jacobian(problem.full0))
    else:
        weak = unidentifiable(problem, inner.jacobian(x0), gauge)
        if weak:
            beyond = f" beyond the {gauge.size} gauge freedoms" if gauge.size else ""
            raise IdentificationError(
                f"the poses cannot identify all parameters{beyond} ({len(weak)} combination(s); "
                f"weakest: {weak[-1]}): fix some or measure more"
            )
    rms_before = rms(inner.residuals(x0))
    legs_before = None if problem.determines_pose else inner.leg_residuals(x0)
    # a solve from the start values begins at the poses just found there
    poses = None if start is not None or problem.determines_pose else [p.poses for p in inner.parts]
    solution = _solve_one(problem, noises, xtol, 500 if max_nfev is None else max_nfev, start, poses)
    converged_or_raise(int(solution.status[0]), truncate)
    full = solution.full[0]
    x = (full[problem.mask] - problem.full0[problem.mask]) / problem.scale
    inner.seed([poses[0] for poses in solution.poses])
    e = inner.residuals(x)
    dof = int(problem.observation_counts().sum()) - (problem.n_free - gauge.size)
    # the leg residuals at the measured poses where the instrument gives them, else at the
    # estimated true poses
    legs = None if problem.determines_pose else (legs_before, inner.leg_residuals(x))
    # the covariance and the bound linearise the gauges at the solution (as at any other point)
    gauge = gauge_freedoms(problem, full) if gauge.size else gauge
    sol = Convergence(solution.status[0], solution.iterations[0], 0.5 * float(e @ e))
    return finish_result(
        problem,
        "ml",
        full,
        e,
        inner.jacobian(x),
        rms_before,
        sol,
        dof=dof,
        leg_residuals=legs,
        gauge=gauge,
        poses=None if problem.determines_pose else inner.poses(x),
        blocks=inner.blocks(x),
        noises=noises,
    )


def ml_misfit(
    problem: Problem, noise: NoiseModel | Sequence[NoiseModel] | None = None, max_nfev: int | None = None
) -> tuple[float, float, int]:
    """``(rms, sum of squares, dof)`` of the whitened residuals of the ``ml`` fit, without its
    covariance, bound or checks: a refit that only compares residuals (a diagnosis). The last
    iterate counts when ``max_nfev`` (iterations) runs out."""
    noises = session_noises(problem, noise)
    solution = _solve_one(problem, noises, 1e-10, 100 if max_nfev is None else max_nfev)
    converged_or_raise(int(solution.status[0]), truncate=True)
    sse = 2.0 * float(solution.cost[0])
    size = sum(len(p) * (6 + p.instrument.size) for p in problem.parts)
    gauge = gauge_freedoms(problem, problem.full0)
    dof = int(problem.observation_counts().sum()) - (problem.n_free - gauge.size)
    return float(np.sqrt(sse / size)), sse, dof
