"""Outliers of instrument data: a single target observation, or a whole pose.

At the maximum-likelihood solution each observation ``j`` has whitened residuals ``e_j``
(legs and instrument values), the pose Jacobian ``B_j`` (orthonormal basis ``Q_j``) and the
projected parameter Jacobian (gauge directions removed, orthonormal basis ``U``). The
linearised model with the poses as unknowns has the hat matrix blocks
``H_j = Q_j Q_jᵀ + U_j U_jᵀ`` (the two column spaces are orthogonal). Deleting a group ``R`` of
residuals changes the residual sum of squares by ``δ = e_Rᵀ (I - H_RR)⁻¹ e_R`` (for a whole pose,
in the coordinates orthogonal to ``B_j``, since the pose goes with it), and

    F = (δ / k) / ((SSE - δ) / (dof - k))

follows ``F(k, dof - k)`` for ``k`` independent residuals in the group (Cook & Weisberg 1982).
Groups: every target observation (``k = 3``) and every pose (``k`` its instrument values); the
threshold is Bonferroni-corrected over all groups tested. :func:`identify_instrument_robust`
removes the most significant group and refits until none is left.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.noise import NoiseModel
from hexcal.estimation.gauge import complement_basis, gauge_freedoms
from hexcal.estimation.instrument import InstrumentResult, identify_instrument, instrument_parameters
from hexcal.estimation.likelihood import PoseProjection
from hexcal.estimation.problem import Problem
from hexcal.estimation.robust import DEFAULT_ALPHA, MAX_LEVERAGE
from hexcal.instruments.instrument_data import instrument_model
from hexcal.instruments.setup import Setup
from hexcal.instruments.targets import TargetMeasurements


@dataclass(frozen=True)
class InstrumentDiagnostics:
    """Deletion statistics of poses and target observations.

    Attributes
    ----------
    pose_pvalue : ndarray, shape (m,)
        Tail probability of each pose's ``F`` (NaN where it cannot be checked).
    target_pvalue : ndarray, shape (m, n)
        Same per target observation (NaN where not seen, and for tool data).
    alpha : float
        Family-wise false alarm rate; a group is flagged when its p-value is below
        ``alpha / groups``.
    groups : int
    """

    pose_pvalue: NDArray[np.float64]
    target_pvalue: NDArray[np.float64]
    alpha: float
    groups: int

    @property
    def limit(self) -> float:
        return self.alpha / max(self.groups, 1)

    def worst(self) -> tuple[str, int, int] | None:
        """The most significant flagged group: ``("pose", j, -1)`` or ``("target", j, i)``, or None."""
        pose = np.where(np.isfinite(self.pose_pvalue), self.pose_pvalue, np.inf)
        tgt = np.where(np.isfinite(self.target_pvalue), self.target_pvalue, np.inf)
        jp = int(np.argmin(pose)) if pose.size else -1
        jt = np.unravel_index(int(np.argmin(tgt)), tgt.shape) if tgt.size else (-1, -1)
        p_pose = pose[jp] if jp >= 0 else np.inf
        p_tgt = tgt[jt] if tgt.size else np.inf
        if min(p_pose, p_tgt) >= self.limit:
            return None
        # a lone bad target also makes its pose look bad: prefer the smaller deletion
        if p_tgt <= p_pose * 10:
            return ("target", int(jt[0]), int(jt[1]))
        return ("pose", jp, -1)


def _fpvalue(stat: NDArray, k: NDArray | int, dof: NDArray | int) -> NDArray[np.float64]:
    from scipy.special import fdtrc  # not scipy.stats: slow to import

    return fdtrc(k, dof, np.maximum(stat, 0.0))


def instrument_diagnostics(
    out: InstrumentResult,
    data: Any,
    noise: NoiseModel,
    fit: str | Sequence[str] | None = None,
    fix: Iterable[str] = (),
    alpha: float = DEFAULT_ALPHA,
) -> InstrumentDiagnostics:
    """Deletion statistics of every pose and target observation at an identification's solution."""
    setup = out.setup
    params = instrument_parameters(out.geometry, setup, fit, fix)
    problem = Problem(out.geometry, data, instrument_model(setup), parameters=params)
    inner = PoseProjection(problem, noise)
    x0 = np.zeros(problem.n_free)
    _, e, b = inner.evaluate(x0)
    gauge = gauge_freedoms(problem, problem.full0)
    ap = inner.jacobian(x0) @ complement_basis(gauge)
    m, rows = e.shape
    u, sv, _ = np.linalg.svd(ap / np.linalg.norm(ap, axis=0), full_matrices=False)
    u = u[:, sv > 1e-10 * sv[0]].reshape(m, rows, -1)
    q, _ = np.linalg.qr(b, mode="complete")
    qb, comp = q[:, :, :6], q[:, :, 6:]
    hat = qb @ qb.transpose(0, 2, 1) + u @ u.transpose(0, 2, 1)
    counts = problem.present.sum(axis=1)
    sse, dof = float(np.sum(e**2)), int(counts.sum()) - u.shape[-1]
    # whole poses, in the coordinates orthogonal to the pose directions
    rt = np.einsum("mrk,mr->mk", comp, e)
    ht = comp.transpose(0, 2, 1) @ hat @ comp
    eye = np.eye(rows - 6)
    lev = np.linalg.eigvalsh(ht)[:, -1]
    safe = np.where((lev < MAX_LEVERAGE)[:, None, None], ht, 0.0)
    delta = np.einsum("mk,mk->m", rt, np.linalg.solve(eye - safe, rt[..., None])[..., 0])
    k_pose = np.maximum(counts, 1)
    stat = (delta / k_pose) / (np.maximum(sse - delta, 1e-300) / np.maximum(dof - k_pose, 1))
    pose_p = np.where((lev < MAX_LEVERAGE) & (dof - k_pose > 0), _fpvalue(stat, k_pose, dof - k_pose), np.nan)
    groups = m
    target_p = np.full((m, 0), np.nan)
    if isinstance(data, TargetMeasurements):
        n = problem.model.n_targets
        target_p = np.full((m, n), np.nan)
        seen = data.seen
        for i in range(n):  # loop over targets, vectorised over poses
            r = slice(6 + 3 * i, 9 + 3 * i)
            h = hat[:, r, r]
            er = e[:, r]
            lev_t = np.linalg.eigvalsh(h)[:, -1]
            ok = seen[:, i] & (lev_t < MAX_LEVERAGE) & (counts > 3)
            if not ok.any():
                continue
            d = np.einsum("mk,mk->m", er[ok], np.linalg.solve(np.eye(3) - h[ok], er[ok][..., None])[..., 0])
            st = (d / 3) / (np.maximum(sse - d, 1e-300) / max(dof - 3, 1))
            target_p[ok, i] = _fpvalue(st, 3, max(dof - 3, 1))
        groups += int(seen.sum())
    return InstrumentDiagnostics(pose_p, target_p, alpha, groups)


