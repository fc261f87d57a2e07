"""Planning ballbar campaigns: feasible circles, and the circles and pivots to measure.

A ballbar circle is a group of poses: the platform ball goes round the pivot ``c`` on a circle
of radius ``R = length + d0`` in a plane (``xy``, ``xz`` or ``yz`` of the base frame), the
platform's orientation held at one value along the circle (level, or tilted by ``tilt``
about x or y), run in both feed directions (``ccw`` then ``cw``; the same points in the other
order: a static model sees the same information, a real machine's reversal errors do not).
A circle is a candidate only when every one of its points is feasible for the machine (leg
limits, distance from singularity: :func:`hexcal.design.check_feasibility`).

Every pivot position is a session with its own ``pivot``, ``ball`` and ``length``.
:func:`select_circles` chooses circles (whole groups, never single poses) among the candidates
of several pivots, greedily by the A-criterion of the machine's joints and ``l0``
(the Cramér–Rao covariance of the distance data, pose nuisances eliminated, gauge-fixed by
hexcal's convention): a circle at a new pivot brings that pivot's seven parameters with it, so
the criterion itself weighs a new pivot against another circle at a pivot already chosen.
:func:`circle_accuracy` gives the predicted accuracy of a choice (the platform pose error over
the workspace after calibration, up to the frames).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.calibration.accuracy import position_metric, predicted_pose_accuracy
from hexcal.core import Geometry, NoiseModel, rotation_matrices
from hexcal.core.linalg import numerical_rank, scaled_svd
from hexcal.core.noise import require_noise
from hexcal.core.progress import task
from hexcal.core.resources import check_memory
from hexcal.design.candidates import MIN_SINGULARITY_DISTANCE, check_feasibility
from hexcal.errors import InputError
from hexcal.estimation.gauge import gauge_freedoms, gauge_projector
from hexcal.estimation.problem import Problem
from hexcal.estimation.uncertainty import cramer_rao, information_rows, planned_session, projected_jacobian
from hexcal.instruments.ballbar import BallbarModel
from hexcal.instruments.ballbar_setup import MIN_LENGTH, BallbarSetup

#: Circle planes by name: the two in-plane axes of the base frame.
PLANES = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}
#: Regularisation of the information (relative to its largest diagonal) while a selection is
#: still rank-deficient: an undetermined direction then costs ``1 / ridge``.
RIDGE = 1e-9
#: What a circle's label says: its plane and its held orientation (level or tilted a,b,c).
LABEL = re.compile(r"plane (xy|xz|yz), (level|tilted ([^,]+),([^,]+),([^ ]+) deg)")
#: The held orientations' tilt of the circles by default (rad): 8°, about x and about y.
DEFAULT_TILT = float(np.deg2rad(8.0))
#: Circles :func:`select_circles` chooses by default.
DEFAULT_CIRCLES = 12
#: A pivot's name (the prefix of its poses' ids): letters, digits, ``_`` and ``-``.
PIVOT_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,31}")
#: Most pivots of one plan: each pivot is a session (a mounting of the bar, with its own seven
#: quantities), and a campaign has a handful; the selection's information matrices grow with
#: the cube of the pivots.
MAX_PIVOTS = 100
#: Bytes per candidate circle point while the circles are built and checked (poses in both feed
#: directions, the feasibility check's leg vectors and distances, the point's id): measured
#: about 1,300 (4.5 GiB for 10,000 pivots of 360 points each).
CIRCLE_POINT_BYTES = 1500


@dataclass(frozen=True)
class Circles:
    """Candidate circles: their poses (grouped) and what each circle is.

    Attributes
    ----------
    poses : ndarray, shape (m, 6)
        Every point of every circle, circle after circle.
    circle : ndarray of int, shape (m,)
        The circle of each pose.
    ids : tuple of str
        Pose labels ``{pivot name}.c{circle}.{ccw|cw}.{point}`` (1-based).
    pivots : ndarray, shape (P, 3)
        The pivot positions (base frame, mm).
    pivot : ndarray of int, shape (C,)
        The pivot of each circle.
    labels : tuple of str
        One line per circle: pivot, plane, orientation, direction.
    setup : BallbarSetup
        The bar (ball, length) the circles are for.
    names : tuple of str
        Each pivot's name, the prefix of its poses' ids (default ``p1``, ``p2``, ...).
    """

    poses: NDArray[np.float64]
    circle: NDArray[np.intp]
    ids: tuple[str, ...]
    pivots: NDArray[np.float64]
    pivot: NDArray[np.intp]
    labels: tuple[str, ...]
    setup: BallbarSetup
    names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not self.names:
            object.__setattr__(self, "names", tuple(f"p{k + 1}" for k in range(len(self.pivots))))

    def pivot_title(self, p: int) -> str:
        """How lines name pivot ``p``: its number (``pivot 5``), or the name given to it."""
        default = self.names[p] == f"p{p + 1}"
        return f"pivot {p + 1}" if default else f"pivot {self.names[p]}"

    @property
    def n_circles(self) -> int:
        return len(self.pivot)

    def subset(self, chosen: ArrayLike) -> Circles:
        """The circles ``chosen`` (indices), renumbered in that order, their pivots kept."""
        chosen = np.asarray(chosen, dtype=np.intp).reshape(-1)
        rows = np.concatenate([np.flatnonzero(self.circle == c) for c in chosen]) if chosen.size else []
        rows = np.asarray(rows, dtype=np.intp)
        index = {int(c): k for k, c in enumerate(chosen)}
        return Circles(
            self.poses[rows],
            np.array([index[int(c)] for c in self.circle[rows]], dtype=np.intp),
            tuple(self.ids[r] for r in rows),
            self.pivots,
            self.pivot[chosen],
            tuple(self.labels[c] for c in chosen),
            self.setup,
            self.names,
        )

    def circle_pivot(self, c: int) -> int:
        """The pivot of circle ``c``."""
        return int(self.pivot[c])

    def instrument(self, p: int) -> BallbarModel:
        """The ballbar at pivot ``p``."""
        return BallbarModel(
            BallbarSetup(self.pivots[p], self.setup.ball, self.setup.length, self.setup.fixed)
        )


def pivot_grid(geometry: Geometry, setup: BallbarSetup, spread: float = 0.5) -> NDArray[np.float64]:
    """Seven candidate pivots: where the ball is at the workspace's centre (level platform),
    and that point moved by ``± spread`` of the box's half-width along x, y and z."""
    if geometry.workspace is None:
        raise InputError("the geometry has no workspace box: give the pivots (--pivots)")
    box = np.asarray(geometry.workspace, dtype=float)
    centre, half = box[:3].mean(axis=1), np.diff(box[:3], axis=1)[:, 0] / 2
    base = centre + setup.ball
    offsets = np.vstack(
        [np.zeros(3), *(s * spread * half[k] * np.eye(3)[k] for k in range(3) for s in (1, -1))]
    )
    return base + offsets


