"""The ISO 230-4 circular test, as numbers.

Pure numpy. Lengths in mm, angles in rad. What each figure is, as implemented (the wording
of the standard's terms, then the choices hexcal makes where the standard leaves one):

**ISO 230-4** (test code for machine tools, part 4: circular tests for numerically controlled
machine tools; the terms of its clause 3). The *nominal path* is the commanded circle; the
*actual path* is where the machine went, measured as a radial deviation from the nominal
circle at each commanded point.

- nominal circle: its plane is the least-squares plane of the commanded positions, its
  centre and radius the least-squares circle of their projections on that plane (or given;
  fitted positions more than 1 % of the radius off that circle or plane are refused);
  angles are measured counterclockwise in that plane, seen from the side its normal points
  to (the normal is turned towards the positive side of the base axis it is closest to:
  ``+z`` for a circle in the x-y plane, so that CCW is the usual CCW);
- the actual point of a commanded point ``q`` at angle ``θ`` lies at the radius
  ``|q - c0| + d`` from the nominal centre ``c0`` (``d`` its measured radial deviation), or
  ``R0 + d`` for points commanded on the circle (``on_circle``: the positions only locate them);
- **radial deviation F** (``F_max``, ``F_min``): the largest and smallest deviation of the
  actual path from the nominal circle, the centre of the nominal circle being where the
  instrument was centred (the commanded centre ``c0``): ``max`` and ``min`` of
  ``|q - c0| + d - R0``;
- **circular deviation G**: the minimum radial separation of two concentric circles that
  enclose the actual path, their centre being the centre of the least-squares circle (LSC)
  of the actual path: ``max r - min r`` with ``r`` the distances of the actual points from
  that centre. (The standard also admits a minimum-zone centre, whose ``G`` is never larger;
  hexcal gives the LSC value.) Given per direction; **G(b)**, bidirectional, is the same
  over both runs together, with the LSC of both;
- **circular hysteresis H**: the largest radial difference between the clockwise and the
  counterclockwise actual paths at the same angle, both about the nominal centre: each
  run's radius is interpolated (linearly, periodically) at the other run's angles where the
  other run covers them, and ``H = max |r_ccw(θ) - r_cw(θ)|``;
- as ballbar software prints them, per run: the LSC centre's offset from the nominal centre
  (in the plane's axes) and the radius error (the LSC radius minus the nominal radius).

The direction of every point is the sign of the angle's progression through the points in
their order (the unwrapped angle of the next point minus that of the previous), unless
given. Every point measured is used (drop feed ramps, overshoot arcs from the data first).

The ISO 9283 pose figures are in :mod:`hexcal.calibration.iso_poses`.

>>> import numpy as np
>>> t = np.radians(np.arange(0, 360, 90.0))
>>> q = 100 * np.column_stack([np.cos(t), np.sin(t)])
>>> c = circular_test(q, [0.01, 0.0, -0.01, 0.0], direction=np.ones(4))
>>> round(c.runs["ccw"].f_max, 6), round(c.runs["ccw"].f_min, 6)
(0.01, -0.01)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.errors import InputError

#: Direction names by the sign of the angle's progression.
DIRECTIONS = {1: "ccw", -1: "cw"}

_LSC_ITERATIONS = 20

#: Commanded positions farther than this fraction of the radius from their least-squares circle
#: (or plane) are no circle: the test refuses them.
CIRCLE_TOLERANCE = 0.01
#: The same for positions that only locate the points on the circle (``on_circle``: the path
#: a machine took, a few percent out of round before calibration at most).
LOCATED_TOLERANCE = 0.1


def lsc_circle(points: ArrayLike) -> tuple[NDArray[np.float64], float]:
    """The least-squares circle of points ``(m, 2)``: centre and radius minimising
    ``Σ (|p_i - c| - ρ)²`` (Gauss–Newton from the algebraic fit).

    >>> c, r = lsc_circle([[1, 0], [0, 1], [-1, 0], [0, -1]])
    >>> np.abs(np.round(c, 12)).tolist(), round(r, 12)
    ([0.0, 0.0], 1.0)
    """
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(p) < 3:
        raise InputError(f"a circle needs at least 3 points, got {len(p)}")
    design = np.column_stack([2 * p, np.ones(len(p))])
    sol, *_ = np.linalg.lstsq(design, np.sum(p**2, axis=1), rcond=None)
    centre, radius = sol[:2], float(np.sqrt(max(sol[2] + sol[:2] @ sol[:2], 0.0)))
    for _ in range(_LSC_ITERATIONS):
        diff = p - centre
        dist = np.linalg.norm(diff, axis=1)
        if np.any(dist == 0):
            break
        jac = np.column_stack([-diff / dist[:, None], -np.ones(len(p))])
        step, *_ = np.linalg.lstsq(jac, -(dist - radius), rcond=None)
        centre, radius = centre + step[:2], radius + float(step[2])
        if np.max(np.abs(step)) < 1e-13 * (1 + radius):
            break
    return centre, radius


def circle_plane(positions: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The least-squares plane of positions ``(m, 3)``: a point of it (the centroid) and its
    axes ``(3, 3)`` (rows: in-plane ``u``, in-plane ``v``, normal ``n``, right-handed), the
    normal turned towards the positive side of its closest base axis, ``u`` the projection of
    the first base axis not along the normal.

    >>> origin, axes = circle_plane([[1, 0, 5], [0, 1, 5], [-1, 0, 5], [0, -1, 5]])
    >>> np.round(axes, 12).tolist()
    [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    """
    p = np.asarray(positions, dtype=float).reshape(-1, 3)
    origin = p.mean(axis=0)
    normal = np.linalg.svd(p - origin, full_matrices=False)[2][-1]
    normal = normal * np.sign(normal[np.argmax(np.abs(normal))])
    base = np.eye(3)[1 if int(np.argmax(np.abs(normal))) == 0 else 0]
    u = base - (base @ normal) * normal
    u /= np.linalg.norm(u)
    return origin, np.array([u, np.cross(normal, u), normal])


