"""The measurement noise learned from the data: variance component estimation.

The errors-in-variables equations of the ``ml`` estimator
(:meth:`hexcal.estimation.problem.Problem.observation_equations`) have one variance per
*group* of observations and per session: the leg sensors (``σ_leg²``) and each group of the
session's instrument (for a pose instrument ``position`` and ``orientation``, for targets
their positions; an instrument's groups are the :class:`~hexcal.core.noise.NoiseModel`
fields its covariance depends on, so a new instrument brings its groups with it). Each
session has its own groups: an instrument moved, or another instrument, has its own noise.
Helmert's variance component estimation in Förstner's iterative form (Förstner 1979; Koch,
*Parameter Estimation and Hypothesis Testing in Linear Models*, 1999, ch. 3.6) alternates

1. the ML fit for the current variances, and
2. ``σ_g² ← σ_g² Ω_g / r_g``, with ``Ω_g`` the sum of the squared whitened residuals of
   group ``g`` and ``r_g`` its redundancy, the sum of ``1 - h_kk`` over its rows of the hat
   matrix of the linearised model (poses and parameters together),

until the variances no longer change. At convergence ``Ω_g = r_g`` for every group (the
reduced chi-square of every group is 1) and ``var(σ̂_g²) ≈ 2 σ_g⁴ / r_g`` (Gaussian
noise), so ``se(σ̂_g) ≈ σ_g / sqrt(2 r_g)``. A group whose variance falls to its floor
(:data:`NOISE_FLOORS`) is held there. A group these data cannot determine is held at its
*fallback* (the noise its instrument declares, or the typical noise of its kind: the caller
says, :mod:`hexcal.instruments.known_noise`; the start value when none is given) and reported
as not estimated: a group with too little redundancy (:data:`MIN_REDUNDANCY`), and one the
others' noise hides, which drifts towards zero while the parameters stand
(:data:`DRIFT_STEPS`). The other groups are then iterated to convergence with it held, so
the figures do not depend on where an iteration happened to stop.

The same ``Ω_g`` and ``r_g`` under a *given* noise model test it
(:func:`hexcal.estimation.noise_check.check_noise`).

The estimated noise is a normal :class:`~hexcal.core.noise.NoiseModel` (standard
deviations): with uniform instrument errors of half-width ``a`` it reports ``a / sqrt(3)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.linalg import numerical_rank
from hexcal.core.noise import NoiseModel
from hexcal.errors import HexcalError, IdentificationError
from hexcal.estimation.problem import Problem

#: Smallest σ of each group (mm for lengths, rad for angles): a group with ~zero variance
#: (a simulated exact measurement) is held here instead of making the fit singular.
NOISE_FLOORS = {"leg": 1e-5, "position": 1e-5, "orientation": 1e-8}

#: A group with less redundancy than this keeps its start value (not estimated).
MIN_REDUNDANCY = 2.0

#: A step that keeps more than this share of a σ is a slow fall (a hidden group's creep).
SLOW_FALL = 0.5

#: Steps in a row a group's σ falls slowly, parameters settled and redundancy below DRIFT_REDUNDANCY
#: (a group the data see converges, however slowly), before it counts as not determined.
DRIFT_STEPS, DRIFT_REDUNDANCY = 5, 20.0

#: Units of each group's σ, for reports.
NOISE_UNITS = {"leg": "mm", "position": "mm", "orientation": "rad", "instrument": ""}

_FIELDS = ("position", "orientation")


def instrument_groups(model: Any) -> tuple[str, ...]:
    """The :class:`NoiseModel` fields the instrument's covariance depends on."""
    return model.noise_groups()


def problem_groups(problem: Problem) -> tuple[tuple[int, str], ...]:
    """The noise groups of a problem: ``(session index, field)``, legs first in each session."""
    return tuple(
        (k, name) for k, part in enumerate(problem.parts) for name in ("leg", *part.instrument.noise_groups())
    )


