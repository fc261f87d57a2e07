"""A given noise model tested against the data, per group and session.

The whitened residual sums ``Ω_g`` and redundancies ``r_g`` of each noise group
(:func:`hexcal.estimation.noise_estimation.group_statistics`) under a *given* noise model
test it: ``Ω_g`` follows approximately χ²(r_g), and ``sqrt(Ω_g / r_g)`` is the ratio of the
σ the data imply to the given one.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.noise import NoiseModel
from hexcal.estimation.noise_estimation import MIN_REDUNDANCY, NOISE_UNITS, group_statistics
from hexcal.estimation.problem import Problem


@dataclass(frozen=True)
class NoiseCheck:
    """A given noise model tested against the data, per group.

    Attributes
    ----------
    groups : tuple of str
    given : ndarray, shape (g,)
        σ of the given model (mm, rad).
    ratio : ndarray, shape (g,)
        σ the data imply over the given σ.
    redundancy : ndarray, shape (g,)
    p_value : ndarray, shape (g,)
        Two-sided p-value of ``Ω_g`` against χ²(r_g).
    alpha : float
    """

    groups: tuple[str, ...]
    given: NDArray[np.float64]
    ratio: NDArray[np.float64]
    redundancy: NDArray[np.float64]
    p_value: NDArray[np.float64]
    alpha: float

    @property
    def disagree(self) -> tuple[str, ...]:
        """Groups whose σ the data reject at level ``alpha`` (Bonferroni over the groups)."""
        bad = (self.p_value < self.alpha / len(self.groups)) & (self.redundancy >= MIN_REDUNDANCY)
        return tuple(g for g, b in zip(self.groups, bad, strict=True) if b)

    def describe(self) -> str:
        """One line: the groups that disagree and by how much."""
        if not self.disagree:
            return "the given noise agrees with the data"
        parts = []
        for g in self.disagree:
            k = self.groups.index(g)
            unit = NOISE_UNITS.get(g.split()[-1], "")
            parts.append(
                f"{g} σ {self.given[k] * self.ratio[k]:.3g} {unit} from the data, "
                f"{self.given[k]:.3g} {unit} given (× {self.ratio[k]:.3g})"
            )
        return "; ".join(parts)

    def to_dict(self) -> dict[str, Any]:
        return {
            g: {
                "given": float(self.given[k]),
                "ratio": float(self.ratio[k]),
                "redundancy": float(self.redundancy[k]),
                "p_value": float(self.p_value[k]),
                "disagrees": g in self.disagree,
            }
            for k, g in enumerate(self.groups)
        }


def check_noise(
    problem: Problem, noise: NoiseModel | Sequence[NoiseModel], result: Any, alpha: float = 0.01
) -> NoiseCheck:
    """Test a given noise model against the data at the solution ``result`` of an ``ml`` fit
    under it: per group ``Ω_g ~ χ²(r_g)``, two-sided."""
    from scipy.special import chdtr

    noises = (noise,) * len(problem.parts) if isinstance(noise, NoiseModel) else tuple(noise)
    stats = group_statistics(problem, noises, result)
    given = []
    for k, name in stats.keys:
        sig_all = dict(zip(("leg", "position", "orientation"), noises[k].sigmas, strict=True))
        given.append(sig_all.get(name, np.nan))
    given = np.array(given)
    red = np.maximum(stats.redundancy, 1e-9)
    cdf = chdtr(red, stats.omega)
    p = np.clip(2 * np.minimum(cdf, 1 - cdf), 0.0, 1.0)
    return NoiseCheck(stats.groups, given, stats.ratio, stats.redundancy, p, alpha)
