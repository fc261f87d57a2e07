"""The measurement noise learned from the data: variance component estimation.

The errors-in-variables equations of the ``ml`` estimator
(:meth:`hexcal.estimation.problem.Problem.observation_equations`) have one variance per
*group* of observations: the leg sensors (``σ_leg²``) and each group of the instrument (for
the full-pose model ``position`` and ``orientation``; a model's groups are the
:class:`~hexcal.core.noise.NoiseModel` fields its :meth:`covariance` depends on, so a new
instrument brings its groups with it). Helmert's variance component estimation in
Förstner's iterative form (Förstner 1979; Koch, *Parameter Estimation and Hypothesis Testing
in Linear Models*, 1999, ch. 3.6) alternates

1. the ML fit for the current variances, and
2. ``σ_g² ← σ_g² Ω_g / r_g``, with ``Ω_g`` the sum of the squared whitened residuals of
   group ``g`` and ``r_g`` its redundancy, the sum of ``1 - h_kk`` over its rows of the hat
   matrix of the linearised model (poses and parameters together),

until the variances no longer change. At convergence ``Ω_g = r_g`` for every group (the
reduced chi-square of every group is 1) and ``var(σ̂_g²) ≈ 2 σ_g⁴ / r_g`` (Gaussian
noise), so ``se(σ̂_g) ≈ σ_g / sqrt(2 r_g)``. A group whose variance falls to its floor
(:data:`NOISE_FLOORS`) is held there; a group with too little redundancy
(:data:`MIN_REDUNDANCY`) keeps its start value and is reported as not estimated.

The same ``Ω_g`` and ``r_g`` under a *given* noise model test it
(:func:`check_noise`): ``Ω_g`` follows approximately χ²(r_g), and ``sqrt(Ω_g / r_g)`` is
the ratio of the σ the data imply to the given one.

The estimated noise is a normal :class:`~hexcal.core.noise.NoiseModel` (standard
deviations): with uniform instrument errors of half-width ``a`` it reports ``a / sqrt(3)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.linalg import numerical_rank
from hexcal.core.noise import NoiseModel
from hexcal.errors import IdentificationError
from hexcal.estimation.problem import Problem

#: Smallest σ of each group (mm for lengths, rad for angles): a group with ~zero variance
#: (a simulated exact measurement) is held here instead of making the fit singular.
NOISE_FLOORS = {"leg": 1e-5, "position": 1e-5, "orientation": 1e-8}

#: A group with less redundancy than this keeps its start value (not estimated).
MIN_REDUNDANCY = 2.0

#: Units of each group's σ, for reports.
NOISE_UNITS = {"leg": "mm", "position": "mm", "orientation": "rad"}

_FIELDS = ("position", "orientation")


def instrument_groups(model: Any) -> tuple[str, ...]:
    """The :class:`NoiseModel` fields the model's instrument covariance depends on."""
    groups = []
    for name in _FIELDS:
        probe = NoiseModel(0.0, **{f: (1.0 if f == name else 0.0) for f in _FIELDS}, distribution="normal")
        if np.any(np.asarray(model.covariance(probe)) != 0):
            groups.append(name)
    return tuple(groups)


def noise_from_sigmas(groups: tuple[str, ...], sigmas: NDArray[np.float64]) -> NoiseModel:
    """A normal :class:`NoiseModel` with the σ of each group (``groups[0]`` is ``"leg"``)."""
    values = dict(zip(groups, np.asarray(sigmas, dtype=float).tolist(), strict=True))
    return NoiseModel(
        values.get("leg", 0.0),
        values.get("position", 0.0),
        values.get("orientation", 0.0),
        distribution="normal",
    )


@dataclass(frozen=True)
class GroupStatistics:
    """Whitened residual sums ``Ω_g`` and redundancies ``r_g`` of each group under a noise model."""

    groups: tuple[str, ...]
    omega: NDArray[np.float64]
    redundancy: NDArray[np.float64]
    helmert: NDArray[np.float64] | None = None

    @property
    def ratio(self) -> NDArray[np.float64]:
        """σ the data imply over the σ used, per group (``sqrt(Ω_g / r_g)``)."""
        return np.sqrt(self.omega / np.maximum(self.redundancy, 1e-300))