def noise_from_sigmas(groups: tuple[str, ...], sigmas: NDArray[np.float64]) -> NoiseModel:
    """A normal :class:`NoiseModel` with the σ of each group (``groups[0]`` is ``"leg"``)."""
    values = dict(zip(groups, np.asarray(sigmas, dtype=float).tolist(), strict=True))
    return NoiseModel(
        values.get("leg", 0.0),
        values.get("position", 0.0),
        values.get("orientation", 0.0),
        distribution="normal",
    )


def _session_noises(
    groups: tuple[tuple[int, str], ...], sigmas: NDArray[np.float64], sessions: int
) -> tuple[NoiseModel, ...]:
    return tuple(
        noise_from_sigmas(
            tuple(name for s, name in groups if s == k),
            np.array([v for (s, _), v in zip(groups, sigmas, strict=True) if s == k]),
        )
        for k in range(sessions)
    )


def group_label(problem: Problem, group: tuple[int, str]) -> str:
    """How reports name a group: ``leg``, ``position``, ``targets``..., with the session's
    label when the problem has several."""
    k, name = group
    part = problem.parts[k]
    label = part.instrument.group_labels().get(name, name)
    return f"{part.label} {label}" if len(problem.parts) > 1 else label


@dataclass(frozen=True)
class GroupStatistics:
    """Whitened residual sums ``Ω_g`` and redundancies ``r_g`` of each group under a noise model."""

    groups: tuple[str, ...]
    omega: NDArray[np.float64]
    redundancy: NDArray[np.float64]
    helmert: NDArray[np.float64] | None = None
    keys: tuple[tuple[int, str], ...] = ()

    @property
    def ratio(self) -> NDArray[np.float64]:
        """σ the data imply over the σ used, per group (``sqrt(Ω_g / r_g)``)."""
        return np.sqrt(self.omega / np.maximum(self.redundancy, 1e-300))


def _row_groups(part: Any, whitener: NDArray[np.float64], ids: dict[str, int], leg: int) -> NDArray[np.intp]:
    """Group index of every whitened row of a session (6 legs then the instrument), ``(6 + k,)``;
    -1 where a row mixes groups (a full instrument covariance)."""
    model = part.instrument
    comp = np.full(model.size, -1, dtype=np.intp)
    for name, g in ids.items():
        probe = NoiseModel(0.0, **{f: (1.0 if f == name else 0.0) for f in _FIELDS}, distribution="normal")
        comp[np.diag(np.asarray(model.covariance(probe))) != 0] = g
    # a row may mix components of one group (eigenvectors of a repeated variance), not two
    nonzero = np.abs(whitener) > 1e-9 * np.max(np.abs(whitener), axis=1, keepdims=True)
    lo = np.min(np.where(nonzero, comp, np.iinfo(np.intp).max), axis=1)
    hi = np.max(np.where(nonzero, comp, -1), axis=1)
    inst = np.where((lo == hi) & (lo >= 0), hi, -1)
    return np.concatenate([np.full(6, leg, dtype=np.intp), inst])


