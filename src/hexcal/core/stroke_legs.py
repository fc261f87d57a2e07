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
scale is 1 mm, the scale of ``l0`` and of a joint coordinate (columns of one size). Outside
the stroke the series extrapolates; :meth:`StrokeLegs.readings` (inverse kinematics,
compensation) refuses a model whose length does not grow with the reading over the stroke.

>>> legs = StrokeLegs(3, np.zeros(6), np.full(6, 100.0))
>>> block = np.concatenate([np.full(6, 600.0), np.ones(6), np.full(6, 0.1), np.zeros(6)])
>>> round(float(legs.lengths(block, np.full((1, 6), 100.0))[0, 0]), 6)  # 600 + 100 + 0.1 P2(1)
700.1
>>> legs.names()[12:14]
('p2_1', 'p2_2')
"""

from __future__ import annotations

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
        return (2 * reading - self.low - self.high) / (self.high - self.low)

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
        _, d = legendre_values(self._x(reading), self.degree)
        curve = np.einsum("...k,...k->...", theta[..., 2:], d[..., 2:]) * 2 / (self.high - self.low)
        return theta[..., 1] + curve

    def stroke_range(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return self.low.copy(), self.high.copy()

    def term_scales(self) -> NDArray[np.float64]:
        return np.ones(len(self.terms))  # |P_k| <= 1: a term moves its leg by at most its value (mm)

    # -- the inverse ------------------------------------------------------------------------
    def check_invertible(self, block: ArrayLike) -> None:
        """Refuse (:class:`GeometryError`, naming the leg) a block whose length does not grow
        with the reading everywhere on a leg's stroke: no reading is then the one of a length."""
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
        """Readings ``(..., 6)`` of ``lengths`` by Newton's method (vectorised), after
        :meth:`check_invertible`; :class:`GeometryError` where it does not converge."""
        self.check_invertible(block)
        theta = self.thetas(block)
        lengths = np.asarray(lengths, dtype=float)
        reading = (lengths - theta[..., 0]) / theta[..., 1]
        for _ in range(60):
            step = (self.length(theta, reading) - lengths) / self.slope(theta, reading)
            reading = reading - step
            if np.all(np.abs(step) <= 1e-12 * (1.0 + np.abs(reading))):
                return reading
        worst = np.unravel_index(int(np.nanargmax(np.abs(step))), np.shape(step))
        raise GeometryError(
            f"leg {int(worst[-1]) + 1}: no reading gives the length {float(lengths[worst]):.6g} mm under the "
            "stroke model (far outside its stroke?)"
        )

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
    """Each leg's stroke in readings: from the geometry's leg length limits when it has them
    (``(limit - l0) / g``), else the range of ``readings (m, 6)``; :class:`GeometryError` if
    neither gives a stroke."""
    if geometry.leg_length_limits is not None:
        ends = (geometry.leg_length_limits[:, None] - geometry.initial_leg_lengths) / geometry.leg_gains
        return ends.min(axis=0), ends.max(axis=0)
    if readings is None or np.size(readings) == 0:
        raise GeometryError("the stroke model needs each leg's stroke: give leg_length_limits or readings")
    dl = np.asarray(readings, dtype=float).reshape(-1, N_LEGS)
    low, high = np.nanmin(dl, axis=0), np.nanmax(dl, axis=0)
    flat = np.flatnonzero(~(high > low))
    if flat.size:
        raise GeometryError(f"leg {int(flat[0]) + 1}: its readings do not move, so they give it no stroke")
    return low, high


def with_leg_model(geometry: Any, model: LegModel) -> Any:
    """``geometry`` with leg model ``model``: ``l0`` and gains kept, the terms of the same name
    kept, new ones at 0 (a linear geometry becomes a stroke one with a straight curve, and back)."""
    old = dict(zip(geometry.leg_model.terms, geometry.leg_terms.T, strict=True))
    terms = np.stack([old.get(t, np.zeros(N_LEGS)) for t in model.terms], axis=1) if model.terms else None
    return geometry.replace(leg_model=model, leg_terms=terms)


register_leg_model(StrokeLegs)
