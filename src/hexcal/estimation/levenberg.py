"""The one Levenberg–Marquardt solver of hexcal: a batch of independent least-squares problems,
each with its own damping, acceptance, convergence test and status.

Every estimator minimises a sum of squares ``0.5 |e(x)|²`` over solver variables ``x``
(:class:`~hexcal.core.parameters.ParameterSet`'s scaled deviations from the start). A *model*
holds a batch of ``B`` such problems (the trials of a Monte Carlo study, the six legs of each
trial, or one identification: a batch of one) and gives, at the points it holds, the cost and
the Gauss–Newton normal equations ``g = Jᵀe``, ``H = JᵀJ``; :func:`minimise` iterates them all
at once, each iteration on the problems still active:

- the step solves ``(H + λ diag H) dx = -g`` (Marquardt's scaling; stacked Cholesky factors,
  :func:`cholesky_solve`), in the directions a basis allows (the complement of gauge freedoms);
- a step is taken when the cost does not rise beyond the rounding of the sum of squares
  (:func:`acceptable`): near the optimum the cost cannot tell steps apart (``paper``
  residuals are differences of squares of 800 mm lengths) but the gradient can;
- the damping follows Nielsen's rule (:func:`update_damping`);
- a problem has converged when it takes a Gauss–Newton step (damping below
  :data:`GN_LAMBDA`) with ``|dx| <= xtol (xtol + |x|)``, ``x`` its deviation from the start,
  or a step within the rounding of the values themselves (a start at the optimum); the step is
  applied. The iterates converge fast near the optimum, so the result is within rounding of the
  optimum, not merely within ``xtol |x|`` of it. Where the rounding of the gradient moves the
  steps more than that (a gross error's large residuals, an ill-conditioned optimum), the
  problem has converged after :data:`STALL` steps in a row, taken, that neither shrink
  tenfold nor promise a decrease beyond the rounding of the cost, whatever their damping: a
  gradient off by more than the cost can tell (a variable projection whose inner pose solves
  stop at their tolerance) makes every step raise the cost a little, within its rounding, and
  the damping then doubles at every step and never comes down to a Gauss–Newton step (the
  noise estimate's first fit of a motion-capture session ran out of iterations so).

``scipy.optimize.least_squares`` decides by the cost alone and cannot batch: it stops up to about
1e-5 mm short of the optimum in weakly determined directions of the ``paper`` cost, and one
problem at a time. The tests compare this solver with it, followed by Gauss–Newton steps.

A failure does not spoil the others: a problem with a non-finite start or step gets
:data:`STATUS_NONFINITE`, one out of iterations :data:`STATUS_MAX_ITER`, and the model may mark
a rank-deficient start :data:`STATUS_RANK_DEFICIENT` before the solve.

Imports numpy only.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

#: Status of a problem: converged; no convergence within ``max_iter``; rank-deficient start;
#: non-finite input or iterate.
STATUS_CONVERGED, STATUS_MAX_ITER, STATUS_RANK_DEFICIENT, STATUS_NONFINITE = 1, 0, -1, -2
STATUS_MESSAGES = {
    STATUS_CONVERGED: "converged",
    STATUS_MAX_ITER: "not converged: the iteration limit was reached",
    STATUS_RANK_DEFICIENT: "the poses cannot identify all parameters (rank-deficient Jacobian)",
    STATUS_NONFINITE: "non-finite measurements, start values or iterate",
}

#: Relative rounding allowed in a cost comparison, the damping below which a step counts as a
#: Gauss–Newton step for the convergence test, and the default start damping.
COST_ROUNDING, GN_LAMBDA, LAMBDA0 = 1e-10, 1e-2, 1e-6

#: Relative rounding of the parameter values: a step below it cannot move them.
ROUNDING = 64 * np.finfo(float).eps

#: Steps in a row within the rounding of the cost, not shrinking, that end a solve.
STALL = 10


class Model(Protocol):
    """What :func:`minimise` asks of a batch of least-squares problems.

    The model holds the current point of every problem (arrays over the batch) and its normal
    equations ``g`` ``(B, n)`` and ``h`` ``(B, n, n)`` (solver units), and the cost ``(B,)``.
    """

    g: NDArray[np.float64]
    h: NDArray[np.float64]
    cost: NDArray[np.float64]

    def deviation(self, idx: NDArray[np.intp]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``x`` of problems ``idx``: their deviation from the start, solver units ``(k, n)``,
        and the values themselves in solver units ``(k, n)`` (their rounding ends the solve)."""

    def trial(self, idx: NDArray[np.intp], dx: NDArray[np.float64]) -> Any:
        """Evaluate problems ``idx`` at ``x + dx``: an opaque trial point whose ``cost`` ``(k,)``
        the solver reads."""

    def take(
        self, idx: NDArray[np.intp], trial: Any, accept: NDArray[np.bool_], again: NDArray[np.bool_]
    ) -> None:
        """Move problems ``idx[accept]`` to their trial point, and update the normal equations
        of ``idx[again]`` (accepted and not converged)."""


