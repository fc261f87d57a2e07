"""The ISO 9283 pose accuracy and repeatability, as numbers.

Pure numpy (scipy, deferred, for grouping repeated visits). Lengths in mm, angles in rad.
What each figure is, as implemented:

**ISO 9283** (manipulating industrial robots, performance criteria; its 7.2.1 pose accuracy
and 7.2.2 pose repeatability). For each commanded pose ``c`` visited ``n`` times, with the
attained positions ``(x_j, y_j, z_j)`` and orientation angles ``(a_j, b_j, c_j)``:

- barycentre ``x̄ = (1/n) Σ x_j`` (likewise ``ȳ, z̄``, and ``ā, b̄, c̄``);
- **position accuracy** ``AP_p = sqrt((x̄ - x_c)² + (ȳ - y_c)² + (z̄ - z_c)²)``, with its
  components ``AP_x = x̄ - x_c``, ...; **orientation accuracy** ``AP_a = ā - a_c``,
  ``AP_b = b̄ - b_c``, ``AP_c = c̄ - c_c``;
- **position repeatability** ``RP_l = l̄ + 3 S_l`` where ``l_j = sqrt((x_j - x̄)² + (y_j -
  ȳ)² + (z_j - z̄)²)``, ``l̄ = (1/n) Σ l_j`` and ``S_l = sqrt(Σ (l_j - l̄)² / (n - 1))``;
- **orientation repeatability** ``RP_a = ±3 S_a`` with ``S_a = sqrt(Σ (a_j - ā)² / (n - 1))``
  (likewise ``RP_b``, ``RP_c``; the value given is ``3 S_a``).

The angles are the pose's own three angles (the geometry's Euler sequence); differences of
angles are wrapped to (-π, π]. The standard measures 30 visits per pose; the count is
reported and repeatability needs at least two.

>>> s = pose_statistics(np.zeros((2, 6)), [[1, 0, 0, 0, 0, 0], [3, 0, 0, 0, 0, 0]], [0, 0])
>>> float(s.position_accuracy[0]), float(s.position_repeatability[0])
(2.0, 1.0)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.calibration.limits import VISIT_TOLERANCE_LIMIT
from hexcal.errors import InputError


def check_visit_tolerance(tolerance: float) -> None:
    """Refuse, in one line, a tolerance of repeated visits that is negative or larger than
    :data:`VISIT_TOLERANCE_LIMIT`."""
    if not 0 <= tolerance <= VISIT_TOLERANCE_LIMIT:
        raise InputError(
            f"the tolerance of repeated visits must be between 0 and {VISIT_TOLERANCE_LIMIT:g} mm, got "
            f"{tolerance:g}: visits of one commanded pose read the same leg commands, and a larger "
            "tolerance joins distinct poses"
        )


def repeated_visits(readings: ArrayLike, tolerance: float) -> NDArray[np.intp]:
    """Visits of the same commanded pose: observations whose leg readings all agree within
    ``tolerance`` (mm), chained (single linkage), numbered 0, 1, ... in order of first visit
    (:func:`check_visits` refuses a chain that joins distinct poses).

    >>> repeated_visits([[0] * 6, [5] * 6, [0.001] * 6], 0.01).tolist()
    [0, 1, 0]
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    r = np.asarray(readings, dtype=float).reshape(-1, 6)
    check_visit_tolerance(tolerance)
    pairs = _close_pairs(r, tolerance)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(r), len(r)))
    labels = connected_components(graph, directed=False)[1]
    _, first, inverse = np.unique(labels, return_index=True, return_inverse=True)
    return np.argsort(np.argsort(first))[inverse]


def check_visits(
    readings: ArrayLike, visits: ArrayLike, tolerance: float, ids: tuple[str, ...] | None = None
) -> None:
    """Refuse, in one line, visits that chain distinct commanded poses: a group whose leg
    readings spread (the largest of max - min over each leg) beyond ``tolerance``, which single
    linkage reaches only through intermediate visits, is no set of visits of one pose.

    >>> try:
    ...     check_visits([[0] * 6, [0.008] * 6, [0.016] * 6], [0, 0, 0], 0.01)
    ... except InputError as error:
    ...     print(str(error).split(": ")[1])
    the visits of pose 1 read legs up to 0.016 mm apart; give a smaller tolerance
    """
    r = np.asarray(readings, dtype=float).reshape(-1, 6)
    labels = np.asarray(visits).reshape(-1)
    k = int(labels.max(initial=-1)) + 1
    high = np.full((k, 6), -np.inf)
    low = np.full((k, 6), np.inf)
    np.maximum.at(high, labels, r)
    np.minimum.at(low, labels, r)
    spread = np.max(high - low, axis=1)
    worst = int(np.argmax(spread)) if k else 0
    if k and spread[worst] > tolerance * (1 + 1e-9) + 1e-12:
        first = int(np.flatnonzero(labels == worst)[0])
        name = ids[first] if ids is not None else str(first + 1)
        raise InputError(
            f"the tolerance of repeated visits ({tolerance:g} mm) chains distinct commanded poses into "
            f"one: the visits of pose {name} read legs up to {spread[worst]:.4g} mm apart; give a smaller "
            "tolerance"
        )


#: Above this many rows within the tolerance of one row in the first reading, the pairs are
#: found by a k-d tree instead of the sweep.
_SWEEP_WIDTH = 64


