"""Gross measurement errors: deletion statistics of observations and of single values, and
the robust fit that leaves them out. One implementation for every instrument.

At a fit's parameters every observation ``j`` has residuals ``e_j`` and Jacobian rows: with
a noise model, the whitened errors-in-variables equations (legs and instrument values, the
true pose ``P_j`` eliminated: an orthonormal basis ``Q_j`` of its Jacobian; for instruments
that determine the pose, the closed form of the same elimination, the six leg residuals at
the measured pose whitened by their covariance ``C_j``); without one (instruments that
determine the pose only), the plain leg residuals. With ``U`` an orthonormal basis of the
stacked parameter Jacobian, the hat matrix of the linearised model has the blocks
``H_j = Q_j Q_jᵀ + U_j U_jᵀ``. Deleting a group ``R`` of residuals changes the residual sum of
squares by

    δ = e_Rᵀ (I - H_RR)⁻¹ e_R

(for a whole observation in the coordinates orthogonal to ``Q_j``: the pose goes with it),
and ``F = (δ / k) / ((SSE - δ) / (dof - k))`` follows ``F(k, dof - k)`` for ``k`` independent
residuals in the group (Cook & Weisberg, *Residuals and Influence in Regression*, 1982,
ch. 2.2). Groups: every observation (``k`` its independent residuals) and every value group
of the instrument (a target, ``k = 3``). A group is flagged below the Bonferroni limit
``alpha / groups``. Without a noise model the six residuals of a pose may be correlated in an
unknown way, and the threshold is the quantile of ``F(1, dof)``: the heaviest tail possible,
so the false alarm rate stays below ``alpha`` however the noise is shared.

The robust fit that leaves flagged groups out is :mod:`hexcal.estimation.robust`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.noise import NoiseModel
from hexcal.estimation.gls import residual_weights
from hexcal.estimation.problem import Problem, session_noises
from hexcal.estimation.result import IdentificationResult

#: Family-wise false alarm rate of the outlier test over all groups of a data set.
DEFAULT_ALPHA = 0.01

#: A group whose leverage block has an eigenvalue above this cannot be checked: the fit
#: follows it whatever it says (it alone determines some parameter combination).
MAX_LEVERAGE = 1 - 1e-6

#: Screening: an observation whose largest residual under the robust fit exceeds this many
#: robust standard deviations is set aside before the least-squares fit.
SCREEN_THRESHOLD = 8.0


@dataclass(frozen=True)
class PoseDiagnostics:
    """Deletion statistics of a fit's observations and value groups.

    Attributes
    ----------
    statistic : ndarray, shape (m,)
        ``F_j`` of each observation (NaN where it cannot be checked).
    pvalue : ndarray, shape (m,)
        Its tail probability under ``F(k_j, dof - k_j)`` (or ``F(1, ...)``, not exact).
    leverage : ndarray, shape (m,)
        Largest eigenvalue of each observation's hat block.
    value_pvalue : ndarray, shape (m, g)
        Tail probability of each value group of each observation (NaN where absent).
    value_labels : tuple of str
        Labels of the value groups (``target t1`` ...).
    alpha : float
    groups : int
        Groups tested (the Bonferroni count).
    thresholds : ndarray, shape (m,)
        Critical value of each observation's ``F``.
    """

    statistic: NDArray[np.float64]
    pvalue: NDArray[np.float64]
    leverage: NDArray[np.float64]
    value_pvalue: NDArray[np.float64]
    value_labels: tuple[str, ...]
    alpha: float
    groups: int
    thresholds: NDArray[np.float64]

    @property
    def limit(self) -> float:
        """The Bonferroni limit of a group's p-value."""
        return self.alpha / max(self.groups, 1)

    @property
    def threshold(self) -> float:
        """The critical ``F`` of the observations (their common one; the largest if they differ)."""
        finite = self.thresholds[np.isfinite(self.thresholds)]
        return float(finite.max()) if finite.size else float("inf")

    @property
    def flagged(self) -> NDArray[np.intp]:
        """Indices of the observations beyond their threshold, most significant first."""
        p = np.where(np.isfinite(self.pvalue), self.pvalue, np.inf)
        idx = np.flatnonzero(p < self.limit)
        return idx[np.argsort(p[idx], kind="stable")]

    @property
    def uncheckable(self) -> NDArray[np.intp]:
        return np.flatnonzero(~np.isfinite(self.statistic))

    def worst(self) -> tuple[str, int, int] | None:
        """The most significant flagged group: ``("observation", j, -1)`` or ``("values", j, i)``,
        or None."""
        pose = np.where(np.isfinite(self.pvalue), self.pvalue, np.inf)
        vals = np.where(np.isfinite(self.value_pvalue), self.value_pvalue, np.inf)
        jp = int(np.argmin(pose)) if pose.size else -1
        p_pose = pose[jp] if jp >= 0 else np.inf
        jv = np.unravel_index(int(np.argmin(vals)), vals.shape) if vals.size else (-1, -1)
        p_val = vals[jv] if vals.size else np.inf
        if min(p_pose, p_val) >= self.limit:
            return None
        # a lone bad value also makes its observation look bad: prefer the smaller deletion
        if p_val <= p_pose * 10:
            return ("values", int(jv[0]), int(jv[1]))
        return ("observation", jp, -1)

    def flagged_labels(self, ids: Sequence[str]) -> tuple[str, ...]:
        """Labels of the flagged groups, one per observation, the most significant first: an
        observation by its id, or one of its value groups (``7 target t2``) where that group
        alone explains it (as :meth:`worst` chooses)."""
        pose = np.where(np.isfinite(self.pvalue), self.pvalue, np.inf)
        vals = np.where(np.isfinite(self.value_pvalue), self.value_pvalue, np.inf)
        best = np.min(vals, axis=1) if vals.shape[1] else np.full(len(pose), np.inf)
        found = []
        for j in range(len(pose)):
            p = min(pose[j], best[j])
            if p >= self.limit:
                continue
            if best[j] <= pose[j] * 10:
                found.append((best[j], f"{ids[j]} {self.value_labels[int(np.argmin(vals[j]))]}"))
            else:
                found.append((pose[j], ids[j]))
        return tuple(label for _, label in sorted(found, key=lambda item: item[0]))

    def to_dict(self, ids: tuple[str, ...] | None = None) -> dict[str, object]:
        """Statistics, threshold and flagged observations (by id when ``ids`` are given)."""
        label = (lambda k: ids[k]) if ids is not None else int
        return {
            "statistic": self.statistic.tolist(),
            "threshold": self.threshold,
            "leverage": self.leverage.tolist(),
            "flagged": [label(k) for k in self.flagged],
        }


