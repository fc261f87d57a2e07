"""Structure in the leg residuals: whether they follow the leg readings.

A leg model that describes the legs leaves residuals that are noise: no function of the
reading explains them. Stroke-dependent errors (a screw's pitch error, a strut that bends
with its extension) leave a smooth curve per leg instead. For each leg, the residuals at the
solution are regressed on Legendre polynomials of its reading (scaled to [-1, 1]) above the
degree the leg model already fits (degree 1: the gain), and the added terms are tested with
an F test; the tests of the six legs are combined with Bonferroni's correction.

>>> rng = np.random.default_rng(0)
>>> readings = rng.uniform(0, 100, (200, 6))
>>> noise = rng.normal(0, 0.01, (200, 6))
>>> leg_structure(noise, readings).significant(0.01)
False
>>> curved = noise + 0.05 * ((readings - 50) / 50) ** 2
>>> leg_structure(curved, readings).significant(0.01)
True
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Highest degree of the tested curves.
DEGREE = 3


@dataclass(frozen=True)
class LegStructure:
    """Per-leg test of the residuals against a curve of the reading.

    Attributes
    ----------
    explained : ndarray, shape (6,)
        Fraction of each leg's residual sum of squares the curve explains.
    p_values : ndarray, shape (6,)
        F-test p-values of the curve's terms (1 where the leg has too few distinct readings).
    curve_rms : ndarray, shape (6,)
        RMS at the readings of the curve beyond the fitted degree (mm).
    degree : int
    """

    explained: NDArray[np.float64]
    p_values: NDArray[np.float64]
    curve_rms: NDArray[np.float64]
    degree: int

    def significant(self, alpha: float) -> bool:
        """Whether some leg's curve is significant at family-wise level ``alpha``."""
        return bool(np.any(self.p_values < alpha / len(self.p_values)))

    def legs(self, alpha: float) -> NDArray[np.intp]:
        """The legs (0-based) whose curve is significant at family-wise level ``alpha``."""
        return np.flatnonzero(self.p_values < alpha / len(self.p_values))


def leg_structure(residuals: ArrayLike, readings: ArrayLike, fitted_degree: int = 1) -> LegStructure:
    """Test each leg's residuals ``(m, 6)`` against polynomials of its readings ``(m, 6)``
    of degrees ``fitted_degree + 1 .. DEGREE`` (NaN rows are left out)."""
    from scipy.special import fdtrc

    res = np.asarray(residuals, dtype=float)
    dl = np.asarray(readings, dtype=float)
    n_legs = res.shape[1]
    explained, p_values, curve = np.zeros(n_legs), np.ones(n_legs), np.zeros(n_legs)
    added = DEGREE - fitted_degree
    for i in range(n_legs):  # six small regressions
        ok = np.isfinite(res[:, i]) & np.isfinite(dl[:, i])
        y, x = res[ok, i], dl[ok, i]
        span = np.ptp(x) if x.size else 0.0
        if added <= 0 or len(np.unique(x)) <= DEGREE + 1 or span == 0:
            continue
        t = 2 * (x - x.min()) / span - 1
        basis = np.polynomial.legendre.legvander(t, DEGREE)
        low = basis[:, : fitted_degree + 1]
        r_low = y - low @ np.linalg.lstsq(low, y, rcond=None)[0]
        fit = basis @ np.linalg.lstsq(basis, y, rcond=None)[0]
        r_all = y - fit
        dof = len(y) - DEGREE - 1
        sse_low, sse_all = float(r_low @ r_low), float(r_all @ r_all)
        if dof <= 0 or sse_all <= 0:
            continue
        f = ((sse_low - sse_all) / added) / (sse_all / dof)
        p_values[i] = float(fdtrc(added, dof, max(f, 0.0)))
        explained[i] = 1 - sse_all / max(float(y @ y), 1e-300)
        curve[i] = float(np.sqrt(np.mean((fit - (y - r_low)) ** 2)))  # beyond the fitted degree
    return LegStructure(explained, p_values, curve, DEGREE)