def _close_pairs(r: NDArray[np.float64], tolerance: float) -> NDArray[np.intp]:
    """The pairs of rows ``(i, j)`` whose readings all agree within ``tolerance``: a sweep
    over the rows sorted by the first reading, one vectorised comparison per offset within
    the window that reading allows (repeated visits make it as wide as the visits), or a k-d
    tree when that window is wide."""
    order = np.argsort(r[:, 0], kind="stable")
    first = r[order, 0]
    width = int(
        np.max(np.searchsorted(first, first + tolerance, side="right") - np.arange(len(r)), initial=1)
    )
    if width > _SWEEP_WIDTH:
        from scipy.spatial import cKDTree

        return cKDTree(r).query_pairs(tolerance, p=np.inf, output_type="ndarray")
    sorted_r = r[order]
    found = []
    for k in range(1, width):
        close = np.all(np.abs(sorted_r[k:] - sorted_r[:-k]) <= tolerance, axis=1)
        i = np.flatnonzero(close)
        found.append(np.column_stack([order[i], order[i + k]]))
    return np.concatenate(found) if found else np.zeros((0, 2), dtype=np.intp)


def _wrap(angles: NDArray) -> NDArray:
    return np.mod(angles + np.pi, 2 * np.pi) - np.pi


@dataclass(frozen=True)
class PoseStatistics:
    """ISO 9283 figures per commanded pose (module docstring): arrays over the poses that
    were visited, in order of first visit. ``accuracy`` ``(k, 6)``: ``AP_x, AP_y, AP_z`` (mm),
    ``AP_a, AP_b, AP_c`` (rad); ``position_accuracy`` ``AP_p`` (mm); ``position_repeatability``
    ``RP_l`` (mm) and ``orientation_repeatability`` ``(k, 3)`` ``3 S_a, 3 S_b, 3 S_c`` (rad),
    NaN for a pose visited once."""

    ids: tuple[str, ...]
    visits: NDArray[np.intp]
    commanded: NDArray[np.float64]
    accuracy: NDArray[np.float64]
    position_accuracy: NDArray[np.float64]
    position_repeatability: NDArray[np.float64]
    orientation_repeatability: NDArray[np.float64]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: one record per commanded pose (NaN as None by the strict JSON writer)."""
        rows = []
        for k, pid in enumerate(self.ids):
            ap = self.accuracy[k]
            rows.append(
                {
                    "id": pid,
                    "visits": int(self.visits[k]),
                    "commanded": self.commanded[k].tolist(),
                    "AP_p_mm": float(self.position_accuracy[k]),
                    "AP_xyz_mm": ap[:3].tolist(),
                    "AP_abc_rad": ap[3:].tolist(),
                    "RP_l_mm": float(self.position_repeatability[k]),
                    "RP_abc_rad": self.orientation_repeatability[k].tolist(),
                }
            )
        return {"poses": rows, "repeated": int(np.sum(self.visits >= 2))}


def pose_statistics(
    commanded: ArrayLike, attained: ArrayLike, visits: ArrayLike, ids: tuple[str, ...] | None = None
) -> PoseStatistics:
    """ISO 9283 pose accuracy and repeatability of every commanded pose (module docstring).

    Parameters
    ----------
    commanded, attained : array_like, shape (m, 6)
        Per observation, its commanded pose and the pose attained (x, y, z mm; three angles
        rad); the commanded pose of a visited pose is the mean over its visits.
    visits : array_like of int, shape (m,)
        Which commanded pose each observation visits (:func:`repeated_visits`).
    ids : tuple of str, optional
        A name per observation: a pose is named by its first visit's.
    """
    cmd = np.asarray(commanded, dtype=float).reshape(-1, 6)
    att = np.asarray(attained, dtype=float).reshape(-1, 6)
    labels = np.asarray(visits).reshape(-1)
    if len(cmd) != len(att) or len(att) != len(labels):
        raise InputError("pose statistics: commanded, attained poses and visits must have one row each")
    if not (np.all(np.isfinite(cmd)) and np.all(np.isfinite(att))):
        raise InputError(
            "pose statistics need finite commanded and attained poses (does the instrument give the pose?)"
        )
    _, first, group = np.unique(labels, return_index=True, return_inverse=True)
    order = np.argsort(first)  # poses in order of first visit
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    group, first = rank[group], first[order]
    k = len(first)
    n = np.bincount(group, minlength=k).astype(float)

    def mean(values: NDArray) -> NDArray:
        return np.stack([np.bincount(group, values[:, j], k) for j in range(values.shape[1])], 1) / n[:, None]

    # angles relative to the first visit's commanded angles, wrapped: no jump at ±π
    ref = cmd[first][group]
    rel_cmd = np.column_stack([cmd[:, :3], _wrap(cmd[:, 3:] - ref[:, 3:])])
    rel_att = np.column_stack([att[:, :3], _wrap(att[:, 3:] - ref[:, 3:])])
    c = mean(rel_cmd)
    bary = mean(rel_att)
    accuracy = bary - c
    spread = rel_att - bary[group]
    dist = np.linalg.norm(spread[:, :3], axis=1)  # l_j
    l_bar = np.bincount(group, dist, k) / n
    with np.errstate(invalid="ignore", divide="ignore"):
        s_l = np.sqrt(np.bincount(group, (dist - l_bar[group]) ** 2, k) / (n - 1))
        squares = np.stack([np.bincount(group, spread[:, 3 + j] ** 2, k) for j in range(3)], 1)
        s_abc = np.sqrt(squares / (n - 1)[:, None])
    once = n < 2
    s_l[once], s_abc[once] = np.nan, np.nan
    names = tuple(ids[i] for i in first) if ids is not None else tuple(str(i + 1) for i in first)
    commanded_k = np.column_stack([c[:, :3], _wrap(c[:, 3:] + cmd[first, 3:])])
    return PoseStatistics(
        names,
        n.astype(np.intp),
        commanded_k,
        accuracy,
        np.linalg.norm(accuracy[:, :3], axis=1),
        l_bar + 3 * s_l,
        3 * s_abc,
    )