def _fdist(stat: Any, k: Any, dof: Any) -> Any:
    from scipy.special import fdtrc  # not scipy.stats: that costs half a second of import time

    return fdtrc(k, dof, np.maximum(stat, 0.0))


def block_diagnostics(
    blocks: Sequence[tuple[NDArray, NDArray | None, NDArray[np.bool_]]],
    jacobian: NDArray[np.float64],
    alpha: float = DEFAULT_ALPHA,
    exact: bool = True,
    value_groups: Sequence[Sequence[tuple[str, NDArray[np.intp]]]] = (),
) -> PoseDiagnostics:
    """Deletion statistics of observations (and value groups) in a linearised least-squares
    model (see the module).

    Parameters
    ----------
    blocks : sequence of (e, q, present)
        Per session: residuals ``e (m, r)``, an orthonormal basis ``q (m, r, p)`` of each
        observation's nuisance (pose) directions or None, and which rows are present.
    jacobian : ndarray, shape (rows, n)
        The parameter Jacobian of all residuals stacked (its column space; the nuisance
        directions already projected out).
    alpha : float
        Family-wise false alarm rate (Bonferroni over the groups).
    exact : bool
        The residuals are whitened (independent, equal variance): thresholds from
        ``F(k, dof)``; otherwise the conservative ``F(1, dof)``.
    value_groups : sequence of sequences
        Per session, the instrument's value groups ``(label, value indices)``; indices count
        from the first row after the six legs when ``q`` is given.
    """
    from scipy.special import fdtri

    norms = np.linalg.norm(jacobian, axis=0)
    u, sv, _ = np.linalg.svd(jacobian / np.where(norms > 0, norms, 1.0), full_matrices=False)
    u = u[:, sv > 1e-10 * sv[0]] if sv.size else u[:, :0]
    p = u.shape[1]
    sse = float(sum(np.sum(e**2) for e, _, _ in blocks))
    counts = [present.sum(axis=1) - (0 if q is None else q.shape[2]) for _, q, present in blocks]
    dof = int(sum(c.sum() for c in counts)) - p
    stat, lev, kk = [], [], []
    n_values = max((len(g) for g in value_groups), default=0)
    value_p = []
    row = 0
    for s, (e, q, present) in enumerate(blocks):
        m, r = e.shape
        ub = u[row : row + m * r].reshape(m, r, p)
        row += m * r
        hat = ub @ ub.transpose(0, 2, 1)
        if q is not None:
            hat = hat + q @ q.transpose(0, 2, 1)
            full_q, _ = np.linalg.qr(q, mode="complete")
            comp = full_q[:, :, q.shape[2] :]
        else:
            comp = np.broadcast_to(np.eye(r), (m, r, r))
        rt = np.einsum("mrk,mr->mk", comp, e)
        ht = comp.transpose(0, 2, 1) @ hat @ comp
        leverage = np.linalg.eigvalsh(ht)[:, -1]
        safe = np.where((leverage < MAX_LEVERAGE)[:, None, None], ht, 0.0)
        delta = np.einsum("mk,mk->m", rt, np.linalg.solve(np.eye(ht.shape[1]) - safe, rt[..., None])[..., 0])
        k = np.maximum(counts[s], 1)
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            f = (delta / k) / (np.maximum(sse - delta, 1e-300) / np.maximum(dof - k, 1))
        ok = (leverage < MAX_LEVERAGE) & (dof - k > 0)
        stat.append(np.where(ok, f, np.nan))
        lev.append(leverage)
        kk.append(k)
        groups_here = list(value_groups[s]) if s < len(value_groups) else []
        vp = np.full((m, n_values), np.nan)
        offset = 6 if q is not None else 0
        for i, (_, idx) in enumerate(groups_here):
            rows_i = offset + np.asarray(idx)
            h = hat[:, rows_i][:, :, rows_i]
            er = e[:, rows_i]
            seen = present[:, rows_i].all(axis=1)
            lev_v = np.linalg.eigvalsh(h)[:, -1]
            okv = seen & (lev_v < MAX_LEVERAGE) & (counts[s] > len(rows_i))
            if not okv.any():
                continue
            d = np.einsum(
                "mk,mk->m", er[okv], np.linalg.solve(np.eye(len(rows_i)) - h[okv], er[okv][..., None])[..., 0]
            )
            kv = len(rows_i)
            st = (d / kv) / (np.maximum(sse - d, 1e-300) / max(dof - kv, 1))
            vp[okv, i] = _fdist(st, kv, max(dof - kv, 1))
        value_p.append(vp)
    statistic, leverage, k_all = np.concatenate(stat), np.concatenate(lev), np.concatenate(kk)
    k_test = k_all if exact else np.ones_like(k_all)
    pvalue = np.where(np.isfinite(statistic), _fdist(statistic, k_test, np.maximum(dof - k_all, 1)), np.nan)
    value_pvalue = np.concatenate(value_p) if value_p else np.full((len(statistic), 0), np.nan)
    # Bonferroni over every observation and every value group present
    n_groups = len(statistic)
    for (_, q, present), groups_here in zip(blocks, value_groups, strict=False):
        offset = 6 if q is not None else 0
        n_groups += sum(int(present[:, offset + np.asarray(idx)].all(axis=1).sum()) for _, idx in groups_here)
    thresholds = np.where(
        dof - k_all > 0, fdtri(k_test, np.maximum(dof - k_all, 1), 1 - alpha / max(n_groups, 1)), np.inf
    )
    labels = next((tuple(label for label, _ in g) for g in value_groups if len(g) == n_values), ())
    return PoseDiagnostics(statistic, pvalue, leverage, value_pvalue, labels, alpha, n_groups, thresholds)


