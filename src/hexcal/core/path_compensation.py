"""Path compensation: a programmed path corrected for a controller that keeps the nominal
geometry, and subdivided so that the real machine follows the path within a tolerance.

A path is a sequence of moves in pose space (mm, rad): straight lines, and arcs (circles or
helices in a plane of two position axes, every other coordinate linear in the move's
parameter). The controller interpolates its commands linearly, so the real machine follows

    r(s) = C⁻¹((1 - s) C(p0) + s C(p1))

between two corrected points ``C(p0)``, ``C(p1)``, where ``C`` is the correction of
:func:`hexcal.core.compensate` (``IK_nominal(C(p))`` produces the readings that bring the
calibrated machine to ``p``). ``C`` is not linear, so ``r`` leaves the intended path
``p(t)`` between the points; :func:`correct_path` subdivides each move until it does not
(the criterion: :func:`correct_path`'s Notes). Pure numpy on top of :mod:`hexcal.core`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hexcal.core.compensation import compensate
from hexcal.core.conventions import rotation_matrices
from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import (
    forward_kinematics,
    inverse_kinematics,
    leg_lengths,
    leg_readings,
    pose_jacobian_from_arrays,
)
from hexcal.core.workspace import leg_limit_violations
from hexcal.errors import ValidationError

#: Share of the tolerances the midpoint of an output segment may use; the rest covers the
#: rounding of the written numbers and the asymmetry of the deviation within a segment.
CHECK_SHARE = 0.9

#: Most rounds of subdivision of one move (each cuts a failed segment into 2 parts or more).
MAX_DEPTH = 40

#: Most segments one block of moves may be cut into (bounds the memory of a block).
MAX_SEGMENTS = 4_000_000

#: A failed segment is cut into ``ceil(SPLIT_MARGIN * sqrt(deviation / allowed))`` equal
#: parts (the deviation shrinks with the square of the length), 2 to :data:`MAX_PARTS`.
SPLIT_MARGIN = 1.05

#: Most parts one failed segment is cut into in one round.
MAX_PARTS = 1024

#: Largest angle of an arc piece before any check (a start for the bisection, rad).
ARC_PIECE = math.pi / 4


class PathError(ValidationError):
    """A move cannot be corrected; ``move`` is its index in the block."""

    def __init__(self, move: int, message: str) -> None:
        super().__init__(message)
        self.move = move


@dataclass(frozen=True, eq=False)
class Moves:
    """A block of consecutive moves (mm, rad); move ``k`` starts where move ``k - 1`` ends.

    Attributes
    ----------
    start : ndarray, shape (6,)
        The pose before the first move.
    end : ndarray, shape (n, 6)
        End pose of each move.
    arc : ndarray of bool, shape (n,)
        Arcs; the others are straight lines in pose space.
    plane : ndarray of int, shape (n, 2)
        The arc's in-plane position axes ``(u, v)`` (0, 1, 2 for x, y, z); the angle turns
        from ``u`` towards ``v``, positive counterclockwise about ``u × v``.
    center : ndarray, shape (n, 2)
        The arc's centre in ``(u, v)``, mm.
    angle, sweep : ndarray, shape (n,)
        The arc's start angle and signed sweep (rad; negative is clockwise).
    radius, end_radius : ndarray, shape (n,)
        Radius at the start and at the end (mm); between them it changes linearly with the
        angle, so that an arc whose end is slightly off its circle still ends there.
    """

    start: NDArray[np.float64]
    end: NDArray[np.float64]
    arc: NDArray[np.bool_]
    plane: NDArray[np.intp]
    center: NDArray[np.float64]
    angle: NDArray[np.float64]
    sweep: NDArray[np.float64]
    radius: NDArray[np.float64]
    end_radius: NDArray[np.float64]

    @classmethod
    def lines(cls, start: NDArray[np.float64], end: NDArray[np.float64]) -> Moves:
        """Straight moves only, through ``end`` (``(n, 6)``) from ``start``."""
        end = np.asarray(end, dtype=float).reshape(-1, 6)
        n = len(end)
        z = np.zeros(n)
        return cls(np.asarray(start, dtype=float), end, np.zeros(n, bool), np.zeros((n, 2), np.intp),
                   np.zeros((n, 2)), z, z, z, z)  # fmt: skip

    @classmethod
    def with_arcs(
        cls,
        start: NDArray[np.float64],
        end: NDArray[np.float64],
        index: NDArray[np.intp],
        plane: NDArray[np.intp],
        center: NDArray[np.float64],
        clockwise: NDArray[np.bool_],
        turns: NDArray[np.intp],
    ) -> Moves:
        """Moves through ``end``, those of ``index`` arcs about ``center`` in ``plane``.

        An arc turns from its start to its end angle (clockwise or not), a full circle where
        they coincide, plus ``turns - 1`` full circles.
        """
        out = cls.lines(start, end)
        if len(index) == 0:
            return out
        s = np.take_along_axis(out.starts[index], plane, axis=1) - center
        e = np.take_along_axis(out.end[index], plane, axis=1) - center
        radius, end_radius = np.hypot(s[:, 0], s[:, 1]), np.hypot(e[:, 0], e[:, 1])
        angle = np.arctan2(s[:, 1], s[:, 0])
        sign = np.where(clockwise, -1.0, 1.0)
        turn = np.mod(sign * (np.arctan2(e[:, 1], e[:, 0]) - angle), 2 * np.pi)
        full = np.hypot(*(e - s).T) <= 1e-12 * np.maximum(1.0, radius)
        sweep = sign * (np.where(full, 2 * np.pi, turn) + 2 * np.pi * (np.asarray(turns) - 1))
        fields = [out.arc.copy(), out.plane.copy(), out.center.copy(), *np.zeros((4, len(end)))]
        for field, value in zip(fields, (True, plane, center, angle, sweep, radius, end_radius), strict=True):
            field[index] = value
        return cls(out.start, out.end, *fields)

    def __len__(self) -> int:
        return len(self.end)

    @property
    def starts(self) -> NDArray[np.float64]:
        """Start pose of each move, shape ``(n, 6)``."""
        return np.concatenate([self.start[None], self.end[:-1]])


def path_points(moves: Moves, index: NDArray[np.intp], t: NDArray[np.float64]) -> NDArray[np.float64]:
    """Poses of the intended path at parameters ``t`` in ``[0, 1]`` of moves ``index``.

    A line is linear in all six coordinates; an arc is ``center + r(t) (cos θ(t), sin θ(t))``
    in its plane with ``θ`` and ``r`` linear in ``t``, and linear in the other four.
    """
    start = moves.starts[index]
    tt = t[:, None]
    out = start + tt * (moves.end[index] - start)
    arcs = np.flatnonzero(moves.arc[index])
    if arcs.size:
        k, s = index[arcs], t[arcs]
        theta = moves.angle[k] + s * moves.sweep[k]
        radius = moves.radius[k] + s * (moves.end_radius[k] - moves.radius[k])
        u, v = moves.plane[k, 0], moves.plane[k, 1]
        out[arcs, u] = moves.center[k, 0] + radius * np.cos(theta)
        out[arcs, v] = moves.center[k, 1] + radius * np.sin(theta)
    return out


def reached_poses(
    calibrated: Geometry, nominal: Geometry, commanded: NDArray[np.float64], guess: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Where the real machine goes when a nominal controller is commanded ``commanded``.

    The controller's inverse kinematics gives the leg readings; the calibrated machine's
    forward kinematics (from ``guess``) gives the pose those readings reach. NaN where it
    does not converge. This is the simulation a test of a filtered program runs.
    """
    readings = leg_readings(nominal, inverse_kinematics(nominal, commanded))
    return forward_kinematics(calibrated, leg_lengths(calibrated, readings), guess=guess).poses