def _statistics(
    problem: Problem, inner: Any, x: NDArray[np.float64], keys: tuple[tuple[int, str], ...]
) -> tuple[GroupStatistics, NDArray[np.float64], NDArray[np.float64]]:
    """Group statistics at solver variables ``x``, and the Gauss–Newton data ``(e, J)``."""
    evaluated = inner.evaluate(x)
    proj = inner.jacobian(x)
    u, sv, _ = np.linalg.svd(proj, full_matrices=False)
    rank = numerical_rank(sv)
    u = u[:, :rank]
    index = {key: g for g, key in enumerate(keys)}
    ng = len(keys)
    omega, red = np.zeros(ng), np.zeros(ng)
    block, grams = np.zeros((ng, ng)), np.zeros((ng, rank, rank))
    counts, hsum = np.zeros(ng), np.zeros(ng)
    mixed = False
    row = 0
    for k, (part, (_, e, _), pp) in enumerate(zip(problem.parts, evaluated, inner.parts, strict=True)):
        m, r = e.shape
        q = pp.basis(x)  # the projected Jacobian's (no second factorisation)
        ub = u[row : row + m * r].reshape(m, r, rank)
        row += m * r
        h = np.sum(q**2, axis=2) + np.sum(ub**2, axis=2)  # (m, 6 + k): the hat matrix diagonal
        present = np.concatenate([np.ones((m, 6), dtype=bool), part.present], axis=1)
        own = {name: index[(k, name)] for name in part.instrument.noise_groups()}
        rows = _row_groups(part, pp.whitener, own, index[(k, "leg")])
        if np.any(rows < 0):  # a full instrument covariance: one instrument group
            mixed = True
            break
        onehot = rows[:, None] == np.arange(ng)  # (6 + k, ng)
        w = present[..., None] & onehot[None]  # (m, 6 + k, ng)
        wf = w.astype(float)
        flat = wf.reshape(m * r, ng)
        omega += flat.T @ (e**2).ravel()
        red += flat.T @ (1.0 - h).ravel()
        # Helmert's matrix M_gk = tr(R D_g R D_k), R = I - H, H = P (pose blocks) + G (= U Uᵀ):
        # tr(D_g D_k) - 2 tr(D_g H D_k) + sum over g x k of H_il², with H² summed blockwise
        # for P and the cross term, and as tr(U_gᵀU_g U_kᵀU_k) for G (matrix products: BLAS)
        p_blk = np.matmul(q, q.transpose(0, 2, 1))
        g_blk = np.matmul(ub, ub.transpose(0, 2, 1))
        sq = (p_blk + g_blk) ** 2 - g_blk**2
        block += flat.T @ np.matmul(sq, wf).reshape(m * r, ng)
        rows_u = ub.reshape(m * r, rank)
        for g in np.flatnonzero(flat.any(axis=0)):  # U_gᵀ U_g of the rows of each group
            own = rows_u[flat[:, g] > 0]
            grams[g] += own.T @ own
        counts += w.sum(axis=(0, 1))
        hsum += flat.T @ h.ravel()
    if mixed:
        return _mixed_statistics(problem, evaluated, u, keys), inner.residuals(x), proj
    full = grams.reshape(ng, -1) @ grams.transpose(0, 2, 1).reshape(ng, -1).T  # tr(U_gᵀU_g U_kᵀU_k)
    helmert = np.diag(counts - 2 * hsum) + block + full
    labels = tuple(group_label(problem, key) for key in keys)
    return GroupStatistics(labels, omega, red, helmert, keys), inner.residuals(x), proj


def _mixed_statistics(problem: Problem, evaluated: list, u: NDArray, keys: tuple) -> GroupStatistics:
    """Legs and one instrument group per session (a full instrument covariance mixes its rows)."""
    groups, omega, red = [], [], []
    row = 0
    for k, (part, (_, e, b)) in enumerate(zip(problem.parts, evaluated, strict=True)):
        m, r = e.shape
        q, _ = np.linalg.qr(b)
        ub = u[row : row + m * r].reshape(m, r, -1)
        row += m * r
        h = np.sum(q**2, axis=2) + np.sum(ub**2, axis=2)
        present = np.concatenate([np.ones((m, 6), dtype=bool), part.present], axis=1)
        res = np.where(present, 1.0 - h, 0.0)
        for label, cols in (("leg", slice(0, 6)), ("instrument", slice(6, r))):
            groups.append((k, label))
            omega.append(float(np.sum(e[:, cols] ** 2)))
            red.append(float(np.sum(res[:, cols])))
    labels = tuple(group_label(problem, key) for key in groups)
    return GroupStatistics(labels, np.array(omega), np.array(red), None, tuple(groups))


def _solver_variables(problem: Problem, result: Any) -> NDArray[np.float64]:
    return (np.asarray(result.values) - problem.full0[problem.mask]) / problem.scale


def group_statistics(
    problem: Problem, noise: NoiseModel | Sequence[NoiseModel], result: Any
) -> GroupStatistics:
    """``Ω_g`` and ``r_g`` of each noise group at the solution of a fit.

    Parameters
    ----------
    problem : Problem
    noise : NoiseModel or one per session
        The noise model the residuals are whitened with.
    result : IdentificationResult
        A fit of ``problem`` (its parameter values are used).
    """
    from hexcal.estimation.likelihood import Projection

    inner = Projection(problem, noise)
    return _statistics(problem, inner, _solver_variables(problem, result), problem_groups(problem))[0]