def _noises(problem: Problem, noise: Any) -> tuple[NoiseModel, ...]:
    return session_noises(problem, noise)


def pose_diagnostics(
    result: IdentificationResult,
    data: Any = None,
    mask: Any = None,
    alpha: float = DEFAULT_ALPHA,
    noise: NoiseModel | Sequence[NoiseModel] | None = None,
    *,
    problem: Problem | None = None,
) -> PoseDiagnostics:
    """Outlier statistics of every observation (and value group) of a fit (see the module).

    Parameters
    ----------
    result : IdentificationResult
        The fit; its values are the linearisation point.
    data
        The data fitted (a session, sessions, or one full-pose data set).
    mask : array_like of bool, optional
        The varied parameters (as for :class:`Problem`).
    alpha : float
    noise : NoiseModel or one per session, optional
        With a noise model the test is the exact ``F(k, dof)`` one on the whitened
        residuals; without, the conservative threshold on the fit's own leg residuals.
    problem : Problem, optional
        The problem of the fit, replacing ``data`` and ``mask``.
    """
    if problem is None:
        problem = Problem(result.start, data, mask=mask)
    full = fit_values(problem, result)
    sessions = [
        p.session.replace(instrument=inst, label=p.label)
        for p, inst in zip(problem.parts, problem.instruments(full), strict=True)
    ]
    at = Problem(problem.geometry(full), sessions, parameters=problem.parameters.with_values(full))
    variant = result.method if result.method in ("length", "paper") else "length"
    return _diagnostics(at, noise, alpha, variant)


