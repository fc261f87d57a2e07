"""Diagnoses: the likely cause of a bad identification, found by refitting variants.

Each diagnosis refits a variant of the data or the model with the fast estimator of the
instruments (least squares on the leg lengths where every instrument gives the pose, else
maximum likelihood under the given noise, with unknown frames registered again) and compares
the residual RMS with the fit as given. A noise learned from the data is no yardstick here: it
has absorbed the very error a diagnosis looks for (positions in metres make a large position
σ, wrong gains a large leg σ), so under a learned noise the refits weigh the groups with the
default noise model:

- **unfitted gains** (always, when the gains are fixed): the fit with the gains; a
  significant F test and a large drop of the sum of squares -> ``fit the gains:
  --fit joints,l0,gains``;
- **units** (bad fits): each session's data re-read as its instrument suggests (lengths in
  metres or inches, angles in the other unit: :meth:`MeasurementModel.variants`); named
  instead of the gains when it explains the fit better;
- **absolute readings** (bad fits and failed ones): readings of the size of the legs
  themselves re-read as ``(dl - l0) / g``: a controller's joint positions (LinuxCNC's
  genhexkins joints are strut lengths) given instead of readings from the home switch;
- **Euler sequence** (bad fits that neither explains, instruments that report angles): every
  other scipy Euler sequence, each by a short refit (:data:`SCREEN_NFEV` evaluations), the
  best few in full; says which one fits.

A variant is named the likely cause when its residual RMS is below :data:`BETTER` times the
original one. When the fit failed outright (:func:`explain_failure`), a variant that fits is
named when it is below :data:`BETTER` times every other variant of its kind. Imports
:mod:`hexcal.core`, :mod:`hexcal.instruments`, :mod:`hexcal.estimation` and
:mod:`hexcal.calibration.verdict`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hexcal.calibration.reasons import Reason
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


#: ``refit(start, sessions, names, max_nfev=None) -> Quality``: a variant fitted with the fast
#: estimator (at most ``max_nfev`` evaluations when given).
Refit = Callable[..., Quality]

#: Evaluations of the screening refit of every other Euler sequence; the best
#: :data:`SCREEN_KEEP` of them are then refitted in full.
SCREEN_NFEV = 8
SCREEN_KEEP = 2


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
    start, names = result.start, tuple(result.names)
    swapped = swapped_points(result)
    if swapped is not None:  # the fit is fine, the labels are not: nothing to refit
        return [swapped]
    base = refit(start, sessions, names)
    if not np.isfinite(base.rms):
        return []
    out = _gains(start, names, sessions, refit, base)
    if not bad:
        return out
    unit = _absolute_readings(start, names, sessions, refit, base) or _units(
        start, names, sessions, refit, base
    )
    if unit is not None:
        # a unit that explains the fit better than the gains do is the cause (gains and l0
        # absorb part of positions in metres)
        gains = [r.data.get("rms_with_gains", np.inf) for r in out]
        return [r for r, g in zip(out, gains, strict=True) if g < unit.data["rms_converted"]] + [unit]
    if any(r.severity == "fail" for r in out):
        return out  # the gains explain the fit (its residual more than halves): no Euler search
    cause = _best(
        _swapped_columns(start, names, sessions, refit, base), _euler(start, names, sessions, refit, base)
    )
    return out + ([cause] if cause is not None else [])


def explain_failure(
    start: Geometry, names: tuple[str, ...], sessions: Sequence[Any], refit: Refit
) -> Reason | None:
    """The likely cause of a fit that failed outright (a solver that did not converge, a
    geometry beyond validity, a degenerate solution): a re-reading of the data (units, Euler
    sequence) that fits where the data as given do not, or clearly better than every other
    re-reading of its kind; None when no variant explains it."""
    base = refit(start, sessions, names)
    return (
        _absolute_readings(start, names, sessions, refit, base)
        or _units(start, names, sessions, refit, base)
        or _best(
            _swapped_columns(start, names, sessions, refit, base), _euler(start, names, sessions, refit, base)
        )
    )


def _best(*causes: Reason | None) -> Reason | None:
    """The cause whose re-reading fits best (a wrong Euler sequence also fits better with two
    columns exchanged, and the other way round)."""
    found = [c for c in causes if c is not None]
    return min(found, key=lambda c: c.data["rms_converted"], default=None)


#: Two points (legs' joints, targets) look swapped when each fitted point lies this many times
#: closer to the other's start than to its own, and moved by more than :data:`SWAP_MOVE` mm.
SWAP_RATIO = 10.0
SWAP_MOVE = 1.0


#: The codes of the diagnoses: a likely cause of the fit's other findings.
CAUSES = (
    "unfitted-gains",
    "absolute-readings",
    "swapped-columns",
    "euler-sequence",
    "length-units",
    "angle-units",
)


def likely_cause_first(reasons: Sequence[Reason]) -> list[Reason]:
    """``reasons`` with the diagnoses' findings (:data:`CAUSES`) first, the others in their
    order: when the data hold a mistake (radians in degree columns), the "not determined" and
    "changed beyond 25 %" findings are its consequences, and the cause must be read first.

    >>> found = [Reason("not-determined", "fail", "a"), Reason("angle-units-degrees", "fail", "b")]
    >>> [r.code for r in likely_cause_first(found)]
    ['angle-units-degrees', 'not-determined']
    """
    cause = [r for r in reasons if r.code.startswith(CAUSES)]
    return cause + [r for r in reasons if not r.code.startswith(CAUSES)]


def _points(result: Any) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``{point: (fitted xyz, start xyz)}`` of every varied point of the fit (``u1``, ``s3``,
    ``t2``, ``session2.t1``...: parameters ``NAME.x``, ``NAME.y``, ``NAME.z``)."""
    fitted = dict(zip(result.names, np.asarray(result.values, dtype=float), strict=True))
    start = dict(zip(result.names, np.asarray(result.start_values, dtype=float), strict=True))
    out = {}
    for name in result.names:
        if name.endswith(".x"):
            point = name[:-2]
            axes = [f"{point}.{a}" for a in "xyz"]
            if all(a in fitted for a in axes):
                out[point] = (np.array([fitted[a] for a in axes]), np.array([start[a] for a in axes]))
    return out