def orientation_deviation(a: NDArray[np.float64], b: NDArray[np.float64], euler: str) -> NDArray[np.float64]:
    """Rotation angle (rad) between the orientations of poses ``a`` and ``b`` ``(..., 6)``.

    ``2 asin(|Ra - Rb|_F / √8)``: exact, and without the cancellation of the trace formula
    for the micro-radians a tolerance is about.
    """
    diff = rotation_matrices(a[..., 3:], euler) - rotation_matrices(b[..., 3:], euler)
    norm = np.sqrt(np.einsum("...ij,...ij->...", diff, diff))
    return 2.0 * np.arcsin(np.minimum(norm / math.sqrt(8.0), 1.0))


@dataclass(frozen=True, eq=False)
class CorrectedPath:
    """The output points of a block of moves, in path order.

    Attributes
    ----------
    move : ndarray of int, shape (k,)
        Index of the move each point ends a segment of; the last point of a move is its end.
    t : ndarray, shape (k,)
        The point's parameter within its move (1 at the end).
    corrected : ndarray, shape (k, 6)
        Poses to command to the nominal controller (mm, rad).
    counts : ndarray of int, shape (n,)
        Output points (segments) per move.
    position, orientation : float
        Largest deviation of the real machine from the intended path found at the checked
        midpoints (mm, rad).
    """

    move: NDArray[np.intp]
    t: NDArray[np.float64]
    corrected: NDArray[np.float64]
    counts: NDArray[np.intp]
    position: float
    orientation: float