@dataclass(frozen=True, eq=False)
class RobustInstrumentResult:
    """Identification with outliers left out: the final fit, the outliers (``"pose 7"`` or
    ``"pose 7 target t2"``) and the kept data."""

    fit: InstrumentResult
    outliers: tuple[str, ...]
    data: Any
    diagnostics: InstrumentDiagnostics


def _without(data: Any, kind: str, j: int, i: int) -> Any:
    if kind == "pose":
        return data.subset(np.delete(np.arange(len(data)), j))
    targets = np.array(data.targets)
    targets[j, i] = np.nan
    if np.isnan(targets[j]).all():
        return data.subset(np.delete(np.arange(len(data)), j))
    return TargetMeasurements(data.readings, targets, data.names, data.ids)


def identify_instrument_robust(
    start: Any,
    data: Any,
    setup: Setup,
    noise: NoiseModel | None = None,
    fit: str | Sequence[str] | None = None,
    fix: Iterable[str] = (),
    alpha: float = DEFAULT_ALPHA,
    max_outliers: int | None = None,
) -> RobustInstrumentResult:
    """:func:`~hexcal.estimation.instrument.identify_instrument`, leaving out the most
    significant outlier (one target observation, or one whole pose) and refitting until no
    group is flagged (at most ``max_outliers``, default a tenth of the poses)."""
    noise = NoiseModel() if noise is None else noise
    limit = max(1, len(data) // 10) if max_outliers is None else max_outliers
    outliers: list[str] = []
    out = identify_instrument(start, data, setup, noise, fit, fix)
    diag = instrument_diagnostics(out, data, noise, fit, fix, alpha)
    while len(outliers) < limit:
        worst = diag.worst()
        if worst is None:
            break
        kind, j, i = worst
        label = f"pose {data.ids[j]}" + (f" target {data.names[i]}" if kind == "target" else "")
        outliers.append(label)
        data = _without(data, kind, j, i)
        out = identify_instrument(start, data, setup, noise, fit, fix)
        diag = instrument_diagnostics(out, data, noise, fit, fix, alpha)
    result = out.result.replace(outliers=tuple(outliers))
    fitted = InstrumentResult(
        result, out.setup, out.registration, out.gauges, out.convention, out.unidentifiable, out.poses
    )
    return RobustInstrumentResult(fitted, tuple(outliers), data, diag)