def pivot_names(names: list[str | None] | tuple[str | None, ...] | None, count: int) -> tuple[str, ...]:
    """The names of ``count`` pivots: each given name, else ``p{k}`` (its 1-based number).

    A name is the prefix of its poses' ids and so of the session they are measured in: give
    one that no other session of the campaign has (a pivot at ``0,0,460`` planned after a
    session ``p1`` would otherwise be ``p1`` too). Names given twice, or a default clashing
    with a given name, are refused.

    >>> pivot_names(["p7", None], 2)
    ('p7', 'p2')
    """
    given = list(names) if names is not None else [None] * count
    if len(given) != count:
        raise InputError(f"pivot names: {len(given)} for {count} pivots")
    out = tuple(name if name is not None else f"p{k + 1}" for k, name in enumerate(given))
    for k, name in enumerate(out):
        if given[k] is not None and not PIVOT_NAME.fullmatch(name):
            raise InputError(
                f"--pivots: pivot name {name!r}: a letter, then letters, digits, _ or - (32 at most)"
            )
        if name in out[:k]:
            raise InputError(
                f"--pivots: two pivots are named {name!r} (unnamed pivot k is p<k>); name each "
                "pivot once (NAME=x,y,z)"
            )
    return out


def orientations(tilt: float) -> NDArray[np.float64]:
    """The held platform orientations (rad): level, and ``± tilt`` about x and about y."""
    if tilt == 0:
        return np.zeros((1, 3))
    return np.array([[0, 0, 0], [tilt, 0, 0], [-tilt, 0, 0], [0, tilt, 0], [0, -tilt, 0]], dtype=float)