def swapped_points(result: Any) -> Reason | None:
    """Two legs' columns (``dl1``/``dl2``), or two targets' (``t1``/``t2``), swapped in the data:
    the fit then fits, with the two legs' joints (or the two targets) exchanged, each fitted
    close to the other's start (a "change beyond 25 %" of a few hundred mm in pairs). Found
    from the fit alone; None when no pair looks exchanged."""
    points = _points(result)
    pairs = []
    legs = sorted({int(p[1:]) for p in points if p[:1] in "us" and p[1:].isdigit()})
    for i in legs:
        for j in legs:
            if i < j and all(f"{k}{n}" in points for k in "us" for n in (i, j)):
                pairs.append(((f"u{i}", f"s{i}"), (f"u{j}", f"s{j}"), f"dl{i}", f"dl{j}", "leg"))
    others = [p for p in points if not (p[:1] in "us" and p[1:].isdigit())]
    for a in others:
        for b in others:
            if a < b and a.rpartition(".")[0] == b.rpartition(".")[0]:  # one session's targets
                pairs.append(((a,), (b,), a.rpartition(".")[2], b.rpartition(".")[2], "target"))
    for first, second, name_a, name_b, kind in pairs:
        same = sum(np.linalg.norm(points[p][0] - points[p][1]) for p in (*first, *second))
        crossed = sum(
            np.linalg.norm(points[p][0] - points[q][1]) + np.linalg.norm(points[q][0] - points[p][1])
            for p, q in zip(first, second, strict=True)
        )
        if same > SWAP_MOVE * 2 * len(first) and crossed * SWAP_RATIO < same:
            columns = "leg columns" if kind == "leg" else "target columns"
            return Reason(
                "swapped-columns",
                "fail",
                f"the {columns} {name_a} and {name_b} look swapped in the data: the fit moved each "
                f"{'leg' if kind == 'leg' else 'target'} by {same / (2 * len(first)):.4g} mm on average to "
                f"within {crossed / (2 * len(first)):.3g} mm of where the other should be; swap them back "
                "(or rename them with --columns)",
                {"columns": [name_a, name_b], "moved_mm": same, "crossed_mm": crossed},
            )
    return None


def _swapped_columns(
    start: Geometry, names: tuple[str, ...], sessions: Sequence[Any], refit: Refit, base: Quality
) -> Reason | None:
    """Two position columns (``x``/``y``...) swapped in a pose file: each exchange is screened by a
    short refit, the best refitted in full, named when it explains the fit (:func:`_explains`).
    Angle columns are left to the Euler search: with small angles, exchanging ``a`` and ``c``
    fits about as well as reading them in the reversed sequence."""
    import dataclasses

    for k, session in enumerate(sessions):
        poses = getattr(session.data, "poses", None)
        if poses is None or not dataclasses.is_dataclass(session.data):
            continue
        tried = []
        for group in (("x", "y", "z"),):
            offset = 0
            for i in range(3):
                for j in range(i + 1, 3):
                    swapped = np.array(poses, dtype=float)
                    swapped[:, [offset + i, offset + j]] = swapped[:, [offset + j, offset + i]]
                    variant = list(sessions)
                    variant[k] = session.replace(data=dataclasses.replace(session.data, poses=swapped))
                    quick = refit(start, variant, names, max_nfev=SCREEN_NFEV)
                    tried.append((quick.rms, group[i], group[j], variant))
        tried.sort(key=lambda t: t[0])
        fits = [(refit(start, t[3], names), t[1], t[2]) for t in tried[:SCREEN_KEEP]]
        fits.sort(key=lambda f: f[0].rms)
        quality, a, b = fits[0]
        if _explains(quality.rms, base, [f[0].rms for f in fits[1:]]):
            where = f"{session.label}: " if session.label else ""
            before = base.text() if np.isfinite(base.rms) else "a failed fit"
            return Reason(
                "swapped-columns",
                "fail",
                f"{where}the pose columns {a} and {b} look swapped: with them exchanged the residual RMS "
                f"falls from {before} to {quality.text()}",
                {"columns": [a, b], "rms": base.rms, "rms_converted": quality.rms},
            )
    return None