def progression(angles: ArrayLike) -> NDArray[np.int_]:
    """The direction of each point (+1 counterclockwise, -1 clockwise) from the order of
    the points: the sign of the unwrapped angle of the next point minus that of the previous.

    >>> progression(np.radians([0, 10, 20, 10, 0])).tolist()
    [1, 1, 0, -1, -1]
    """
    t = np.unwrap(np.asarray(angles, dtype=float))
    if len(t) < 2:
        return np.ones(len(t), dtype=int)
    ahead = np.concatenate([t[1:], t[-1:]])
    behind = np.concatenate([t[:1], t[:-1]])
    return np.sign(ahead - behind).astype(int)


@dataclass(frozen=True)
class CircleRun:
    """The figures of one run (or both together) of a circular test (mm, rad)."""

    points: int
    f_max: float
    f_min: float
    g: float
    centre_offset: tuple[float, float]
    radius_error: float
    angles: NDArray[np.float64] = field(repr=False)
    deviation: NDArray[np.float64] = field(repr=False)

    def to_dict(self) -> dict[str, Any]:
        return {
            "points": self.points,
            "radial_deviation_max_mm": self.f_max,
            "radial_deviation_min_mm": self.f_min,
            "circular_deviation_mm": self.g,
            "centre_offset_mm": list(self.centre_offset),
            "radius_error_mm": self.radius_error,
            "angles_deg": np.degrees(self.angles).tolist(),
            "deviation_mm": self.deviation.tolist(),
        }