def correct_poses(
    calibrated: Geometry, nominal: Geometry, targets: NDArray[np.float64], move: NDArray[np.intp]
) -> NDArray[np.float64]:
    """``compensate(calibrated, targets, nominal=nominal).corrected_poses``, or a
    :class:`PathError` naming the move of the first target outside the calibrated machine's
    leg length limits or without a corrected pose."""
    if len(targets) == 0:
        return np.empty((0, 6))
    try:
        comp = compensate(calibrated, targets, nominal=nominal)
    except ValidationError:
        # which target: the same computation as compensate's, kept per row
        readings = leg_readings(calibrated, inverse_kinematics(calibrated, targets))
        fk = forward_kinematics(nominal, leg_lengths(nominal, readings), guess=targets)
        k = int(np.flatnonzero(~fk.converged)[0])
        raise PathError(
            int(move[k]),
            "the nominal controller has no pose giving the calibrated leg readings "
            "(its forward kinematics does not converge)",
        ) from None
    if not comp.feasible.all():
        k = int(np.flatnonzero(~comp.feasible)[0])
        raise PathError(int(move[k]), _limits(calibrated, comp.lengths[k], targets[k]))
    assert comp.corrected_poses is not None
    return comp.corrected_poses


def _limits(geometry: Geometry, lengths: NDArray[np.float64], pose: NDArray[np.float64]) -> str:
    assert geometry.leg_length_limits is not None
    lo, hi = geometry.leg_length_limits
    leg = int(np.argmax(np.maximum(lo - lengths, lengths - hi)))
    where = ", ".join(f"{v:.6g}" for v in (*pose[:3], *np.rad2deg(pose[3:])))
    return (
        f"outside the leg length limits of the calibrated machine at ({where}) mm/deg: "
        f"leg {leg + 1} would be {lengths[leg]:.6g} mm (limits {lo:g}-{hi:g} mm)"
    )