def circle_poses(
    pivot: ArrayLike, ball: ArrayLike, radius: float, plane: str, angles: ArrayLike, points: int, euler: str
) -> NDArray[np.float64]:
    """The ``points`` platform poses ``(points, 6)`` that put the ball at equal steps round
    the circle of ``radius`` about ``pivot`` in ``plane`` (counter-clockwise from the plane's
    first axis), the platform held at orientation ``angles``."""
    if plane not in PLANES:
        raise InputError(f"plane {plane!r}: choose from {', '.join(PLANES)}")
    i, j = PLANES[plane]
    theta = 2 * np.pi * np.arange(points) / points
    where = np.tile(np.asarray(pivot, dtype=float), (points, 1))
    where[:, i] += radius * np.cos(theta)
    where[:, j] += radius * np.sin(theta)
    angles = np.asarray(angles, dtype=float)
    rot = rotation_matrices(angles, euler)
    origin = where - rot @ np.asarray(ball, dtype=float)
    return np.column_stack([origin, np.tile(angles, (points, 1))])


def ballbar_circles(
    geometry: Geometry,
    setup: BallbarSetup,
    pivots: ArrayLike | None = None,
    planes: tuple[str, ...] = ("xy", "xz", "yz"),
    tilt: float = DEFAULT_TILT,
    points: int = 12,
    d0: float = 0.0,
    min_distance: float | None = None,
    names: list[str | None] | tuple[str | None, ...] | None = None,
) -> tuple[Circles, int]:
    """The feasible circles of a bar at ``pivots`` (default :func:`pivot_grid`).

    Every pivot, plane and held orientation (:func:`orientations` of ``tilt``, rad) gives one
    circle of ``points`` poses at radius ``length + d0``, in each feed direction (``ccw``,
    ``cw``). Returns the circles whose every point is feasible and how many were left out.
    ``names`` (one per pivot, None for the default ``p{k}``: :func:`pivot_names`) prefix the
    poses' ids. Refused before anything is allocated: a bar shorter than ``MIN_LENGTH`` along
    the circles, more than :data:`MAX_PIVOTS` pivots, circles over the memory budget.
    """
    if points < 3:
        raise InputError(f"--points {points}: a circle needs at least 3 points")
    radius = setup.length + d0
    if not radius >= MIN_LENGTH:  # NaN too
        raise InputError(
            f"--d0 {d0:g}: the bar would be {radius:g} mm long ({setup.length:g} mm + d0); a bar is at "
            f"least {MIN_LENGTH:g} mm long"
        )
    pivots = pivot_grid(geometry, setup) if pivots is None else np.asarray(pivots, dtype=float).reshape(-1, 3)
    if not np.all(np.isfinite(pivots)):
        raise InputError("pivots must be finite numbers (mm)")
    if len(pivots) > MAX_PIVOTS:
        raise InputError(
            f"--pivots: {len(pivots):,} pivots, at most {MAX_PIVOTS} (each is a session: a mounting of "
            "the bar)"
        )
    prefixes = pivot_names(names, len(pivots))
    held = orientations(tilt)
    n_circles = 2 * len(pivots) * len(planes) * len(held)
    check_memory(
        "--points" if points >= n_circles else "--pivots",
        CIRCLE_POINT_BYTES * n_circles * points,
        f"{n_circles:,} circles of {points:,} points",
    )
    combos = [(p, plane, k) for p in range(len(pivots)) for plane in planes for k in range(len(held))]
    if not combos:
        raise InputError("no circles: give at least one plane")
    base = np.stack([circle_poses(pivots[p], setup.ball, radius, plane, held[k], points, geometry.euler)
                     for p, plane, k in combos])  # fmt: skip
    both = np.concatenate([base, base[:, ::-1]], axis=0)  # ccw, then cw
    flat = both.reshape(-1, 6)
    ok = check_feasibility(geometry, flat, MIN_SINGULARITY_DISTANCE if min_distance is None else min_distance)
    feasible = ok.feasible.reshape(len(both), points).all(axis=1)
    keep = np.flatnonzero(feasible)
    n = len(combos)
    poses, circle, ids, labels, pivot_of = [], [], [], [], []
    for new, c in enumerate(keep):
        p, plane, k = combos[c % n]
        way = "ccw" if c < n else "cw"
        deg = np.rad2deg(held[k])
        tilted = "level" if not np.any(deg) else "tilted " + ",".join(f"{v:+g}" for v in deg) + " deg"
        title = f"pivot {p + 1}" if prefixes[p] == f"p{p + 1}" else f"pivot {prefixes[p]}"
        labels.append(f"{title}, plane {plane}, {tilted}, {way}")
        ids += [f"{prefixes[p]}.c{new + 1}.{way}.{j + 1:02d}" for j in range(points)]
        poses.append(both[c])
        circle += [new] * points
        pivot_of.append(p)
    return (
        Circles(
            np.concatenate(poses) if poses else np.zeros((0, 6)),
            np.asarray(circle, dtype=np.intp),
            tuple(ids),
            pivots,
            np.asarray(pivot_of, dtype=np.intp),
            tuple(labels),
            setup,
            prefixes,
        ),
        int((~feasible).sum()),
    )


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
    is made (the first: the lowest trace). Returns the circles in the order chosen.
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
        """The predicted position error (mean square, mm²) after ``steps`` more greedy
        circles at the pivots in use (inf: too few left)."""
        chosen = list(chosen)
        for _ in range(steps):
            moves = singles(chosen)
            if not moves:
                return np.inf
            best = moves[int(np.argmin(score(moves, base)))]
            chosen += best
            base = base + infos[best[0]]
        return float(_criterion(base[None], proj, position)[0])

    chosen: list[int] = []
    total = np.zeros_like(infos[0])
    history: list[float] = []
    done = [0]
    with task("circles", n) as step:
        while len(chosen) < n:
            step(len(chosen) - done[0])
            done[0] = len(chosen)
            used = {int(circles.pivot[c]) for c in chosen}
            room = n - len(chosen)
            opens = [group for p, group in first.items() if p not in used and len(group) <= room]
            moves = singles(chosen) + opens
            if not moves:  # every pivot used up: any circle left
                moves = [[c] for c in range(circles.n_circles) if c not in chosen]
            scores = score(moves, total)
            best = int(np.argmin(scores))
            one = [k for k, m in enumerate(moves) if len(m) == 1]
            groups = [k for k, m in enumerate(moves) if len(m) > 1]
            opening = min(groups, key=lambda k: scores[k], default=None)
            if chosen and one and opening is not None:
                # a pivot's starters lower the criterion less at once than as many circles at the
                # pivots in use, and often more in the end: the plan is completed both ways (greedy
                # circles at the pivots then in use) and the lower predicted position error decides
                group = moves[opening]
                stay = ahead(chosen, total, room)
                go = ahead(chosen + group, total + infos[group].sum(axis=0), room - len(group))
                best = opening if go < stay else min(one, key=lambda k: scores[k])
            chosen += moves[best]
            total = total + infos[moves[best]].sum(axis=0)
            history += [float(scores[best])] * len(moves[best])
        step(len(chosen) - done[0])
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
