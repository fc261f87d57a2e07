"""An unmodelled stroke error: the verdict's reason when linear legs leave curved residuals.

A leg whose length is not a straight line of its reading (a screw's pitch error, a belt that
stretches) leaves, after a fit with the linear model ``l0 + g dl``, residuals that follow a
smooth curve of the reading. :func:`stroke_findings` tests each leg's residuals at the fit
against Legendre polynomials of its reading above the gain
(:func:`hexcal.estimation.residual_structure.leg_structure`, an F test) and names the legs
where the curve is significant at the family-wise level :data:`ALPHA` (Bonferroni over the
six legs) and explains at least :data:`EXPLAINED` of their residuals: then ``warn``, with the
suggestion to fit the stroke model (``--leg-model stroke`` or ``auto``).

The findings are plain tuples ``(code, severity, message, data)`` that
:func:`hexcal.calibration.verdict.assess` turns into its reasons (this module does not import
the verdict, which imports it).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hexcal.estimation.residual_structure import leg_structure

#: Family-wise level of the per-leg F tests (a warn needs strong evidence).
ALPHA = 1e-3

#: Smallest share of a leg's residual sum of squares the curve must explain to be named.
EXPLAINED = 0.1

#: Code of the reason.
CODE = "stroke-structure"


def stroke_findings(result: Any, problem: Any) -> list[tuple[str, str, str, dict[str, Any]]]:
    """The ``warn`` finding of legs whose residuals follow their readings (module docstring),
    or none: the fitted legs are not linear, or the residuals are not at hand."""
    if problem is None or result.leg_residuals_after is None or result.geometry.leg_model.name != "linear":
        return []
    residuals = np.asarray(result.leg_residuals_after, dtype=float)
    readings = np.asarray(problem.readings, dtype=float)
    if residuals.shape != readings.shape:
        return []
    found = leg_structure(residuals, readings, fitted_degree=1)
    legs = [int(i) for i in found.legs(ALPHA) if found.explained[i] >= EXPLAINED]
    if not legs:
        return []
    listed = ", ".join(
        f"{i + 1} ({found.explained[i]:.0%}, curve RMS {found.curve_rms[i]:.3g} mm)" for i in legs
    )
    message = (
        f"leg residuals follow the readings beyond the gain on leg(s) {listed}: an unmodelled stroke "
        f"error is likely (F test p < {ALPHA:g}); fit the stroke model: --leg-model stroke (or auto)"
    )
    data = {
        "legs": [i + 1 for i in legs],
        "explained": [float(found.explained[i]) for i in legs],
        "p_values": [float(found.p_values[i]) for i in legs],
        "curve_rms_mm": [float(found.curve_rms[i]) for i in legs],
        "degree": found.degree,
    }
    return [(CODE, "warn", message, data)]