def _row_groups(problem: Problem, whitener: NDArray[np.float64], groups: tuple[str, ...]) -> NDArray[np.intp]:
    """Group index of every whitened row (6 legs then the instrument), ``(6 + k,)``; -1 where a
    row mixes groups (a full instrument covariance)."""
    model = problem.model
    comp = np.full(model.size, -1, dtype=np.intp)
    for g, name in enumerate(groups[1:], start=1):
        probe = NoiseModel(0.0, **{f: (1.0 if f == name else 0.0) for f in _FIELDS}, distribution="normal")
        comp[np.diag(np.asarray(model.covariance(probe))) != 0] = g
    # a row may mix components of one group (eigenvectors of a repeated variance), not two
    nonzero = np.abs(whitener) > 1e-9 * np.max(np.abs(whitener), axis=1, keepdims=True)
    lo = np.min(np.where(nonzero, comp, np.iinfo(np.intp).max), axis=1)
    hi = np.max(np.where(nonzero, comp, -1), axis=1)
    inst = np.where((lo == hi) & (lo >= 0), hi, -1)
    return np.concatenate([np.zeros(6, dtype=np.intp), inst])


def _statistics(
    problem: Problem, inner: Any, x: NDArray[np.float64], groups: tuple[str, ...]
) -> tuple[GroupStatistics, NDArray[np.float64], NDArray[np.float64]]:
    """Group statistics at solver variables ``x``, and the Gauss–Newton data ``(e, J)``."""
    _, e, b = inner.evaluate(x)
    proj = inner.jacobian(x)
    q, _ = np.linalg.qr(b)
    h = np.sum(q**2, axis=2)  # (m, 6 + k): the pose part of the hat matrix
    u, sv, _ = np.linalg.svd(proj, full_matrices=False)
    rank = numerical_rank(sv)
    h = h + np.sum(u[:, :rank] ** 2, axis=1).reshape(h.shape)
    present = np.concatenate([np.ones((len(problem), 6), dtype=bool), problem.present], axis=1)
    r = np.where(present, 1.0 - h, 0.0)
    rows = _row_groups(problem, inner.whitener, groups)
    if np.any(rows < 0):  # a full instrument covariance: one instrument group
        groups = (groups[0], "instrument")
        rows = np.where(rows < 0, 1, rows)
    ng = len(groups)
    omega = np.array([np.sum(e[:, rows == g] ** 2) for g in range(ng)])
    red = np.array([np.sum(r[:, rows == g]) for g in range(ng)])
    # Helmert's matrix M_gk = tr(R D_g R D_k), R = I - H, H = P (pose blocks) + G (= U Uᵀ):
    # tr(D_g D_k) - 2 tr(D_g H D_k) + sum over g x k of H_il², with H² summed blockwise
    # for P and the cross term, and as tr(U_gᵀU_g U_kᵀU_k) for G
    ub = u[:, :rank].reshape(len(problem), -1, rank)
    p_blk = np.einsum("mik,mlk->mil", q, q)
    g_blk = np.einsum("mik,mlk->mil", ub, ub)
    sq = (p_blk + g_blk) ** 2 - g_blk**2
    onehot = rows[:, None] == np.arange(ng)  # (6 + k, ng)
    w = present[..., None] & onehot[None]  # (m, 6 + k, ng)
    wf = w.astype(float)
    block = np.einsum("mig,mil,mlk->gk", wf, sq, wf)
    grams = np.einsum("mig,mia,mib->gab", wf, ub, ub)  # U_gᵀ U_g
    full = np.einsum("gab,kba->gk", grams, grams)  # tr(U_gᵀU_g U_kᵀU_k)
    counts = w.sum(axis=(0, 1)).astype(float)
    hsum = np.array([np.sum(np.where(w[..., g], h, 0.0)) for g in range(ng)])
    helmert = np.diag(counts - 2 * hsum) + block + full
    return GroupStatistics(groups, omega, red, helmert), e.ravel(), proj


def _solver_variables(problem: Problem, result: Any) -> NDArray[np.float64]:
    return (np.asarray(result.values) - problem.full0[problem.mask]) / problem.scale


def group_statistics(problem: Problem, noise: NoiseModel, result: Any) -> GroupStatistics:
    """``Ω_g`` and ``r_g`` of each noise group at the solution of a fit.

    Parameters
    ----------
    problem : Problem
    noise : NoiseModel
        The noise model the residuals are whitened with.
    result : IdentificationResult
        A fit of ``problem`` (its parameter values are used).
    """
    from hexcal.estimation.likelihood import PoseProjection

    groups = ("leg", *instrument_groups(problem.model))
    inner = PoseProjection(problem, noise)
    return _statistics(problem, inner, _solver_variables(problem, result), groups)[0]


