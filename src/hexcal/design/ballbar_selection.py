"""Choosing a ballbar campaign's circles and pivots, and its predicted accuracy.

:func:`select_circles` chooses circles (whole groups, never single poses) among the candidates
of several pivots (:func:`hexcal.design.ballbar_plan.ballbar_circles`), greedily by the
A-criterion of the machine's joints and ``l0`` (the Cramér–Rao covariance of the distance data,
pose nuisances eliminated, gauge-fixed by hexcal's convention); a new pivot comes with its
:func:`starters`. Two plans are made, the greedy one (the move that lowers the criterion most
per circle) and one that opens a pivot when the plan completed with it predicts a lower
position error than without it; the one predicting the lower position error is returned.
:func:`circle_accuracy` gives the predicted accuracy of a choice (the platform pose error over
the workspace after calibration, up to the frames).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.calibration.accuracy import position_metric, predicted_pose_accuracy
from hexcal.core import Geometry, NoiseModel
from hexcal.core.linalg import numerical_rank, scaled_svd
from hexcal.core.noise import require_noise
from hexcal.core.progress import task
from hexcal.core.resources import check_memory
from hexcal.design.ballbar_plan import Circles
from hexcal.errors import InputError
from hexcal.estimation.gauge import gauge_freedoms, gauge_projector
from hexcal.estimation.problem import Problem
from hexcal.estimation.uncertainty import cramer_rao, information_rows, planned_session, projected_jacobian

#: Regularisation of the information (relative to its largest diagonal) while a selection is
#: still rank-deficient: an undetermined direction then costs ``1 / ridge``.
RIDGE = 1e-9
#: What a circle's label says: its plane and its held orientation (level or tilted a,b,c).
LABEL = re.compile(r"plane (xy|xz|yz), (level|tilted ([^,]+),([^,]+),([^ ]+) deg)")
#: Circles :func:`select_circles` chooses by default.
DEFAULT_CIRCLES = 12


def circle_problem(geometry: Geometry, circles: Circles, fit: str = "joints,l0") -> Problem:
    """The noise-free identification problem of the circles: one session per pivot used."""
    used = np.unique(circles.pivot)
    sessions = []
    for p in used:
        rows = np.isin(circles.circle, np.flatnonzero(circles.pivot == p))
        sessions.append(planned_session(geometry, circles.instrument(int(p)), circles.poses[rows]))
    return Problem(geometry, sessions, fit=fit)


def circle_rows(problem: Problem, circles: Circles, noise: NoiseModel) -> list[NDArray[np.float64]]:
    """Each circle's square-root information rows ``(rows, n_free)`` in the problem's layout
    (the sessions of :func:`circle_problem`: pivots in increasing order)."""
    per_obs = np.concatenate(information_rows(problem, noise))  # (m, r, n_free), session order
    order = np.concatenate([np.flatnonzero(np.isin(circles.circle, np.flatnonzero(circles.pivot == p)))
                            for p in np.unique(circles.pivot)])  # fmt: skip
    circle_of = circles.circle[order]
    return [per_obs[circle_of == c].reshape(-1, problem.n_free) for c in range(circles.n_circles)]


@dataclass(frozen=True)
class CircleSelection:
    """Circles chosen (indices into the candidates), their pivots and the criterion's trace."""

    chosen: NDArray[np.intp]
    circles: Circles
    history: tuple[float, ...]

    @property
    def pivots_used(self) -> NDArray[np.intp]:
        return np.unique(self.circles.pivot)


def _criterion(info: NDArray, proj: NDArray, weight: NDArray) -> NDArray:
    """Batched ``trace(P (F + ridge I)⁻¹ Pᵀ W)`` (mm²) for the informations ``F``, gauge-fixed
    by ``P``: the A-criterion of the machine's parameters (``W`` diagonal, their scales²), or
    the predicted position error's mean square (``W``: :func:`selection_weight`)."""
    ridge = RIDGE * np.max(np.diagonal(info, axis1=-2, axis2=-1), axis=-1)[..., None, None]
    cov = proj @ np.linalg.inv(info + ridge * np.eye(info.shape[-1])) @ proj.T
    return np.einsum("...ij,ji->...", cov, weight)