@dataclass(frozen=True)
class CircularTest:
    """An ISO 230-4 circular test (module docstring): the nominal circle, each run's figures
    (``ccw``, ``cw``, and ``both`` when there are two), ``G(b)`` and ``H`` (None with one run)."""

    radius: float
    centre: NDArray[np.float64]
    axes: NDArray[np.float64]
    runs: dict[str, CircleRun]
    hysteresis: float | None
    bidirectional: float | None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready figures (mm; angles of the runs' points in degrees)."""
        return {
            "nominal_radius_mm": self.radius,
            "nominal_centre_mm": self.centre.tolist(),
            "plane_axes": self.axes.tolist(),
            "runs": {name: run.to_dict() for name, run in self.runs.items()},
            "circular_hysteresis_mm": self.hysteresis,
            "bidirectional_circular_deviation_mm": self.bidirectional,
        }


def _run(angles: NDArray, radii: NDArray, radius: float) -> CircleRun:
    points = radii[:, None] * np.column_stack([np.cos(angles), np.sin(angles)])
    centre, rho = lsc_circle(points)
    about = np.linalg.norm(points - centre, axis=1)
    dev = radii - radius
    return CircleRun(
        len(angles),
        float(dev.max()),
        float(dev.min()),
        float(about.max() - about.min()),
        (float(centre[0]), float(centre[1])),
        float(rho - radius),
        angles,
        dev,
    )


def _covered(at: NDArray, angles: NDArray) -> NDArray[np.bool_]:
    """Which angles ``at`` a run through ``angles`` covers: all but its largest gap between
    neighbouring angles (mod 2π), when that gap is wider than three typical steps."""
    wrapped = np.sort(np.mod(angles, 2 * np.pi))
    gaps = np.diff(np.concatenate([wrapped, wrapped[:1] + 2 * np.pi]))
    k = int(np.argmax(gaps))
    if gaps[k] <= 3 * np.median(gaps):
        return np.ones(len(at), dtype=bool)
    into = np.mod(at - wrapped[k], 2 * np.pi)
    return (into <= 1e-12) | (into >= gaps[k] - 1e-12)


def _hysteresis(ccw: tuple[NDArray, NDArray], cw: tuple[NDArray, NDArray]) -> float:
    diffs = []
    for (t_a, r_a), (t_b, r_b) in ((ccw, cw), (cw, ccw)):
        inside = _covered(t_a, t_b)
        if inside.any():
            other = np.interp(t_a[inside], t_b, r_b, period=2 * np.pi)
            diffs.append(np.abs(r_a[inside] - other))
    return float(np.max(np.concatenate(diffs))) if diffs else float("nan")


def circular_test(
    commanded: ArrayLike,
    deviation: ArrayLike,
    direction: ArrayLike | None = None,
    *,
    centre: ArrayLike | None = None,
    radius: float | None = None,
    on_circle: bool = False,
) -> CircularTest:
    """The ISO 230-4 figures of one circle (module docstring).

    Parameters
    ----------
    commanded : array_like, shape (m, 2) or (m, 3)
        The commanded positions, mm: in the circle's plane, or in space (their least-squares
        plane is the circle's).
    deviation : array_like, shape (m,)
        The measured radial deviation of the actual path at each point, mm (outwards positive).
    direction : array_like of +1/-1, shape (m,), optional
        Counterclockwise (+1) or clockwise (-1) per point; default from the points' order.
    centre, radius : optional
        The nominal circle's centre (in the plane's coordinates) and radius; default the
        least-squares circle of the commanded positions.
    on_circle : bool
        Each point commanded on the nominal circle at its angle (the actual radius is the
        nominal one plus its deviation), rather than at the position given: for positions that
        locate the points on the circle without being the command (docs/iso-tests.md), which
        may lie up to :data:`LOCATED_TOLERANCE` of the radius off it.

    Raises
    ------
    InputError
        Fewer than 3 points in a run, shapes that do not agree, non-finite values.
    """
    q = np.asarray(commanded, dtype=float)
    d = np.asarray(deviation, dtype=float).reshape(-1)
    if q.ndim != 2 or q.shape[1] not in (2, 3) or len(q) != len(d):
        raise InputError(
            f"a circle: commanded positions (m, 2 or 3) and m deviations, got {q.shape}, {d.shape}"
        )
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(d))):
        raise InputError("a circle: commanded positions and deviations must be finite")
    if q.shape[1] == 3:
        origin, axes = circle_plane(q)
        planar = (q - origin) @ axes[:2].T
        off_plane = float(np.max(np.abs((q - origin) @ axes[2])))
    else:
        origin, axes, planar, off_plane = np.zeros(3), np.eye(3), q, 0.0
    c0, r0 = lsc_circle(planar) if centre is None else (np.asarray(centre, dtype=float), float(radius or 0))
    if centre is not None and radius is None:
        r0 = float(np.mean(np.linalg.norm(planar - c0, axis=1)))
    off = max(float(np.max(np.abs(np.linalg.norm(planar - c0, axis=1) - r0))), off_plane)
    limit = LOCATED_TOLERANCE if on_circle else CIRCLE_TOLERANCE
    if centre is None and not off <= limit * r0:
        raise InputError(
            f"the {'' if on_circle else 'commanded '}positions are no circle: {off:.4g} mm off their "
            f"least-squares circle of radius {r0:.4g} mm (more than {limit:.0%}); the circular test needs "
            "one circle's points"
        )
    rel = planar - c0
    angles = np.arctan2(rel[:, 1], rel[:, 0])
    radii = (r0 if on_circle else np.linalg.norm(rel, axis=1)) + d
    sense = progression(angles) if direction is None else np.sign(np.asarray(direction, dtype=float))
    sense = np.where(sense == 0, np.concatenate([sense[1:], sense[-1:]]), sense)  # a turning point
    runs: dict[str, CircleRun] = {}
    for sign, name in DIRECTIONS.items():
        mask = sense == sign
        if mask.sum() >= 3:
            runs[name] = _run(angles[mask], radii[mask], r0)
    if not runs:
        raise InputError(f"a circle needs at least 3 points in one direction, got {len(d)} points")
    hysteresis = bidirectional = None
    if len(runs) == 2:
        both = _run(angles, radii, r0)
        runs["both"] = both
        bidirectional = both.g
        hysteresis = _hysteresis(
            (angles[sense == 1], radii[sense == 1]), (angles[sense == -1], radii[sense == -1])
        )
    centre3 = origin + c0 @ axes[:2] if q.shape[1] == 3 else np.array([*c0, 0.0])
    return CircularTest(r0, centre3, axes, runs, hysteresis, bidirectional)