def _deviation(
    calibrated: Geometry, nominal: Geometry, commanded: NDArray[np.float64], intended: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Position and orientation deviation of the real machine commanded ``commanded`` from
    ``intended`` (one Newton step of its forward kinematics from ``intended``), and its leg
    lengths."""
    lengths = leg_lengths(calibrated, leg_readings(nominal, inverse_kinematics(nominal, commanded)))
    at, jac = pose_jacobian_from_arrays(
        calibrated.base_joints, calibrated.platform_joints, intended, calibrated.euler
    )
    try:
        step = np.linalg.solve(jac, (lengths - at)[..., None])[..., 0]
    except np.linalg.LinAlgError:  # a singular pose: its deviation is unknown, so too large
        step = np.einsum("...ij,...j->...i", np.linalg.pinv(jac), lengths - at)
        step[np.linalg.matrix_rank(jac) < 6] = np.inf
    step = np.where(np.isfinite(step), step, np.inf)
    position = np.linalg.norm(step[:, :3], axis=1)
    orientation = np.where(
        np.isfinite(position),
        orientation_deviation(intended, intended + np.nan_to_num(step), calibrated.euler),
        np.inf,
    )
    return position, orientation, lengths


def _split(
    calibrated: Geometry,
    nominal: Geometry,
    moves: Moves,
    bad: NDArray[np.intp],
    parts: NDArray[np.intp],
    move: NDArray[np.intp],
    t0: NDArray[np.float64],
    t1: NDArray[np.float64],
    q0: NDArray[np.float64],
    q1: NDArray[np.float64],
) -> tuple[
    NDArray[np.intp], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]
]:
    """Segments ``bad`` cut into ``parts`` equal parts each, the new points corrected."""
    parent = np.repeat(bad, parts)
    count = np.repeat(parts, parts)
    j = np.arange(len(parent)) - np.repeat(np.cumsum(parts) - parts, parts)
    width = (t1 - t0)[parent]
    new_t0 = t0[parent] + width * (j / count)
    new_t1 = np.where(j == count - 1, t1[parent], t0[parent] + width * ((j + 1) / count))
    new_move = move[parent]
    inner = np.flatnonzero(j < count - 1)
    new_q1 = q1[parent]
    new_q1[inner] = correct_poses(
        calibrated, nominal, path_points(moves, new_move[inner], new_t1[inner]), new_move[inner]
    )
    new_q0 = np.empty_like(new_q1)
    new_q0[1:] = new_q1[:-1]
    new_q0[j == 0] = q0[bad]
    return new_move, new_t0, new_t1, new_q0, new_q1


def correct_path(
    calibrated: Geometry,
    nominal: Geometry,
    moves: Moves,
    start_corrected: NDArray[np.float64],
    tolerance: float,
    angle_tolerance: float,
) -> CorrectedPath:
    """Corrected points of a block of moves such that the real machine follows the path.

    Parameters
    ----------
    calibrated, nominal : Geometry
        The real machine and the controller's geometry.
    moves : Moves
        The intended path (mm, rad).
    start_corrected : ndarray, shape (6,)
        The corrected pose of ``moves.start`` (the last output point before the block).
    tolerance, angle_tolerance : float
        Largest deviation of the real machine from the intended path, mm and rad.

    Returns
    -------
    CorrectedPath

    Raises
    ------
    PathError
        Naming the move of a point outside the calibrated leg length limits, without a
        corrected pose, or that cannot be followed within the tolerance.

    Notes
    -----
    Every move starts as one segment (an arc as pieces of at most :data:`ARC_PIECE`), each
    point corrected by :func:`hexcal.core.compensate`. A segment from ``t0`` to ``t1`` of a
    move is accepted when the real machine commanded the midpoint of its corrected ends,
    ``(C(p(t0)) + C(p(t1))) / 2``, reaches the intended ``p((t0 + t1) / 2)`` within
    :data:`CHECK_SHARE` of both tolerances (position distance; rotation angle). Otherwise it
    is cut into ``n = ceil(1.05 sqrt(deviation / allowed))`` equal parts (at least 2: the
    deviation shrinks with the square of the length), the new points are corrected, and the
    parts are checked in the same way, all segments of the block at once.

    Comparing at the same parameter bounds the distance to the path from above. The
    midpoint is where the deviation is largest: a linear interpolation of the smooth map
    ``C`` deviates by ``t (1 - t)`` times its second derivative along the segment, to
    leading order; the next term is smaller by the segment's length over the scale on which
    the correction changes (metres), and the 10 % left covers it and the rounding of the
    written numbers. The real pose is one Newton step of the calibrated forward kinematics
    from the intended pose: exact to second order in the deviation (1e-9 relative for a
    micrometre). Leg length limits are checked at every output point and every accepted
    midpoint.
    """
    n = len(moves)
    if n == 0:
        return CorrectedPath(
            np.empty(0, np.intp), np.empty(0), np.empty((0, 6)), np.zeros(0, np.intp), 0.0, 0.0
        )
    pieces = np.ones(n, dtype=np.intp)
    pieces[moves.arc] = np.maximum(1, np.ceil(np.abs(moves.sweep[moves.arc]) / ARC_PIECE - 1e-9)).astype(
        np.intp
    )
    move = np.repeat(np.arange(n), pieces)
    first = np.cumsum(pieces) - pieces
    k = np.arange(len(move)) - first[move] + 1
    t1 = k / pieces[move]
    last = k == pieces[move]
    points = np.empty((len(move), 6))
    points[last] = moves.end
    inner = np.flatnonzero(~last)
    points[inner] = path_points(moves, move[inner], t1[inner])
    q1 = correct_poses(calibrated, nominal, points, move)
    q0 = np.concatenate([np.asarray(start_corrected, dtype=float)[None], q1[:-1]])
    t0 = np.where(k == 1, 0.0, (k - 1) / pieces[move])
    done: list[tuple[NDArray[np.intp], NDArray[np.float64], NDArray[np.float64]]] = []
    worst = [0.0, 0.0]
    share = (CHECK_SHARE * tolerance, CHECK_SHARE * angle_tolerance)
    for depth in range(MAX_DEPTH + 1):
        tm = 0.5 * (t0 + t1)
        intended = path_points(moves, move, tm)
        position, orientation, lengths = _deviation(calibrated, nominal, 0.5 * (q0 + q1), intended)
        ok = (position <= share[0]) & (orientation <= share[1])
        if ok.any():
            short, long = leg_limit_violations(calibrated, lengths[ok], margin=1e-9)
            if (short | long).any():
                j = np.flatnonzero(ok)[np.flatnonzero(short | long)[0]]
                raise PathError(
                    int(move[j]),
                    "the path between its points leaves the leg length "
                    "limits: " + _limits(calibrated, lengths[j], intended[j]),
                )
            worst = [max(worst[0], float(position[ok].max())), max(worst[1], float(orientation[ok].max()))]
            done.append((move[ok], t1[ok], q1[ok]))
        bad = np.flatnonzero(~ok)
        if bad.size == 0:
            break
        ratio = np.maximum(position[bad] / share[0], orientation[bad] / share[1])
        ratio = np.where(np.isfinite(ratio), ratio, 4.0)
        parts = np.clip(np.ceil(SPLIT_MARGIN * np.sqrt(ratio)), 2, MAX_PARTS).astype(np.intp)
        if depth == MAX_DEPTH or parts.sum() + sum(len(d[0]) for d in done) > MAX_SEGMENTS:
            j = bad[np.argmax(ratio)]
            raise PathError(
                int(move[j]),
                f"cannot follow the path within the tolerance ({tolerance:g} mm, "
                f"{angle_tolerance:g} rad) after {depth} subdivisions: {position[j]:.3g} mm, "
                f"{orientation[j]:.3g} rad off; give a larger --tolerance",
            )
        move, t0, t1, q0, q1 = _split(calibrated, nominal, moves, bad, parts, move, t0, t1, q0, q1)
    out_move = np.concatenate([d[0] for d in done])
    out_t = np.concatenate([d[1] for d in done])
    out_q = np.concatenate([d[2] for d in done])
    order = np.lexsort((out_t, out_move))
    out_move, out_t, out_q = out_move[order], out_t[order], out_q[order]
    return CorrectedPath(out_move, out_t, out_q, np.bincount(out_move, minlength=n), worst[0], worst[1])
