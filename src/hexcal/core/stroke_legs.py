"""A stroke-dependent leg model: the linear legs plus a smooth curve of each leg's reading.

A screw's pitch error, a belt that stretches, a strut that bends as it extends: the length a
reading gives is then not a straight line of the reading. :class:`StrokeLegs` adds to each
leg's ``l0_i + g_i dl_i`` a Legendre series of the reading mapped to ``[-1, 1]`` over the
leg's stroke ``[low_i, high_i]`` (readings, in the readings' own unit),

    l_i = l0_i + g_i dl_i + Σ_{k=2..D} p_{k,i} P_k(x_i),   x_i = (2 dl_i - low_i - high_i) / (high_i - low_i),

whose terms ``p{k}_{i}`` (mm) start at 0. ``P_0`` and ``P_1`` are left out: they are the
initial length and the gain. The degree ``D`` (2 to :data:`MAX_DEGREE`) and the stroke are the
model's settings, stored in the geometry file with the terms::

    leg_model:
      kind: stroke
      degree: 3
      stroke: {low: [6 readings], high: [6 readings]}
      terms: {p2: [6 values, mm], p3: [6 values, mm]}

Every ``|P_k| <= 1`` on the stroke, so a term moves a leg by at most its value: its solver
scale is 1 mm, the scale of ``l0`` and of a joint coordinate (columns of one size).

**Beyond the stroke the curve is held** at its value at the nearer end: ``x_i`` is clipped to
``[-1, 1]``, so a leg continues as the straight line of its gain ``g_i`` through the curve's end
point (continuous, its slope ``g_i`` outside). A polynomial fitted over the readings a
campaign covered says nothing about readings it did not reach, and its end derivatives are its
least determined quantity (``P_k'(1) = k (k + 1) / 2``): a tangent continued from them grows
without bound with the term's error. Held, the curve's error beyond the stroke is its error at
the end, and the leg follows its mean gain there, as linear legs do. It is also LinuxCNC's own
rule beyond a compensation table (the end trims held), so an exported table agrees with the
model at every joint position (:mod:`hexcal.io.linuxcnc_comp`). The inverse always exists and
is monotone when the length grows with the reading on the stroke (:meth:`StrokeLegs.readings`
refuses a model where it does not); :func:`stroke_excess` says how far readings go beyond.

>>> legs = StrokeLegs(3, np.zeros(6), np.full(6, 100.0))
>>> block = np.concatenate([np.full(6, 600.0), np.ones(6), np.full(6, 0.1), np.zeros(6)])
>>> round(float(legs.lengths(block, np.full((1, 6), 100.0))[0, 0]), 6)  # 600 + 100 + 0.1 P2(1)
700.1
>>> legs.names()[12:14]
('p2_1', 'p2_2')
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.legs import N_LEGS, LegModel, register_leg_model
from hexcal.errors import GeometryError

#: Highest degree of the series (a higher one follows the noise of any real session).
MAX_DEGREE = 8

#: Default degree: a cubic (a bow and an S of the stroke).
DEFAULT_DEGREE = 3

#: Points per leg at which :meth:`StrokeLegs.readings` checks that the length grows.
_CHECK_POINTS = 257

#: Share of a leg's stroke that readings may pass either end by before commands warn
#: (:func:`stroke_excess`): a little beyond the readings a campaign covered is usual (the
#: corners of a workspace box, a new session), and the held curve changes slowly there.
STROKE_MARGIN = 0.05

#: Row identifiers :class:`StrokeExcess` keeps (the first rows beyond the margin).
_KEPT_IDS = 20


def legendre_values(x: NDArray[np.float64], degree: int) -> tuple[NDArray, NDArray]:
    """``P_k(x)`` and ``P_k'(x)`` for ``k = 0 .. degree``, each ``(..., degree + 1)``
    (Bonnet's recurrence and ``P'_{k+1} = P'_{k-1} + (2k + 1) P_k``)."""
    p = [np.ones_like(x), x]
    d = [np.zeros_like(x), np.ones_like(x)]
    for k in range(1, degree):
        p.append(((2 * k + 1) * x * p[k] - k * p[k - 1]) / (k + 1))
        d.append(d[k - 1] + (2 * k + 1) * p[k])
    return np.stack(p[: degree + 1], axis=-1), np.stack(d[: degree + 1], axis=-1)


class StrokeLegs(LegModel):
    """``l = l0 + g dl + Σ p_k P_k(x(dl))``, ``k = 2 .. degree`` (see the module).

    Parameters
    ----------
    degree : int
        Highest Legendre degree, 2 to :data:`MAX_DEGREE` (``degree - 1`` terms per leg).
    low, high : array_like, shape (6,)
        Each leg's stroke in readings: the range mapped to ``[-1, 1]``.
    """

    name = "stroke"

    def __init__(self, degree: int = DEFAULT_DEGREE, low: ArrayLike = -1.0, high: ArrayLike = 1.0) -> None:
        if isinstance(degree, bool) or not isinstance(degree, int | np.integer):
            raise GeometryError(f"leg_model.degree must be an integer, got {degree!r}")
        if not 2 <= degree <= MAX_DEGREE:
            raise GeometryError(f"leg_model.degree must be 2 to {MAX_DEGREE}, got {degree}")
        self.degree = int(degree)
        self.low = _six(low, "leg_model.stroke.low")
        self.high = _six(high, "leg_model.stroke.high")
        bad = np.flatnonzero(~(self.high > self.low))
        if bad.size:
            k = int(bad[0])
            raise GeometryError(
                f"leg_model.stroke: leg {k + 1} has low {self.low[k]:g} >= high {self.high[k]:g}; "
                "give each leg's stroke as low < high readings"
            )
        self.terms = tuple(f"p{k}" for k in range(2, self.degree + 1))

    # -- the per-leg functions ------------------------------------------------------------
    def _x(self, reading: NDArray[np.float64]) -> NDArray[np.float64]:
        """The reading on ``[-1, 1]`` over the stroke, clipped there (the curve is held beyond)."""
        return np.clip((2 * reading - self.low - self.high) / (self.high - self.low), -1.0, 1.0)

    def length(self, theta: NDArray[np.float64], reading: NDArray[np.float64]) -> NDArray[np.float64]:
        p, _ = legendre_values(self._x(reading), self.degree)
        return (
            theta[..., 0] + theta[..., 1] * reading + np.einsum("...k,...k->...", theta[..., 2:], p[..., 2:])
        )

    def length_jacobian(
        self, theta: NDArray[np.float64], reading: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        p, _ = legendre_values(self._x(reading), self.degree)
        shape = np.broadcast_shapes(theta.shape[:-1], np.shape(reading))
        one = np.ones(shape)
        return np.concatenate(
            [np.stack([one, one * reading], axis=-1), np.broadcast_to(p[..., 2:], (*shape, len(self.terms)))],
            axis=-1,
        )

    def slope(self, theta: NDArray[np.float64], reading: NDArray[np.float64]) -> NDArray[np.float64]:
        """``d length / d reading``: the gain plus the curve's slope on the stroke (its ends
        included, one-sided), the gain alone beyond it."""
        reading = np.asarray(reading, dtype=float)
        _, d = legendre_values(self._x(reading), self.degree)
        curve = np.einsum("...k,...k->...", theta[..., 2:], d[..., 2:]) * 2 / (self.high - self.low)
        on = (reading >= self.low) & (reading <= self.high)
        return theta[..., 1] + np.where(on, curve, 0.0)

    def stroke_range(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return self.low.copy(), self.high.copy()

    def term_scales(self) -> NDArray[np.float64]:
        return np.ones(len(self.terms))  # |P_k| <= 1: a term moves its leg by at most its value (mm)

    # -- the inverse ------------------------------------------------------------------------
    def check_invertible(self, block: ArrayLike) -> None:
        """Refuse (:class:`GeometryError`, naming the leg) a block whose length does not grow
        with the reading everywhere on a leg's stroke: no reading is then the one of a length.

        Beyond the stroke the length grows with the gain, which is then above 0 too: it is the
        first Legendre moment of the length over the stroke (the terms ``P_k``, ``k >= 2``, have
        none), ``(3/2) ∫ l x dx = (3/2) ∫ (l(x) - l(0)) x dx > 0`` for a growing ``l``."""
        theta = self.thetas(block)
        if theta.ndim > 2:
            theta = theta.reshape(-1, N_LEGS, self.per_leg)
        t = np.linspace(0.0, 1.0, _CHECK_POINTS)[:, None]
        grid = self.low + t * (self.high - self.low)  # (points, 6)
        slopes = self.slope(theta[..., None, :, :], grid)  # (..., points, 6)
        bad = np.argwhere(slopes.reshape(-1, _CHECK_POINTS, N_LEGS) <= 0)
        if bad.size:
            _, point, leg = (int(v) for v in bad[0])
            raise GeometryError(
                f"leg {leg + 1}: the stroke model's length does not grow with the reading at "
                f"{grid[point, leg]:.6g} (stroke [{self.low[leg]:g}, {self.high[leg]:g}]), so no reading "
                "can be computed for a length; refit with a lower --leg-model degree"
            )

    def readings(self, block: ArrayLike, lengths: ArrayLike) -> NDArray[np.float64]:
        """Readings ``(..., 6)`` of ``lengths``, after :meth:`check_invertible`: beyond the
        stroke the straight line of the gain (exact); on it, Newton's method kept inside the
        bracket of the stroke's ends (vectorised; bisection where a step would leave it)."""
        self.check_invertible(block)
        theta = self.thetas(block)
        lengths = np.asarray(lengths, dtype=float)
        shape = np.broadcast_shapes(theta.shape[:-1], lengths.shape)
        theta = np.broadcast_to(theta, (*shape, self.per_leg))
        lengths = np.broadcast_to(lengths, shape)
        low, high = np.broadcast_to(self.low, shape), np.broadcast_to(self.high, shape)
        at_low, at_high = self.length(theta, low), self.length(theta, high)
        gain = theta[..., 1]
        # beyond the ends: the line of the gain through the curve's end point
        reading = np.where(
            lengths <= at_low, low + (lengths - at_low) / gain, high + (lengths - at_high) / gain
        )
        on = (lengths > at_low) & (lengths < at_high)
        if not on.any():
            return reading
        lo, hi = low.copy(), high.copy()
        span = np.where(on, at_high - at_low, 1.0)
        x = np.where(on, low + (lengths - at_low) / span * (high - low), reading)  # the chord's reading
        for _ in range(100):
            error = np.where(on, self.length(theta, x) - lengths, 0.0)
            lo, hi = np.where(error < 0, x, lo), np.where(error > 0, x, hi)
            nxt = x - error / self.slope(theta, x)
            nxt = np.where((nxt > lo) & (nxt < hi), nxt, 0.5 * (lo + hi))  # bisect when Newton leaves
            nxt = np.where(error == 0, x, nxt)
            done = np.all(np.abs(nxt - x) <= 1e-12 * (1.0 + np.abs(x)))
            x = nxt
            if done:
                break
        return x

    # -- settings and files -------------------------------------------------------------
    def settings(self) -> tuple[Any, ...]:
        return (self.degree, tuple(self.low.tolist()), tuple(self.high.tolist()))

    def to_dict(self, block: ArrayLike) -> Any:
        values = np.asarray(block, dtype=float)[12:].reshape(-1, N_LEGS)
        return {
            "kind": self.name,
            "degree": self.degree,
            "stroke": {"low": self.low.tolist(), "high": self.high.tolist()},
            "terms": {term: row.tolist() for term, row in zip(self.terms, values, strict=True)},
        }

    @classmethod
    def from_dict(cls, value: Any, where: str = "leg_model") -> tuple[LegModel, NDArray[np.float64]]:
        if not isinstance(value, dict):
            raise GeometryError(
                f"{where}: the stroke model needs its stroke: a mapping with kind, degree, stroke"
            )
        unknown = sorted(set(value) - {"kind", "degree", "stroke", "terms"})
        if unknown:
            raise GeometryError(f"{where}: unknown key(s): {', '.join(map(str, unknown))}")
        stroke = value.get("stroke")
        if not isinstance(stroke, dict) or set(stroke) != {"low", "high"}:
            raise GeometryError(f"{where}.stroke: a mapping with low and high (six readings each)")
        model = cls(value.get("degree", DEFAULT_DEGREE), stroke["low"], stroke["high"])
        terms = value.get("terms") or {}
        if not isinstance(terms, dict):
            raise GeometryError(f"{where}.terms: a mapping of {', '.join(model.terms)} to six values each")
        extra = sorted(set(map(str, terms)) - set(model.terms))
        if extra:
            raise GeometryError(
                f"{where}.terms: {', '.join(extra)} beyond degree {model.degree} "
                f"(terms {', '.join(model.terms)})"
            )
        rows = [_six(terms.get(t, [0.0] * N_LEGS), f"{where}.terms.{t}") for t in model.terms]
        return model, np.stack(rows, axis=1)

    def __repr__(self) -> str:
        return f"StrokeLegs(degree={self.degree})"


def _six(value: Any, what: str) -> NDArray[np.float64]:
    try:
        out = np.array(np.broadcast_to(np.asarray(value, dtype=float), (N_LEGS,)))
    except (TypeError, ValueError) as exc:
        raise GeometryError(f"{what}: six numbers, one per leg ({exc})") from None
    if np.ndim(value) not in (0, 1) or not np.all(np.isfinite(out)):
        raise GeometryError(f"{what}: six finite numbers, one per leg")
    return out


def stroke_of(geometry: Any, readings: ArrayLike | None = None) -> tuple[NDArray, NDArray]:
    """Each leg's stroke in readings: the range of ``readings (m, 6)`` when given (the stroke a
    campaign covered, over which its curve is determined: beyond it the model holds its curve),
    else, before any reading (planning), from the geometry's leg length limits
    (``(limit - l0) / g``); :class:`GeometryError` if neither gives a stroke."""
    if readings is not None and np.size(readings):
        dl = np.asarray(readings, dtype=float).reshape(-1, N_LEGS)
        low, high = np.nanmin(dl, axis=0), np.nanmax(dl, axis=0)
        flat = np.flatnonzero(~(high > low))
        if flat.size:
            leg = int(flat[0]) + 1
            raise GeometryError(f"leg {leg}: its readings do not move, so they give it no stroke")
        return low, high
    if geometry.leg_length_limits is not None:
        ends = (geometry.leg_length_limits[:, None] - geometry.initial_leg_lengths) / geometry.leg_gains
        return ends.min(axis=0), ends.max(axis=0)
    raise GeometryError("the stroke model needs each leg's stroke: give leg_length_limits or readings")


@dataclass(frozen=True)
class StrokeExcess:
    """How far readings go beyond each leg's calibrated stroke (:func:`stroke_excess`).

    Attributes
    ----------
    low, high : ndarray, shape (6,)
        Each leg's stroke (readings).
    gains : ndarray, shape (6,)
        Each leg's gain (mm per unit of reading), to say an excess as a length.
    margin : float
        The share of the stroke beyond which a row is flagged.
    rows : int
        Rows (poses, program points, readings) checked.
    beyond_rows, flagged_rows : int
        Rows with a leg beyond its stroke at all, and by more than the margin.
    beyond : ndarray of int, shape (6,)
        Per leg, the rows whose reading is beyond its stroke.
    below, above : ndarray, shape (6,)
        Per leg, the largest excess below ``low`` and above ``high`` (readings; 0 where none).
    ids : tuple of str
        Identifiers of the first flagged rows (up to 20; when given).
    """

    low: NDArray[np.float64]
    high: NDArray[np.float64]
    gains: NDArray[np.float64]
    margin: float
    rows: int
    beyond_rows: int
    flagged_rows: int
    beyond: NDArray[np.int_]
    below: NDArray[np.float64]
    above: NDArray[np.float64]
    ids: tuple[str, ...] = ()

    @property
    def share(self) -> NDArray[np.float64]:
        """Per leg, the largest excess as a share of the stroke."""
        return np.maximum(self.below, self.above) / (self.high - self.low)

    @property
    def beyond_share(self) -> float:
        """The share of the rows with a leg beyond its stroke (0 with no row)."""
        return self.beyond_rows / self.rows if self.rows else 0.0

    def merge(self, other: StrokeExcess) -> StrokeExcess:
        """The figures of both sets of rows (the same model and margin), e.g. of two blocks."""
        return StrokeExcess(
            self.low,
            self.high,
            self.gains,
            self.margin,
            self.rows + other.rows,
            self.beyond_rows + other.beyond_rows,
            self.flagged_rows + other.flagged_rows,
            self.beyond + other.beyond,
            np.maximum(self.below, other.below),
            np.maximum(self.above, other.above),
            (self.ids + other.ids)[:_KEPT_IDS],
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain-Python form (``beyond_stroke`` of the JSON outputs)."""
        return {
            "rows": self.rows,
            "beyond_rows": self.beyond_rows,
            "beyond_share": self.beyond_share,
            "margin": self.margin,
            "flagged_rows": self.flagged_rows,
            "largest_share_of_stroke": float(self.share.max()),
            "largest_mm": float(np.max(np.maximum(self.below, self.above) * self.gains)),
            "low": self.low.tolist(),
            "high": self.high.tolist(),
            "beyond": self.beyond.tolist(),
            "below": self.below.tolist(),
            "above": self.above.tolist(),
        }

    def legs_text(self) -> str:
        """Each leg beyond its stroke and by how much, e.g. ``leg 3 up to 0.42 above its stroke
        [1.28, 3.26] (20% of it, 30.4 mm)``; the legs beyond the margin, else all beyond."""
        share = self.share
        legs = np.flatnonzero(share > self.margin)
        if not legs.size:
            legs = np.flatnonzero(share > 0)
        parts = []
        for leg in legs:
            up = self.above[leg] >= self.below[leg]
            side, amount = ("above", self.above[leg]) if up else ("below", self.below[leg])
            parts.append(
                f"leg {leg + 1} up to {amount:.3g} {side} its stroke [{self.low[leg]:.4g}, "
                f"{self.high[leg]:.4g}] ({share[leg]:.0%} of it, {amount * self.gains[leg]:.3g} mm)"
            )
        return "; ".join(parts)

    def warning(self, what: str = "pose(s)") -> str | None:
        """One line when rows take a leg beyond its stroke by more than the margin, else None."""
        if not self.flagged_rows:
            return None
        ids, left = "", self.flagged_rows - len(self.ids)
        if self.ids:
            ids = f" ({', '.join(self.ids)}{f' and {left} more' if left > 0 else ''})"
        return (
            f"{self.flagged_rows} of {self.rows} {what}{ids} take a leg beyond its calibrated stroke by "
            f"more than {self.margin:.0%} of it, where the stroke model holds its curve (the leg follows "
            f"its gain; not measured there): {self.legs_text()}"
        )


def stroke_excess(
    geometry: Any,
    readings: ArrayLike,
    margin: float = STROKE_MARGIN,
    ids: Sequence[Any] | None = None,
) -> StrokeExcess | None:
    """How far ``readings (m, 6)`` go beyond each leg's calibrated stroke on ``geometry``
    (``None`` when its leg model has no stroke): per leg, the rows beyond and the largest
    excess below and above (readings), the rows beyond by more than ``margin`` (a share of the
    stroke) and, with ``ids`` (one per row), the first of them. NaN readings are not beyond.

    >>> from hexcal.core import preset
    >>> machine = preset("paper-hmt")
    >>> stroke = with_leg_model(machine, StrokeLegs(3, np.zeros(6), np.full(6, 100.0)))
    >>> excess = stroke_excess(stroke, [[50.0] * 6, [110.0] + [50.0] * 5], ids=["p1", "p2"])
    >>> excess.beyond_rows, excess.flagged_rows, excess.ids, round(float(excess.share[0]), 3)
    (1, 1, ('p2',), 0.1)
    """
    ranges = geometry.leg_model.stroke_range()
    if ranges is None:
        return None
    if not (np.isfinite(margin) and margin >= 0):
        raise ValueError(f"margin must be a share >= 0 of the stroke, got {margin}")
    low, high = ranges
    dl = np.asarray(readings, dtype=float).reshape(-1, N_LEGS)
    below = np.nan_to_num(np.clip(low - dl, 0.0, None))
    above = np.nan_to_num(np.clip(dl - high, 0.0, None))
    out = (below > 0) | (above > 0)
    flagged = np.any(np.maximum(below, above) > margin * (high - low), axis=1)
    kept: tuple[str, ...] = ()
    if ids is not None:
        kept = tuple(str(ids[k]) for k in np.flatnonzero(flagged)[:_KEPT_IDS])
    empty = np.zeros(N_LEGS)
    return StrokeExcess(
        low,
        high,
        np.asarray(geometry.leg_gains, dtype=float),
        float(margin),
        len(dl),
        int(np.sum(out.any(axis=1))),
        int(np.sum(flagged)),
        out.sum(axis=0),
        below.max(axis=0) if len(dl) else empty,
        above.max(axis=0) if len(dl) else empty,
        kept,
    )


def with_leg_model(geometry: Any, model: LegModel) -> Any:
    """``geometry`` with leg model ``model``: ``l0`` and gains kept, the terms of the same name
    kept, new ones at 0 (a linear geometry becomes a stroke one with a straight curve, and back)."""
    old = dict(zip(geometry.leg_model.terms, geometry.leg_terms.T, strict=True))
    terms = np.stack([old.get(t, np.zeros(N_LEGS)) for t in model.terms], axis=1) if model.terms else None
    return geometry.replace(leg_model=model, leg_terms=terms)


register_leg_model(StrokeLegs)