def _helmert_ratio(stats: GroupStatistics, estimated: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Helmert's update ``α = M⁻¹ Ω`` of the variance ratios (``σ_new = sqrt(α) σ``); a
    negative ratio (a group with no noise) is 0, floored by the caller."""
    ratio = np.ones(len(stats.groups))
    if stats.helmert is None:
        return stats.ratio
    sub = stats.helmert[np.ix_(estimated, estimated)]
    alpha = np.linalg.lstsq(sub, stats.omega[estimated], rcond=None)[0]
    ratio[estimated] = np.sqrt(np.maximum(alpha, 0.0))
    return ratio


@dataclass(frozen=True)
class NoiseEstimate:
    """Noise σ of each group learned from the data, with their standard errors.

    Attributes
    ----------
    groups : tuple of str
        ``("leg", "position", "orientation")`` for the full-pose model.
    sigmas, stderr : ndarray, shape (g,)
        σ and its standard error (mm for lengths, rad for angles).
    redundancy : ndarray, shape (g,)
        Redundancy numbers ``r_g`` (the degrees of freedom of each group).
    estimated : ndarray of bool, shape (g,)
        False where the redundancy was too small (the start value was kept).
    floored : ndarray of bool, shape (g,)
        True where the σ fell to its floor (:data:`NOISE_FLOORS`).
    iterations : int
    converged : bool
    """

    groups: tuple[str, ...]
    sigmas: NDArray[np.float64]
    stderr: NDArray[np.float64]
    redundancy: NDArray[np.float64]
    estimated: NDArray[np.bool_]
    floored: NDArray[np.bool_]
    iterations: int
    converged: bool

    @property
    def noise(self) -> NoiseModel:
        """The estimated noise as a normal :class:`NoiseModel` (standard deviations)."""
        return noise_from_sigmas(self.groups, self.sigmas)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: ``{group: {"sigma", "stderr", "redundancy", "estimated", "floored", "unit"}}``."""
        out: dict[str, Any] = {
            g: {
                "sigma": float(self.sigmas[k]),
                "stderr": float(self.stderr[k]),
                "redundancy": float(self.redundancy[k]),
                "estimated": bool(self.estimated[k]),
                "floored": bool(self.floored[k]),
                "unit": NOISE_UNITS.get(g, ""),
            }
            for k, g in enumerate(self.groups)
        }
        out["iterations"], out["converged"] = self.iterations, self.converged
        return out


def estimate_noise(
    problem: Problem,
    start: NoiseModel | None = None,
    max_iter: int = 40,
    rtol: float = 1e-3,
    **options: Any,
) -> tuple[NoiseEstimate, Any]:
    """Variance components of the noise groups, iterated with the ``ml`` fit to convergence.

    Parameters
    ----------
    problem : Problem
    start : NoiseModel, optional
        Start values (default the seed paper's noise).
    max_iter : int
        Fit ↔ variance-component iterations at most.
    rtol : float
        Stop when no σ changes by more than this fraction.
    **options
        Passed to :func:`hexcal.estimation.likelihood.fit_ml`.

    Returns
    -------
    (NoiseEstimate, IdentificationResult)
        The noise and the ``ml`` fit under it.

    >>> from hexcal.core.presets import preset
    >>> from hexcal.core.workspace import workspace_corners
    >>> from hexcal.estimation.bounds import planned_measurements
    >>> nominal, real = preset("paper-hmt"), preset("paper-hmt-true")
    >>> rng = np.random.default_rng(1)
    >>> data = planned_measurements(real, workspace_corners(nominal))
    >>> data = type(data)(data.poses + rng.normal(0, [0.02] * 3 + [3e-4] * 3, (64, 6)), data.readings)
    >>> est, fit = estimate_noise(Problem(nominal, data))
    >>> bool(0.7 < est.sigmas[1] / 0.02 < 1.3), bool(0.7 < est.sigmas[2] / 3e-4 < 1.3)
    (True, True)
    """
    from hexcal.estimation.likelihood import PoseProjection, fit_ml

    start = NoiseModel() if start is None else start
    groups = ("leg", *instrument_groups(problem.model))
    sig_all = dict(zip(("leg", "position", "orientation"), start.sigmas, strict=True))
    floors = np.array([NOISE_FLOORS.get(g, 1e-8) for g in groups])
    sigmas = np.maximum(np.array([sig_all[g] for g in groups]), floors)
    # one converged fit, then Gauss–Newton steps of the parameters interleaved with the
    # variance-component updates (each step is one pose projection, not a whole fit)
    x = _solver_variables(problem, fit_ml(problem, noise_from_sigmas(groups, sigmas), **options))
    poses = None
    converged, it = False, 0
    while it < max_iter:
        it += 1
        inner = PoseProjection(problem, noise_from_sigmas(groups, sigmas))
        if poses is not None:
            inner.poses = poses
        stats, e, jac = _statistics(problem, inner, x, groups)
        if stats.groups != groups:
            raise IdentificationError("variance components need a diagonal instrument covariance")
        poses = inner.poses
        step = np.linalg.lstsq(jac, e, rcond=None)[0]
        x = x - step
        estimated = stats.redundancy >= MIN_REDUNDANCY
        new = np.where(estimated, np.maximum(sigmas * _helmert_ratio(stats, estimated), floors), sigmas)
        change = float(np.max(np.abs(new / sigmas - 1)))
        sigmas = new
        if change < rtol and float(np.max(np.abs(step), initial=0.0)) < 1e-6:
            converged = True
            break
    noise = noise_from_sigmas(groups, sigmas)
    result = fit_ml(problem, noise, **options)
    stats = group_statistics(problem, noise, result)
    red = stats.redundancy
    estimated = red >= MIN_REDUNDANCY
    stderr = np.full(len(groups), np.nan)
    if stats.helmert is not None and estimated.any():
        # var(α̂) = 2 M⁻¹ for the variance ratios α (Gaussian noise); σ = sqrt(α) σ₀
        sub = stats.helmert[np.ix_(estimated, estimated)]
        var_alpha = 2 * np.diag(np.linalg.pinv(sub))
        stderr[estimated] = sigmas[estimated] * np.sqrt(np.maximum(var_alpha, 0.0)) / 2
    floored = sigmas <= floors * (1 + 1e-9)
    estimate = NoiseEstimate(groups, sigmas, stderr, red, estimated, floored, it, converged)
    return estimate, result.replace(noise=noise)


@dataclass(frozen=True)
class NoiseCheck:
    """A given noise model tested against the data, per group.

    Attributes
    ----------
    groups : tuple of str
    given : ndarray, shape (g,)
        σ of the given model (mm, rad).
    ratio : ndarray, shape (g,)
        σ the data imply over the given σ.
    redundancy : ndarray, shape (g,)
    p_value : ndarray, shape (g,)
        Two-sided p-value of ``Ω_g`` against χ²(r_g).
    alpha : float
    """

    groups: tuple[str, ...]
    given: NDArray[np.float64]
    ratio: NDArray[np.float64]
    redundancy: NDArray[np.float64]
    p_value: NDArray[np.float64]
    alpha: float

    @property
    def disagree(self) -> tuple[str, ...]:
        """Groups whose σ the data reject at level ``alpha`` (Bonferroni over the groups)."""
        bad = (self.p_value < self.alpha / len(self.groups)) & (self.redundancy >= MIN_REDUNDANCY)
        return tuple(g for g, b in zip(self.groups, bad, strict=True) if b)

    def describe(self) -> str:
        """One line: the groups that disagree and by how much."""
        if not self.disagree:
            return "the given noise agrees with the data"
        parts = []
        for g in self.disagree:
            k = self.groups.index(g)
            unit = NOISE_UNITS.get(g, "")
            parts.append(
                f"{g} σ {self.given[k] * self.ratio[k]:.3g} {unit} from the data, "
                f"{self.given[k]:.3g} {unit} given (× {self.ratio[k]:.3g})"
            )
        return "; ".join(parts)

    def to_dict(self) -> dict[str, Any]:
        return {
            g: {
                "given": float(self.given[k]),
                "ratio": float(self.ratio[k]),
                "redundancy": float(self.redundancy[k]),
                "p_value": float(self.p_value[k]),
                "disagrees": g in self.disagree,
            }
            for k, g in enumerate(self.groups)
        }


def check_noise(problem: Problem, noise: NoiseModel, result: Any, alpha: float = 0.01) -> NoiseCheck:
    """Test a given noise model against the data at the solution ``result`` of an ``ml`` fit
    under it: per group ``Ω_g ~ χ²(r_g)``, two-sided."""
    from scipy.special import chdtr

    stats = group_statistics(problem, noise, result)
    sig_all = dict(zip(("leg", "position", "orientation"), noise.sigmas, strict=True))
    given = np.array([sig_all.get(g, np.nan) for g in stats.groups])
    red = np.maximum(stats.redundancy, 1e-9)
    cdf = chdtr(red, stats.omega)
    p = np.clip(2 * np.minimum(cdf, 1 - cdf), 0.0, 1.0)
    return NoiseCheck(stats.groups, given, stats.ratio, stats.redundancy, p, alpha)
