"""Diagnoses: the likely cause of a bad identification, found by refitting variants.

Each diagnosis refits the leg-length least squares (``length``, fast and free of any noise
model) on a variant of the data or the model and compares the leg residual RMS with the
fit as given:

- **unfitted gains** (always, when the gains are fixed): the fit with the gains; a
  significant F test and a large drop of the sum of squares -> ``fit the gains:
  --fit joints,l0,gains``;
- **angle units** (bad fits): the angles converted from degrees to radians and the reverse;
- **Euler sequence** (bad fits): every other scipy Euler sequence; says which one fits.

A variant is named the likely cause when its leg residual RMS is below :data:`BETTER`
times the original one.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hexcal.core.parameters import PARAMETER_NAMES
from hexcal.errors import HexcalError
from hexcal.estimation.verdict import Reason

#: A variant explains a bad fit when its leg residual RMS is below this fraction of the original.
BETTER = 0.5

#: The sequences tried for a wrong Euler convention.
EULER_SEQUENCES = tuple(a + b + c for a in "XYZ" for b in "XYZ" for c in "XYZ" if a != b and b != c) + tuple(
    a + b + c for a in "xyz" for b in "xyz" for c in "xyz" if a != b and b != c
)


def length_fit_rms(start: Any, measurements: Any, mask: Any) -> tuple[float, int]:
    """Leg residual RMS (mm) of the ``length`` least-squares fit and its degrees of freedom
    (``inf`` when the fit fails)."""
    from hexcal.estimation.least_squares import fit_least_squares
    from hexcal.estimation.problem import Problem

    try:
        res = fit_least_squares(Problem(start, measurements, mask=mask), "length", max_nfev=60)
    except (HexcalError, ValueError, np.linalg.LinAlgError):
        return float("inf"), 0
    return res.rms_after, res.dof


def _with_angles(measurements: Any, factor: float) -> Any:
    poses = np.array(measurements.poses)
    poses[:, 3:] *= factor
    return type(measurements)(poses, measurements.readings, measurements.ids)


def diagnose(result: Any, measurements: Any, bad: bool = True) -> list[Reason]:
    """Reasons naming the likely cause of a bad fit (see the module docstring).

    Parameters
    ----------
    result : IdentificationResult
        The fit (its start geometry and varied parameters are refitted).
    measurements : Measurements
        The data fitted.
    bad : bool
        The fit is suspect: also try angle units and Euler sequences.
    """
    from scipy.special import fdtr

    mask = np.isin(PARAMETER_NAMES, result.names)
    if len(result.names) != int(mask.sum()):
        return []
    start = result.start
    rms0, dof0 = length_fit_rms(start, measurements, mask)
    if not np.isfinite(rms0):
        return []
    out: list[Reason] = []
    if not mask[42:].any():
        with_gains = mask | np.isin(PARAMETER_NAMES, PARAMETER_NAMES[42:])
        rms1, dof1 = length_fit_rms(start, measurements, with_gains)
        if np.isfinite(rms1) and dof1 > 0:
            sse0, sse1 = rms0**2 * (dof0 + mask.sum()), rms1**2 * (dof1 + with_gains.sum())
            f = ((sse0 - sse1) / 6) / max(sse1 / dof1, 1e-300)
            p = 1 - fdtr(6, dof1, max(f, 0.0))
            if p < 1e-3 and rms1 < np.sqrt(BETTER) * rms0:
                # the leg residual halves with six more parameters: the model is wrong (fail);
                # a smaller, still significant drop is a warning
                out.append(
                    Reason(
                        "unfitted-gains",
                        "fail" if rms1 < BETTER * rms0 else "warn",
                        f"fitting the gains lowers the leg residual RMS from {rms0:.4g} to {rms1:.4g} mm "
                        f"(F test p {p:.1e}): fit the gains: --fit joints,l0,gains",
                        {"rms": rms0, "rms_with_gains": rms1},
                    )
                )
    if not bad:
        return out
    angles = np.abs(np.asarray(measurements.poses)[:, 3:])
    trials = [("radians", np.pi / 180, "the angles look like degrees in radian columns")]
    if np.max(angles, initial=0.0) * 180 / np.pi <= np.pi:
        trials.append(("degrees", 180 / np.pi, "the angles look like radians in degree columns (a_deg)"))
    for code, factor, text in trials:
        rms1, _ = length_fit_rms(start, _with_angles(measurements, factor), mask)
        if rms1 < BETTER * rms0:
            out.append(
                Reason(
                    f"angle-units-{code}",
                    "fail",
                    f"{text}: with them converted the leg residual RMS falls from {rms0:.4g} "
                    f"to {rms1:.4g} mm",
                    {"rms": rms0, "rms_converted": rms1},
                )
            )
            return out
    fits = []
    for seq in EULER_SEQUENCES:
        if seq != start.euler:
            fits.append((length_fit_rms(start.replace(euler=seq), measurements, mask)[0], seq))
    best_rms, best = min(fits)
    if best_rms < BETTER * rms0:
        out.append(
            Reason(
                "euler-sequence",
                "fail",
                f"the Euler sequence looks wrong: with {best!r} instead of {start.euler!r} the leg "
                f"residual RMS falls from {rms0:.4g} to {best_rms:.4g} mm",
                {"euler": best, "rms": rms0, "rms_converted": best_rms},
            )
        )
    return out