# -- stacked linear algebra -------------------------------------------------------------------
def cholesky_lower(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Lower Cholesky factors of a stack ``(..., n, n)``, returned as ``(n, n, ...)`` (row, column,
    stack), vectorised over the stack (a loop over ``n``). A member that is not numerically
    positive definite gets NaN, and no exception, so that one bad problem cannot stop the others."""
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


#: Systems below which LAPACK's stacked solve is faster than :func:`cholesky_solve` (its
#: per-system cost is lower; the vectorised Cholesky's per-call cost is lower).
SMALL_STACK = 2048


def solve_small(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """``a⁻¹ b`` for stacks ``(..., n, n)`` of symmetric positive definite systems and ``b``
    ``(..., n)``: LAPACK for a few systems, :func:`cholesky_solve` for many, or where one of a
    few is singular (NaN for it, the others solved)."""
    if int(np.prod(a.shape[:-2])) < SMALL_STACK:
        try:
            return np.linalg.solve(a, b[..., None])[..., 0]
        except np.linalg.LinAlgError:
            pass
    return cholesky_solve(a, b)


# -- the damping and the acceptance of a step ------------------------------------------------
def damped(h: NDArray[np.float64], lam: NDArray[np.float64]) -> NDArray[np.float64]:
    """``H + λ diag(H)`` (Marquardt's scaling; the diagonal floored to stay positive)."""
    diag = np.diagonal(h, axis1=-2, axis2=-1)
    floor = 1e-12 * np.max(diag, axis=-1, keepdims=True) + 1e-300
    out = h.copy()
    idx = np.arange(h.shape[-1])
    out[..., idx, idx] += lam[..., None] * np.maximum(diag, floor)
    return out


def update_damping(
    lam: NDArray[np.float64], nu: NDArray[np.float64], accept: NDArray[np.bool_], gain: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
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


# -- the solver -------------------------------------------------------------------------------
def minimise(
    model: Model,
    active: NDArray[np.bool_],
    floor: NDArray[np.float64],
    xtol: float = 1e-10,
    max_iter: int = 100,
    lam0: float | NDArray[np.float64] = LAMBDA0,
    basis: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.int_], NDArray[np.int_]]:
    """Levenberg–Marquardt on every ``active`` problem of ``model`` (see the module).

    Parameters
    ----------
    model : Model
        At its start point, with its normal equations there.
    active : ndarray of bool, shape (B,)
        The problems to solve (the others keep their status, :data:`STATUS_NONFINITE` unless
        the caller says otherwise).
    floor : ndarray, shape (B,)
        Rounding level of each problem's cost (:func:`rounding_floor`).
    xtol : float
        Step tolerance, solver units.
    max_iter : int
    lam0 : float or ndarray, shape (B,)
        Start damping (small near the optimum, larger from afar).
    basis : ndarray, shape (B, n, n - g), optional
        Each problem's directions (orthonormal columns) the step stays in.

    Returns
    -------
    status, iterations : ndarray of int, shape (B,)
        The model is left at each problem's last point.
    """
    active = np.array(active, dtype=bool)
    b = len(active)
    status = np.where(active, STATUS_MAX_ITER, STATUS_NONFINITE)
    iterations = np.zeros(b, dtype=int)
    lam = np.broadcast_to(np.asarray(lam0, dtype=float), (b,)).copy()
    nu = np.full(b, 2.0)
    previous, stalled = np.full(b, np.inf), np.zeros(b, dtype=int)
    for _ in range(max_iter):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        g, h = model.g[idx], model.h[idx]
        if basis is None:
            dx = -cholesky_solve(damped(h, lam[idx]), g)
        else:
            z = basis[idx]
            zt = np.swapaxes(z, 1, 2)
            dz = -cholesky_solve(damped(zt @ h @ z, lam[idx]), (zt @ g[..., None])[..., 0])
            dx = (z @ dz[..., None])[..., 0]
        x, values = model.deviation(idx)
        size = np.linalg.norm(dx, axis=1)
        small = (size <= xtol * (xtol + np.linalg.norm(x, axis=1))) | (
            size <= ROUNDING * np.linalg.norm(values, axis=1)
        )
        finite = np.all(np.isfinite(dx), axis=1)
        trial = model.trial(idx, np.where(finite[:, None], dx, 0.0))
        cost = model.cost[idx]
        predicted = -np.einsum("ti,ti->t", g, dx) - 0.5 * np.einsum("ti,tij,tj->t", dx, h, dx)
        gain = (cost - trial.cost) / np.where(predicted > 0, predicted, np.inf)
        accept = acceptable(cost, trial.cost, floor[idx]) & finite
        iterations[idx] += 1
        lam[idx], nu[idx] = update_damping(lam[idx], nu[idx], accept, gain)
        newton = lam[idx] <= GN_LAMBDA
        flat = accept & (predicted <= cost * COST_ROUNDING + floor[idx]) & (size > 0.1 * previous[idx])
        stalled[idx] = np.where(flat, stalled[idx] + 1, 0)
        previous[idx] = np.where(accept, size, previous[idx])
        small = (small & newton) | (stalled[idx] >= STALL)
        model.take(idx, trial, accept, accept & ~small)
        status[idx[small]] = STATUS_CONVERGED
        status[idx[~finite]] = STATUS_NONFINITE
        active[idx[small | ~finite]] = False
    return status, iterations


class Convergence:
    """How one problem's solve ended: its status, iterations, function evaluations and cost
    (the solver record of a result)."""

    def __init__(self, status: int, iterations: int, cost: float, evaluations: int | None = None) -> None:
        self.status, self.iterations, self.cost = int(status), int(iterations), float(cost)
        self.evaluations = self.iterations + 1 if evaluations is None else int(evaluations)

    @property
    def converged(self) -> bool:
        return self.status == STATUS_CONVERGED

    @property
    def message(self) -> str:
        return STATUS_MESSAGES[self.status]