#: Largest change of a σ in one variance-component step (a factor either way).
_MAX_RATIO = 10.0


def _helmert_ratio(stats: GroupStatistics, estimated: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Helmert's update ``α = M⁻¹ Ω`` of the variance ratios (``σ_new = sqrt(α) σ``), at most
    a factor :data:`_MAX_RATIO` either way per step.

    Where it gives a group a negative (or no finite) variance, the step is Förstner's
    ``σ_new² = σ² Ω_g / r_g`` instead: positive, with the same fixed point (``Ω_g = r_g``). A
    gross error makes the Helmert step negative for the group that does not hold it (the legs,
    when one target observation is 1.5 mm off); held at its floor, that group then made the fit
    singular and the iteration diverge. The clip keeps a group with no noise at all falling to its
    floor geometrically instead of in one step, from where the next step would overshoot."""
    ratio = np.ones(len(stats.groups))
    if stats.helmert is None:
        return stats.ratio
    sub = stats.helmert[np.ix_(estimated, estimated)]
    alpha = np.linalg.lstsq(sub, stats.omega[estimated], rcond=None)[0]
    if not np.all(np.isfinite(alpha)) or np.any(alpha <= 0):
        alpha = stats.omega[estimated] / stats.redundancy[estimated]
    ratio[estimated] = np.sqrt(np.clip(alpha, 1 / _MAX_RATIO**2, _MAX_RATIO**2))
    return ratio


@dataclass(frozen=True)
class NoiseEstimate:
    """Noise σ of each group learned from the data, with their standard errors.

    Attributes
    ----------
    groups : tuple of str
        ``("leg", "position", "orientation")`` for one full-pose session (with the session's
        label in front when there are several).
    sigmas, stderr : ndarray, shape (g,)
        σ and its standard error (mm for lengths, rad for angles).
    redundancy : ndarray, shape (g,)
        Redundancy numbers ``r_g`` (the degrees of freedom of each group).
    estimated : ndarray of bool, shape (g,)
        False where these data do not determine the group (held at its fallback).
    floored : ndarray of bool, shape (g,)
        True where the σ fell to its floor (:data:`NOISE_FLOORS`).
    iterations : int
    converged : bool
    keys : tuple of (int, str)
        ``(session, field)`` of every group.
    """

    groups: tuple[str, ...]
    sigmas: NDArray[np.float64]
    stderr: NDArray[np.float64]
    redundancy: NDArray[np.float64]
    estimated: NDArray[np.bool_]
    floored: NDArray[np.bool_]
    iterations: int
    converged: bool
    keys: tuple[tuple[int, str], ...] = field(default=())
    hidden: NDArray[np.bool_] | None = None

    @property
    def hidden_groups(self) -> NDArray[np.bool_]:
        """True where the others' noise hides a group with enough redundancy (it fell towards 0
        while the parameters stood): held at its fallback, like one with too little redundancy."""
        return np.zeros(len(self.groups), dtype=bool) if self.hidden is None else self.hidden

    @property
    def noises(self) -> tuple[NoiseModel, ...]:
        """The estimated noise of each session as normal :class:`NoiseModel` objects."""
        sessions = 1 + max((k for k, _ in self.keys), default=0)
        return _session_noises(self.keys, self.sigmas, sessions)

    @property
    def noise(self) -> NoiseModel:
        """The estimated noise of the first session (standard deviations)."""
        return self.noises[0]

    def units(self) -> tuple[str, ...]:
        return tuple(NOISE_UNITS.get(name, "") for _, name in self.keys)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: ``{group: {"sigma", "stderr", "redundancy", "estimated", "floored", "unit"}}``."""
        out: dict[str, Any] = {
            g: {
                "sigma": float(self.sigmas[k]),
                "stderr": float(self.stderr[k]),
                "redundancy": float(self.redundancy[k]),
                "estimated": bool(self.estimated[k]),
                "hidden": bool(self.hidden_groups[k]),
                "floored": bool(self.floored[k]),
                "unit": unit,
            }
            for k, (g, unit) in enumerate(zip(self.groups, self.units(), strict=True))
        }
        out["iterations"], out["converged"] = self.iterations, self.converged
        return out