def _explains(rms: float, base: Quality, others: Sequence[float]) -> bool:
    """A variant explains the fit: its RMS below :data:`BETTER` times the fit as given, or,
    when that failed, finite and below :data:`BETTER` times every other variant of its kind."""
    if np.isfinite(base.rms):
        return bool(rms < BETTER * base.rms)
    return bool(np.isfinite(rms) and all(rms < BETTER * o for o in others))


def _gains(
    start: Geometry, names: tuple[str, ...], sessions: Sequence[Any], refit: Refit, base: Quality
) -> list[Reason]:
    from scipy.special import fdtr

    gains = start.leg_model.groups()["gains"]
    if set(gains) & set(names):
        return []
    fitted = refit(start, sessions, names + tuple(gains))
    if not (np.isfinite(fitted.rms) and fitted.dof > 0):
        return []
    f = ((base.sse - fitted.sse) / len(gains)) / max(fitted.sse / fitted.dof, 1e-300)
    p = 1 - fdtr(len(gains), fitted.dof, max(f, 0.0))
    if not (p < 1e-3 and fitted.rms < np.sqrt(BETTER) * base.rms):
        return []
    # the residual halves with six more parameters: the model is wrong (fail); a smaller,
    # still significant drop is a warning
    return [
        Reason(
            "unfitted-gains",
            "fail" if fitted.rms < BETTER * base.rms else "warn",
            f"fitting the gains lowers the residual RMS from {base.text()} to {fitted.text()} "
            f"(F test p {p:.1e}): fit the gains: --fit joints,l0,gains",
            {"rms": base.rms, "rms_with_gains": fitted.rms},
        )
    ]


def _units(
    start: Geometry, names: tuple[str, ...], sessions: Sequence[Any], refit: Refit, base: Quality
) -> Reason | None:
    for k, session in enumerate(sessions):
        fits = []
        for code, text, data in [*session.instrument.variants(session.data), *_with_legs(session)]:
            variant = list(sessions)
            variant[k] = session.replace(data=data)
            fits.append((refit(start, variant, names), code, text))
            if np.isfinite(base.rms) and _explains(fits[-1][0].rms, base, ()):
                break  # the first variant that explains the fit is enough
        for quality, code, text in fits:
            others = [q.rms for q, c, _ in fits if c != code]
            if _explains(quality.rms, base, others):
                where = f"{session.label}: " if session.label else ""
                before = base.text() if np.isfinite(base.rms) else "a failed fit"
                return Reason(
                    code,
                    "fail",
                    f"{where}{text}: with them converted the residual RMS falls from {before} "
                    f"to {quality.text()}",
                    {"rms": base.rms, "rms_converted": quality.rms},
                )
    return None


def _with_legs(session: Any) -> list[tuple[str, str, Any]]:
    """The instrument's length re-readings (metres, inches) with the leg readings re-read in
    the same unit: a file written all in metres, legs included."""
    import dataclasses

    readings = getattr(session.data, "readings", None)
    if readings is None or not dataclasses.is_dataclass(session.data):
        return []
    out = []
    for code, _, data in session.instrument.variants(session.data):
        unit = code.removeprefix("length-units-")
        if unit == code:
            continue
        factor = {"metres": 1000.0, "inches": 25.4}.get(unit)
        if factor is None:
            continue
        both = dataclasses.replace(data, readings=np.asarray(readings, dtype=float) * factor)
        out.append((f"{code}-legs", f"everything looks like {unit}, the leg readings included", both))
    return out


