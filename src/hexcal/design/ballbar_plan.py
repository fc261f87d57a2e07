"""Planning ballbar campaigns: the feasible circles of a bar at its pivots (the circles and
pivots to measure are chosen by :mod:`hexcal.design.ballbar_selection`).

A ballbar circle is a group of poses: the platform ball goes round the pivot ``c`` on a circle
of radius ``R = length + d0`` in a plane (``xy``, ``xz`` or ``yz`` of the base frame), the
platform's orientation held at one value along the circle (level, or tilted by ``tilt``
about x or y), run in both feed directions (``ccw`` then ``cw``; the same points in the other
order: a static model sees the same information, a real machine's reversal errors do not).
A circle is a candidate only when every one of its points is feasible for the machine (leg
limits, distance from singularity: :func:`hexcal.design.check_feasibility`).

Every pivot position is a session with its own ``pivot``, ``ball`` and ``length``, named
by the prefix of its poses' ids (:func:`pivot_names`). The sizes asked for go through the
memory budget (:mod:`hexcal.core.resources`) before any circle is built.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core import Geometry, rotation_matrices
from hexcal.core.resources import check_memory
from hexcal.design.candidates import MIN_SINGULARITY_DISTANCE, check_feasibility
from hexcal.errors import InputError
from hexcal.instruments.ballbar import BallbarModel
from hexcal.instruments.ballbar_setup import MIN_LENGTH, BallbarSetup

#: Circle planes by name: the two in-plane axes of the base frame.
PLANES = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}
#: The held orientations' tilt of the circles by default (rad): 8°, about x and about y.
DEFAULT_TILT = float(np.deg2rad(8.0))
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