def selection_weight(geometry: Geometry, problem: Problem, gauge: Any) -> NDArray[np.float64]:
    """``W`` (n_free, n_free, scaled units) whose ``trace(Σ W)`` is the square of the position
    RMS that :func:`circle_accuracy` predicts for a covariance ``Σ`` of the free parameters
    (:func:`hexcal.calibration.accuracy.position_metric` of the machine's block, the frames'
    rigid motions removed as there)."""
    k = int(problem.machine_mask.sum())
    rigid = (gauge.generators * problem.scale[:, None])[:k] if gauge.size else None
    metric = position_metric(geometry, problem.machine_mask, rigid)
    scale = problem.scale[:k]
    weight = np.zeros((problem.n_free, problem.n_free))
    weight[:k, :k] = scale[:, None] * metric * scale[None, :]
    return weight


def _starter_kind(label: str) -> tuple[str, str] | None:
    """``(plane, "level")``, ``("xz", "y")`` or ``("yz", "x")`` (a tilt about an axis in the
    plane, that axis), else None."""
    match = LABEL.search(label)
    if match is None:
        return None
    plane, held = match.group(1), match.group(2)
    if held == "level":
        return plane, "level"
    tilt = [float(match.group(k)) != 0 for k in (3, 4, 5)]
    if plane == "xz" and tilt == [False, True, False]:
        return plane, "y"
    if plane == "yz" and tilt == [True, False, False]:
        return plane, "x"
    return None


def starters(circles: Circles) -> dict[int, list[int]]:
    """The circles a new pivot starts with: its first circle of each plane with the platform
    level, in the xz plane tilted about y and in the yz plane tilted about x. With the platform
    level the data see only the difference of the ball and the pivot; a tilt about an axis in
    the circle's plane shows the ball's other coordinates along the bar; so a pivot needs
    both tilted circles beside the level ones for its own quantities. A pivot where one of
    these kinds (of the candidates at any pivot) is infeasible gets none: it is not offered."""
    out: dict[int, dict[tuple[str, str], int]] = {}
    for c, label in enumerate(circles.labels):
        kind = _starter_kind(label)
        if kind is not None:
            out.setdefault(int(circles.pivot[c]), {}).setdefault(kind, c)
    every = {kind for kinds in out.values() for kind in kinds}
    return {p: list(kinds.values()) for p, kinds in out.items() if set(kinds) == every}


