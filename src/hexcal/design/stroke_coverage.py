"""How much of each leg's stroke a pose set covers, for a leg model with a curve of the stroke.

A stroke-dependent leg model (:class:`hexcal.core.stroke_legs.StrokeLegs`) describes each
leg's length by a curve of its reading over the leg's stroke ``[low, high]``. Poses determine
that curve only where their readings go: outside, the fitted curve extrapolates. So the
poses of a campaign must cover each leg's stroke. :func:`stroke_coverage` gives, per leg, the
readings' range at planned poses (the nominal inverse kinematics) and its share of the
stroke; :data:`COVERAGE_WARNING` is the share below which planning warns.

>>> from hexcal.core import preset, workspace_corners
>>> from hexcal.core.stroke_legs import StrokeLegs
>>> machine = preset("paper-hmt")
>>> stroke = machine.replace(leg_model=StrokeLegs(3, [0.0] * 6, [495.0] * 6), leg_terms=np.zeros((6, 2)))
>>> cover = stroke_coverage(stroke, workspace_corners(machine))
>>> [round(float(c), 2) for c in cover.covered][:2]
[0.76, 0.82]
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core import Geometry, as_poses, inverse_kinematics, leg_readings

#: A leg whose poses cover less of its stroke than this share gets a warning: the stroke
#: terms are then determined on a part of the stroke only, and extrapolate on the rest.
COVERAGE_WARNING = 0.5


@dataclass(frozen=True)
class StrokeCoverage:
    """Per leg: the stroke ``low``/``high`` and the planned readings' ``lowest``/``highest``
    (readings), the share of the stroke between them (``covered``, 0 to 1) and the share of
    readings outside the stroke (``outside``)."""

    low: NDArray[np.float64]
    high: NDArray[np.float64]
    lowest: NDArray[np.float64]
    highest: NDArray[np.float64]
    covered: NDArray[np.float64]
    outside: NDArray[np.float64]

    def findings(self) -> list[str]:
        """One line per leg whose stroke is poorly covered or exceeded."""
        out = []
        for leg in range(len(self.low)):
            reached = f"[{self.lowest[leg]:.4g}, {self.highest[leg]:.4g}]"
            span = f"{reached} of [{self.low[leg]:.4g}, {self.high[leg]:.4g}]"
            if self.covered[leg] < COVERAGE_WARNING:
                out.append(
                    f"leg {leg + 1}: the poses' readings {span} cover {self.covered[leg]:.0%} of its stroke; "
                    "its stroke terms are determined there only and extrapolate elsewhere: add poses "
                    "that extend this leg further"
                )
            if self.outside[leg] > 0:
                out.append(
                    f"leg {leg + 1}: {self.outside[leg]:.0%} of the poses read outside its stroke "
                    f"({span}): the model holds its curve there"
                )
        return out

    def to_dict(self) -> dict[str, Any]:
        """Plain-Python form (``stroke_coverage`` of ``observability --json``)."""
        return {
            "low": self.low.tolist(),
            "high": self.high.tolist(),
            "readings_min": self.lowest.tolist(),
            "readings_max": self.highest.tolist(),
            "covered": self.covered.tolist(),
            "outside": self.outside.tolist(),
            "warning_below": COVERAGE_WARNING,
            "findings": self.findings(),
        }


def stroke_coverage(geometry: Geometry, poses: ArrayLike) -> StrokeCoverage | None:
    """The coverage of each leg's stroke by the readings of ``poses`` (m, 6) on ``geometry``
    (its own inverse kinematics); ``None`` when its leg model has no stroke."""
    ranges = geometry.leg_model.stroke_range()
    if ranges is None:
        return None
    low, high = ranges
    poses = as_poses(poses).reshape(-1, 6)
    readings = leg_readings(geometry, inverse_kinematics(geometry, poses))
    lowest, highest = readings.min(axis=0), readings.max(axis=0)
    inside_span = np.clip(highest, low, high) - np.clip(lowest, low, high)
    covered = np.clip(inside_span / (high - low), 0.0, 1.0)
    outside = np.mean((readings < low) | (readings > high), axis=0)
    return StrokeCoverage(low, high, lowest, highest, covered, outside)