def _start_sigmas(problem: Problem, keys: tuple, start: Any) -> NDArray[np.float64]:
    if start is None or isinstance(start, NoiseModel):
        start = (NoiseModel() if start is None else start,) * len(problem.parts)
    out = []
    for k, name in keys:
        sig = dict(zip(("leg", "position", "orientation"), start[k].sigmas, strict=True))
        out.append(sig[name])
    return np.array(out)


def estimate_noise(
    problem: Problem,
    start: NoiseModel | Sequence[NoiseModel] | None = None,
    max_iter: int = 40,
    rtol: float = 1e-3,
    fallback: NoiseModel | Sequence[NoiseModel] | None = None,
    **options: Any,
) -> tuple[NoiseEstimate, Any]:
    """Variance components of the noise groups, iterated with the ``ml`` fit to convergence.

    Parameters
    ----------
    problem : Problem
    start : NoiseModel or one per session, optional
        Start values (default the seed paper's noise).
    fallback : NoiseModel or one per session, optional
        The σ a group is held at where these data cannot determine it (default ``start``).
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
    >>> from hexcal.estimation.uncertainty import planned_measurements
    >>> nominal, real = preset("paper-hmt"), preset("paper-hmt-true")
    >>> rng = np.random.default_rng(1)
    >>> data = planned_measurements(real, workspace_corners(nominal))
    >>> data = type(data)(data.poses + rng.normal(0, [0.02] * 3 + [3e-4] * 3, (64, 6)), data.readings)
    >>> est, fit = estimate_noise(Problem(nominal, data))
    >>> bool(0.7 < est.sigmas[1] / 0.02 < 1.3), bool(0.7 < est.sigmas[2] / 3e-4 < 1.3)
    (True, True)
    """
    from hexcal.estimation.gls import solve_gls
    from hexcal.estimation.likelihood import Projection, fit_ml

    keys = problem_groups(problem)
    n_sessions = len(problem.parts)
    floors = np.array([NOISE_FLOORS.get(name, 1e-8) for _, name in keys])
    sigmas = np.maximum(_start_sigmas(problem, keys, start), floors)
    held_at = sigmas if fallback is None else np.maximum(_start_sigmas(problem, keys, fallback), floors)
    # one converged fit, then Gauss–Newton steps of the parameters interleaved with the
    # variance-component updates (each step is one pose projection, not a whole fit). The
    # step under the current variances comes first: the update needs the residuals of the
    # fit for these variances, and residuals one step behind make it overshoot and
    # oscillate (40 iterations without converging instead of about 8)
    first = _session_noises(keys, sigmas, n_sessions)
    # from the generalised least-squares estimate where the pose is measured (the same estimator to
    # first order: with a gross misfit, a wrong Euler sequence, the likelihood has other minima)
    gls = solve_gls(problem, first, 1, check=False)[0] if problem.determines_pose else None
    x = _solver_variables(problem, fit_ml(problem, first, start=gls, **options))
    poses = None
    converged, it = False, 0
    falling = np.zeros(len(keys), dtype=int)  # consecutive steps each σ fell slowly
    hidden = np.zeros(len(keys), dtype=bool)  # held at the fallback: the others' noise hides it
    while it < max_iter:
        it += 1
        inner = Projection(problem, _session_noises(keys, sigmas, n_sessions))
        if poses is not None:
            for part, own in zip(inner.parts, poses, strict=True):
                part.poses = own
        try:
            step = np.linalg.lstsq(inner.jacobian(x), inner.residuals(x), rcond=None)[0]
            moved = x - step
            if not np.all(np.isfinite(moved)):
                raise np.linalg.LinAlgError("the step is not finite")
            stats, _, _ = _statistics(problem, inner, moved, keys)
        except (np.linalg.LinAlgError, FloatingPointError, HexcalError):
            # the step left the basin (a large change of the weights moved the optimum far):
            # a full fit under the current variances instead, or stop with the last values
            current = _session_noises(keys, sigmas, n_sessions)
            try:
                moved = _solver_variables(problem, fit_ml(problem, current, **options))
                inner = Projection(problem, current)
                stats, _, _ = _statistics(problem, inner, moved, keys)
            except (np.linalg.LinAlgError, FloatingPointError, HexcalError):
                break
            step = moved - x
        x = moved
        if stats.keys != keys:
            raise IdentificationError("variance components need a diagonal instrument covariance")
        poses = [part.poses for part in inner.parts]
        # a group with too little redundancy keeps its σ while the others converge (set to its
        # fallback only at the end: set at once, one near the limit swings between the two, 40
        # steps without converging on real data); a hidden one is at its fallback from now on
        estimated = (stats.redundancy >= MIN_REDUNDANCY) & ~hidden
        new = np.where(estimated, np.maximum(sigmas * _helmert_ratio(stats, estimated), floors), sigmas)
        if not np.all(np.isfinite(new)):
            break  # the iteration diverges (a gross error): keep the last finite values
        ratios = new / sigmas
        change = float(np.max(np.abs(ratios - 1)))
        # slowly: a hidden group creeps towards 0 by a few per cent a step, a group with no noise
        # at all falls to its floor by large steps (and is no hidden group: exact data)
        falling = np.where((ratios < 1 - rtol) & (ratios > SLOW_FALL), falling + 1, 0)
        sigmas = new
        # the parameters need only be near the fit of these variances (a µm, in solver units):
        # the final fit below refines them; a group with hardly any redundancy converges
        # slowly (a factor 4 per step on real data) and would hit max_iter at 1e-6
        settled = float(np.max(np.abs(step), initial=0.0)) < 1e-3
        if change < rtol and settled:
            converged = True
            break
        # a hidden group drifts towards zero by a few per cent a step (the slow approach to the
        # boundary) while the parameters stand: it is not determined by these data; held at its
        # fallback from here on, the others converge with it (where it stops would otherwise
        # depend on the machine's rounding: the figures differed in the third digit)
        moving = (np.abs(ratios - 1) >= rtol) & estimated
        weak = stats.redundancy[moving] < DRIFT_REDUNDANCY
        if settled and it >= DRIFT_STEPS and np.all(falling[moving] >= DRIFT_STEPS) and np.all(weak):
            hidden |= moving
            sigmas = np.where(hidden, held_at, sigmas)
            falling[:] = 0
            if np.all(hidden | (stats.redundancy < MIN_REDUNDANCY)):
                converged = True
                break
    # the fit of the last variances from the iteration's last parameters: a fit from the start
    # values can fall into another minimum under strict weights (a ballbar read to 1 µm, its
    # circles at one pivot: reduced chi-square 60 instead of 1)
    noises = _session_noises(keys, sigmas, n_sessions)
    # its last iterate counts if it runs out of iterations (the verdict judges it, and its status
    # says so)
    result = fit_ml(problem, noises, start=x, **({"truncate": True} | options))
    stats = group_statistics(problem, noises, result)
    red = stats.redundancy
    estimated = (red >= MIN_REDUNDANCY) & ~hidden
    # the undetermined groups at their fallback; one that fell to its floor stays there (the data
    # show no noise in it: exact data)
    at_floor = sigmas <= floors * (1 + 1e-9)
    final = np.where(estimated | (at_floor & ~hidden), sigmas, held_at)
    stderr = np.full(len(keys), np.nan)
    if stats.helmert is not None and estimated.any():
        # var(α̂) = 2 M⁻¹ for the variance ratios α (Gaussian noise); σ = sqrt(α) σ₀
        sub = stats.helmert[np.ix_(estimated, estimated)]
        var_alpha = 2 * np.diag(np.linalg.pinv(sub))
        stderr[estimated] = sigmas[estimated] * np.sqrt(np.maximum(var_alpha, 0.0)) / 2
    if not np.array_equal(final, sigmas):  # a group the last fit showed undetermined
        sigmas = final
        noises = _session_noises(keys, sigmas, n_sessions)
        result = fit_ml(problem, noises, start=_solver_variables(problem, result), **options)
    floored = sigmas <= floors * (1 + 1e-9)
    estimate = NoiseEstimate(
        stats.groups, sigmas, stderr, red, estimated, floored, it, converged, keys, hidden
    )
    return estimate, result.replace(noise=noises[0], noises=noises)