def fit_values(problem: Problem, result: Any) -> NDArray[np.float64]:
    """The full parameter vector of a fit of ``problem`` (its values in the varied slots)."""
    full = np.array(problem.full0)
    full[problem.mask] = np.asarray(result.values)
    return full


def _diagnostics(problem: Problem, noise: Any, alpha: float, variant: str = "length") -> PoseDiagnostics:
    """Deletion statistics at the problem's start values."""
    full = problem.full0
    if noise is None:
        r = problem.leg_residuals(full, variant)
        jac = problem.leg_jacobian(full, variant, scaled=False)
        present = np.ones(r.shape, dtype=bool)
        return block_diagnostics([(r, None, present)], jac, alpha, exact=False)
    noises = _noises(problem, noise)
    if problem.determines_pose:
        w = residual_weights(problem, full, noises)
        r = np.einsum("mij,mj->mi", w, problem.leg_residuals(full))
        a = problem.leg_jacobian(full, scaled=False).reshape(len(problem), 6, -1)
        jac = np.einsum("mij,mjk->mik", w, a).reshape(6 * len(problem), -1)
        return block_diagnostics([(r, None, np.ones(r.shape, dtype=bool))], jac, alpha, exact=True)
    from hexcal.estimation.likelihood import Projection

    inner = Projection(problem, noises)
    x0 = np.zeros(problem.n_free)
    evaluated = inner.evaluate(x0)
    blocks = []
    for part, (_, e, b) in zip(problem.parts, evaluated, strict=True):
        q, _ = np.linalg.qr(b)
        present = np.concatenate([np.ones((len(part), 6), dtype=bool), part.present], axis=1)
        blocks.append((e, q, present))
    from hexcal.estimation.gauge import complement_basis, gauge_freedoms

    jac = inner.jacobian(x0) @ complement_basis(gauge_freedoms(problem, full))
    groups = [part.instrument.value_groups() for part in problem.parts]
    return block_diagnostics(blocks, jac, alpha, exact=True, value_groups=groups)