def absolute_readings(start: Geometry, sessions: Sequence[Any]) -> str | None:
    """The message for readings no leg can have, found before any fit: a reading that makes its
    leg 0 mm or shorter (naming the pose), or readings that are plainly absolute strut lengths:
    every reading lies within the machine's leg lengths (its limits, else the lengths over its
    workspace box or at its home pose, widened by 20 %), while every length the readings would
    give (``l0 + g dl``) lies beyond them; None otherwise."""
    from hexcal.core.kinematics import inverse_kinematics, leg_lengths
    from hexcal.core.workspace import workspace_corners

    if start.leg_length_limits is not None:
        low, high = (float(v) for v in start.leg_length_limits)
    elif start.workspace is not None or start.home_pose is not None:
        poses = workspace_corners(start) if start.workspace is not None else start.home_pose[None]
        lengths = inverse_kinematics(start, poses)
        low, high = 0.8 * float(lengths.min()), 1.2 * float(lengths.max())
    else:
        return None
    for session in sessions:
        readings = getattr(session.data, "readings", None)
        if readings is None or not np.size(readings):
            continue
        given = leg_lengths(start, readings)
        where = f"{session.label}: " if session.label else ""
        short = np.flatnonzero(np.any(given <= 0, axis=1))
        if short.size:
            ids = session.instrument.ids(session.data)
            row, leg = int(short[0]), int(np.argmin(given[short[0]]))
            more = f" (and {short.size - 1} more)" if short.size > 1 else ""
            return (
                f"{where}pose {ids[row]}{more}: dl{leg + 1} = {readings[row, leg]:.6g} makes leg {leg + 1} "
                f"{given[row, leg]:.6g} mm long (l0 + g dl), no real leg; a sign or unit slip in that column?"
            )
        if np.all((readings >= low) & (readings <= high)) and np.all(given > high):
            return (
                f"{where}the leg readings dl ({np.min(readings):.4g} to {np.max(readings):.4g}) look like "
                f"absolute strut lengths (a controller's joint positions): the legs are {low:.4g} to "
                f"{high:.4g} mm long, and l0 + g dl would make them {np.min(given):.4g} to "
                f"{np.max(given):.4g} mm; give readings from the switch, dl = joint position - HOME_OFFSET"
            )
    return None


def _absolute_readings(
    start: Geometry, names: tuple[str, ...], sessions: Sequence[Any], refit: Refit, base: Quality
) -> Reason | None:
    """Readings that are strut lengths (joint positions) rather than readings from the switch:
    tried where their medians are of the size of ``l0 / g`` (between half and three times)."""
    import dataclasses

    l0, gains = start.initial_leg_lengths, start.leg_gains
    for k, session in enumerate(sessions):
        readings = getattr(session.data, "readings", None)
        if readings is None or not dataclasses.is_dataclass(session.data):
            continue
        typical = np.abs(l0 / gains)
        median = np.nanmedian(np.abs(readings), axis=0)
        if not np.all((median > 0.5 * typical) & (median < 3.0 * typical)):
            continue
        variant = list(sessions)
        variant[k] = session.replace(data=dataclasses.replace(session.data, readings=(readings - l0) / gains))
        quality = refit(start, variant, names)
        if not _explains(quality.rms, base, ()):
            continue
        where = f"{session.label}: " if session.label else ""
        before = base.text() if np.isfinite(base.rms) else "a failed fit"
        return Reason(
            "absolute-readings",
            "fail",
            f"{where}the leg readings dl look like absolute strut lengths (a controller's joint positions), "
            "not readings from the home switch: read as dl - l0 the residual RMS falls from "
            f"{before} to {quality.text()}; give readings from the switch, dl = joint position - HOME_OFFSET",
            {"rms": base.rms, "rms_converted": quality.rms},
        )
    return None


def _euler(
    start: Geometry, names: tuple[str, ...], sessions: Sequence[Any], refit: Refit, base: Quality
) -> Reason | None:
    if not any(s.instrument.has_angles for s in sessions):
        return None
    # a short refit of every sequence ranks them; the best few are refitted in full
    screened = sorted(
        (refit(start.replace(euler=seq), sessions, names, max_nfev=SCREEN_NFEV).rms, seq)
        for seq in EULER_SEQUENCES
        if seq != start.euler
    )
    fits = sorted(
        (refit(start.replace(euler=seq), sessions, names).rms, seq) for _, seq in screened[:SCREEN_KEEP]
    )
    best_rms, best = fits[0]
    if not _explains(best_rms, base, [rms for rms, _ in fits[1:]]):
        return None
    before = f"{base.rms:.4g} {base.unit}" if np.isfinite(base.rms) else "a failed fit"
    return Reason(
        "euler-sequence",
        "fail",
        f"the Euler sequence looks wrong: with {best!r} instead of {start.euler!r} the "
        f"residual RMS falls from {before} to {best_rms:.4g} {base.unit}",
        {"euler": best, "rms": base.rms, "rms_converted": best_rms},
    )
