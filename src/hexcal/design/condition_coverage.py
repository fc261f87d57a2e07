"""How much the conditions of a pose set vary, for a leg model that reads them.

A thermal leg term ``kt_i (T_i - T_ref)`` is told apart from the leg's ``l0_i`` only by poses
at different temperatures of that leg: at one temperature it is a constant like ``l0_i``, and
the pair is not determined. A compliance term ``kc_i F_i`` needs the leg's axial force to vary
(payloads, or poses that load the leg differently). :func:`condition_coverage` gives, per leg,
the span of the temperatures (K) and of the axial forces (N) at the planned poses, and whether
the terms' columns of the identification Jacobian are determined, as the analysis of the pose
set found them (the rank and identifiability of every parameter).

>>> from hexcal.core import preset, workspace_corners
>>> from hexcal.core.covariate_legs import CovariateLegs
>>> from hexcal.core.stroke_legs import with_leg_model
>>> from hexcal.instruments import Covariates
>>> warm = with_leg_model(preset("paper-hmt"), CovariateLegs(thermal=True))
>>> poses = workspace_corners(warm)[:6]
>>> cover = condition_coverage(warm, poses, Covariates(temperatures=[18.0, 22, 26, 18, 22, 26]))
>>> cover.temperature_span.tolist()
[8.0, 8.0, 8.0, 8.0, 8.0, 8.0]
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core import Geometry

#: The terms of a covariate leg model whose determination is reported, and their quantity.
TERMS = {"thermal": "temperature", "compliance": "axial force"}


@dataclass(frozen=True)
class ConditionCoverage:
    """Per leg: the span of the planned poses' temperatures (K, or None without a thermal term)
    and axial forces (N, or None without a compliance term), and per term (``thermal``,
    ``compliance``) whether every leg's coefficient is determined (``determined``) and the legs
    whose coefficient is not (``undetermined``, 1-based)."""

    temperature_span: NDArray[np.float64] | None
    force_span: NDArray[np.float64] | None
    determined: dict[str, bool]
    undetermined: dict[str, list[int]]

    def findings(self) -> list[str]:
        """One line per term whose coefficients the pose set does not determine."""
        out = []
        for term, legs in self.undetermined.items():
            if not legs:
                continue
            span = self.temperature_span if term == "thermal" else self.force_span
            unit = "K" if term == "thermal" else "N"
            spans = ", ".join(f"{s:.3g} {unit}" for s in np.asarray(span)[np.asarray(legs) - 1])
            out.append(
                f"the {term} terms of leg(s) {', '.join(map(str, legs))} are not determined: their "
                f"{TERMS[term]} spans {spans} over the poses; plan poses at different "
                + ("temperatures" if term == "thermal" else "payloads or loads")
            )
        return out

    def to_dict(self) -> dict[str, Any]:
        """Plain-Python form (``condition_coverage`` of ``observability`` and ``select --json``)."""
        return {
            "temperature_span_K": None if self.temperature_span is None else self.temperature_span.tolist(),
            "force_span_N": None if self.force_span is None else self.force_span.tolist(),
            "determined": dict(self.determined),
            "undetermined_legs": {k: list(v) for k, v in self.undetermined.items()},
            "findings": self.findings(),
        }


def condition_coverage(
    geometry: Geometry,
    poses: ArrayLike,
    covariates: Any,
    names: tuple[str, ...] | None = None,
    not_identifiable: ArrayLike | None = None,
) -> ConditionCoverage | None:
    """The conditions' spans at ``poses`` (m, 6) under ``covariates`` and, given the analysed
    parameters' ``names`` and ``not_identifiable`` flags, whether the covariate terms are
    determined; ``None`` for a leg model without covariates."""
    model = geometry.leg_model
    if not model.covariates:
        return None
    poses = np.asarray(poses, dtype=float).reshape(-1, 6)
    inputs = model.leg_inputs(covariates, poses, geometry, "the poses")
    spans = np.ptp(inputs, axis=0)  # (6, K), in the order of model.inputs
    groups = model.groups()
    column = {name: k for k, name in enumerate(model.inputs)}
    temperature = spans[:, column["dT"]] if "dT" in column else None
    force = spans[:, column["force"]] if "force" in column else None
    lost = (
        set()
        if names is None or not_identifiable is None
        else {n for n, bad in zip(names, np.asarray(not_identifiable), strict=True) if bad}
    )
    fitted = set(groups.get("thermal", ()) + groups.get("compliance", ())) if names is None else set(names)
    determined, undetermined = {}, {}
    for term in TERMS:
        if term not in groups or not fitted.intersection(groups[term]):
            continue  # a term held, not identified: nothing to determine
        legs = [k + 1 for k, name in enumerate(groups[term]) if name in lost]
        undetermined[term] = legs
        determined[term] = not legs
    return ConditionCoverage(temperature, force, determined, undetermined)
