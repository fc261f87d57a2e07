"""Diagnoses: the likely cause of a bad identification, found by refitting variants.

Each diagnosis refits a variant of the data or the model with the fast estimator of the
instruments (least squares on the leg lengths where every instrument gives the pose, else
maximum likelihood under the fit's noise, with unknown frames registered again) and compares
the residual RMS with the fit as given:

- **unfitted gains** (always, when the gains are fixed): the fit with the gains; a
  significant F test and a large drop of the sum of squares -> ``fit the gains:
  --fit joints,l0,gains``;
- **units** (bad fits): each session's data re-read as its instrument suggests (lengths in
  metres or inches, angles in the other unit: :meth:`MeasurementModel.variants`);
- **Euler sequence** (bad fits, instruments that report angles): every other scipy Euler
  sequence; says which one fits.

A variant is named the likely cause when its residual RMS is below :data:`BETTER` times the
original one. Imports :mod:`hexcal.core`, :mod:`hexcal.instruments`, :mod:`hexcal.estimation`
and :mod:`hexcal.calibration.verdict`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hexcal.calibration.verdict import Reason
from hexcal.core.geometry import Geometry

#: A variant explains a bad fit when its residual RMS is below this fraction of the original.
BETTER = 0.5

#: The sequences tried for a wrong Euler convention.
EULER_SEQUENCES = tuple(a + b + c for a in "XYZ" for b in "XYZ" for c in "XYZ" if a != b and b != c) + tuple(
    a + b + c for a in "xyz" for b in "xyz" for c in "xyz" if a != b and b != c
)


@dataclass(frozen=True)
class Quality:
    """How well a variant fits: the residual RMS (``unit``), the sum of squares and the degrees
    of freedom (``inf`` RMS when the fit failed)."""

    rms: float
    sse: float
    dof: int
    unit: str = "mm"

    def text(self) -> str:
        return f"{self.rms:.4g} {self.unit}".strip()


#: ``refit(start, sessions, names) -> Quality``: a variant fitted with the fast estimator.
Refit = Callable[[Geometry, Sequence[Any], tuple[str, ...]], Quality]


def diagnose(result: Any, sessions: Sequence[Any], refit: Refit, bad: bool = True) -> list[Reason]:
    """Reasons naming the likely cause of a bad fit (see the module docstring).

    Parameters
    ----------
    result : IdentificationResult
        The fit (its start geometry and varied parameters are refitted).
    sessions : sequence of Session
        The sessions as given (before any registration).
    refit : callable
        Fits a variant (:data:`Refit`).
    bad : bool
        The fit is suspect: also try units and Euler sequences.
    """
    from scipy.special import fdtr

    start, names = result.start, tuple(result.names)
    base = refit(start, sessions, names)
    if not np.isfinite(base.rms):
        return []
    out: list[Reason] = []
    gains = start.leg_model.groups()["gains"]
    if not set(gains) & set(names):
        with_gains = names + tuple(gains)
        fitted = refit(start, sessions, with_gains)
        if np.isfinite(fitted.rms) and fitted.dof > 0:
            f = ((base.sse - fitted.sse) / len(gains)) / max(fitted.sse / fitted.dof, 1e-300)
            p = 1 - fdtr(len(gains), fitted.dof, max(f, 0.0))
            if p < 1e-3 and fitted.rms < np.sqrt(BETTER) * base.rms:
                # the residual halves with six more parameters: the model is wrong (fail); a
                # smaller, still significant drop is a warning
                out.append(
                    Reason(
                        "unfitted-gains",
                        "fail" if fitted.rms < BETTER * base.rms else "warn",
                        f"fitting the gains lowers the residual RMS from {base.text()} to {fitted.text()} "
                        f"(F test p {p:.1e}): fit the gains: --fit joints,l0,gains",
                        {"rms": base.rms, "rms_with_gains": fitted.rms},
                    )
                )
    if not bad:
        return out
    for k, session in enumerate(sessions):
        for code, text, data in session.instrument.variants(session.data):
            variant = list(sessions)
            variant[k] = session.replace(data=data)
            quality = refit(start, variant, names)
            if quality.rms < BETTER * base.rms:
                where = f"{session.label}: " if len(sessions) > 1 and session.label else ""
                out.append(
                    Reason(
                        code,
                        "fail",
                        f"{where}{text}: with them converted the residual RMS falls from {base.text()} "
                        f"to {quality.text()}",
                        {"rms": base.rms, "rms_converted": quality.rms},
                    )
                )
                return out
    if not any(s.instrument.has_angles for s in sessions):
        return out
    fits = [
        (refit(start.replace(euler=seq), sessions, names).rms, seq)
        for seq in EULER_SEQUENCES
        if seq != start.euler
    ]
    best_rms, best = min(fits)
    if best_rms < BETTER * base.rms:
        out.append(
            Reason(
                "euler-sequence",
                "fail",
                f"the Euler sequence looks wrong: with {best!r} instead of {start.euler!r} the "
                f"residual RMS falls from {base.text()} to {best_rms:.4g} {base.unit}",
                {"euler": best, "rms": base.rms, "rms_converted": best_rms},
            )
        )
    return out