def select_circles(
    geometry: Geometry,
    circles: Circles,
    n: int = DEFAULT_CIRCLES,
    noise: NoiseModel | None = None,
    fit: str = "joints,l0",
) -> CircleSelection:
    """Choose ``n`` circles greedily (A-criterion of the machine's parameters, gauge-fixed).

    A step either adds one circle at a pivot already in use, or takes a new pivot with its
    :func:`starters` (a pivot measured by one circle, or by level circles only, leaves its own
    quantities undetermined), while there is room for them. Every move is scored at once (a
    batch of information matrices) by the trace of the covariance of the machine's
    parameters, every used pivot's setup fitted too; the move that lowers it most per circle
    is made (the first: the lowest trace). A second plan opens a pivot whenever the plan
    completed with it predicts a lower position error than without it; of the two, the plan
    with the lower predicted position error (:func:`selection_weight`) is returned, in the
    order chosen. Refused: a zero noise, a problem over the memory budget.
    """
    if not 1 <= n <= circles.n_circles:
        raise InputError(f"--circles {n}: choose between 1 and {circles.n_circles} circles")
    noise = NoiseModel(distribution="normal") if noise is None else noise
    require_noise(noise, "every predicted accuracy", pose_noise=False)  # legs and the bar
    problem = circle_problem(geometry, circles, fit)
    # each point's information rows (the 6 legs and the bar), the circles' information matrices,
    # and as many again for the moves scored at once and their inverses
    size = 8 * problem.n_free * (7 * len(circles.poses) + 3 * circles.n_circles * problem.n_free)
    what = f"choosing among {circles.n_circles:,} circles at {len(circles.pivots)} pivots"
    check_memory("--pivots", size, what)
    blocks = circle_rows(problem, circles, noise)
    infos = np.stack([b.T @ b for b in blocks])  # (C, n, n)
    gauge = gauge_freedoms(problem, problem.full0)
    proj = gauge_projector(gauge)
    counted = np.zeros(problem.n_free)
    counted[: int(problem.machine_mask.sum())] = 1.0
    a_weight = np.diag(counted * problem.scale**2)  # the A-criterion: the machine's variances
    position = selection_weight(geometry, problem, gauge)
    first = starters(circles)

    def score(sets: list[list[int]], base: NDArray) -> NDArray:
        return _criterion(base + np.stack([infos[m].sum(axis=0) for m in sets]), proj, a_weight)

    def singles(chosen: list[int]) -> list[list[int]]:
        used = {int(circles.pivot[c]) for c in chosen}
        return [[c] for c in range(circles.n_circles) if c not in chosen and int(circles.pivot[c]) in used]

    def ahead(chosen: list[int], base: NDArray, steps: int) -> float:
        """The predicted position error (mean square, mm²) after ``steps`` more circles at the
        pivots in use: those that lower the criterion most, each judged alone (one batch, not
        ``steps`` greedy rounds); inf when too few are left."""
        moves = singles(chosen)
        if len(moves) < steps:
            return np.inf
        if steps:
            best = np.argsort(score(moves, base), kind="stable")[:steps]
            base = base + infos[[moves[k][0] for k in best]].sum(axis=0)
        return float(_criterion(base[None], proj, position)[0])

    def plan(lookahead: bool, step: Any) -> tuple[list[int], list[float], NDArray]:
        """The greedy plan: each step adds one circle at a pivot in use or a new pivot with its
        starters. Without ``lookahead`` the move lowering the criterion most per circle is made;
        with it, a new pivot is opened when the plan completed with it predicts the lower
        position error (a pivot's starters lower the criterion less at once than as many
        circles at the pivots in use, and often more in the end)."""
        chosen: list[int] = []
        total = np.zeros_like(infos[0])
        history: list[float] = []
        current = np.inf
        while len(chosen) < n:
            used = {int(circles.pivot[c]) for c in chosen}
            room = n - len(chosen)
            opens = [group for p, group in first.items() if p not in used and len(group) <= room]
            moves = singles(chosen) + opens
            if not moves:  # every pivot used up: any circle left
                moves = [[c] for c in range(circles.n_circles) if c not in chosen]
            scores = score(moves, total)
            cost = np.array([len(m) for m in moves], dtype=float)
            best = int(np.argmax(-scores if not np.isfinite(current) else (current - scores) / cost))
            one = [k for k, m in enumerate(moves) if len(m) == 1]
            groups = [k for k, m in enumerate(moves) if len(m) > 1]
            opening = min(groups, key=lambda k: scores[k], default=None)
            if lookahead and chosen and one and opening is not None:
                group = moves[opening]
                stay = ahead(chosen, total, room)
                go = ahead(chosen + group, total + infos[group].sum(axis=0), room - len(group))
                best = opening if go < stay else min(one, key=lambda k: scores[k])
            chosen += moves[best]
            total = total + infos[moves[best]].sum(axis=0)
            current = float(scores[best])
            history += [current] * len(moves[best])
            step(len(moves[best]))
        return chosen, history, total

    with task("circle plans", 2 * n) as step:  # two plans of n circles
        plans = [plan(lookahead, step) for lookahead in (False, True)]
    errors = [float(_criterion(total[None], proj, position)[0]) for _, _, total in plans]
    chosen, history, _ = plans[int(np.argmin(errors))]  # the plan that predicts better
    return CircleSelection(np.asarray(chosen, dtype=np.intp), circles.subset(chosen), tuple(history))


def circle_accuracy(
    geometry: Geometry, circles: Circles, noise: NoiseModel | None = None, fit: str = "joints,l0"
) -> dict[str, Any]:
    """Predicted accuracy of measuring ``circles``: the machine's Cramér–Rao covariance
    (gauge-fixed) through :func:`hexcal.calibration.accuracy.predicted_pose_accuracy`, with the
    rank and the mean σ of the joints and ``l0`` (mm); ``poses`` counts the test poses of the
    accuracy, ``circle_poses`` those measured."""
    noise = NoiseModel(distribution="normal") if noise is None else noise
    require_noise(noise, "every predicted accuracy", pose_noise=False)  # legs and the bar
    problem = circle_problem(geometry, circles, fit)
    cov = cramer_rao(problem, noise)
    k = int(problem.machine_mask.sum())
    gauge = gauge_freedoms(problem, problem.full0)
    rank = numerical_rank(scaled_svd(projected_jacobian(problem, noise)).singular_values)
    rigid = (gauge.generators * problem.scale[:, None])[:k] if gauge.size else None
    acc = predicted_pose_accuracy(geometry, cov[:k, :k], problem.machine_mask, rigid=rigid)
    sigma = np.sqrt(np.clip(np.diag(cov[:k, :k]), 0, None))
    return {
        "circles": circles.n_circles,
        "pivots": len(np.unique(circles.pivot)),
        "circle_poses": len(circles.poses),
        "parameters": problem.n_free,
        "gauges": gauge.size,
        "rank": int(rank),
        "identifiable": bool(rank == problem.n_free - gauge.size),
        "joint_sigma_mean_mm": float(sigma.mean()),
        **acc,
    }
