"""The leg model of an identification: by name, or chosen by cross-validation.

``--leg-model`` names a model of :data:`hexcal.core.legs.LEG_MODELS`, with a degree for the
stroke model (``linear``, ``stroke``, ``stroke:2``); :func:`start_for` gives the nominal
geometry that model (its ``l0`` and gains kept, the new terms at 0; the stroke model's
stroke the range of the sessions' readings, the stroke they calibrate, or without sessions
the geometry's leg length limits, :func:`hexcal.core.stroke_legs.stroke_of`) and
:func:`fit_for` adds the model's own group to the fitted groups.

``auto`` chooses among :data:`CANDIDATES` by how well each predicts data it was not fitted to
(:func:`choose_leg_model`), on two kinds of held-out parts:

- **within**: several sessions: **leave one session out**, the machine fitted on the others
  predicts it; one session: **K-fold over its poses** (``folds``, dealt at random with
  ``seed``; fewer when a held-out fold would keep too few poses to re-register a free
  instrument);
- **the stroke's ends**: for each leg, the poses whose reading of it is among the lowest and
  the highest (together the share of a fold, over all the sessions) are held out, and the
  machine fitted on the others predicts them. Its stroke is then the other poses' (as
  ``identify`` would make it from them), so these parts are predicted beyond it, with the
  model's held curve: what a campaign that did not reach a leg's ends predicts there. Legs
  whose held-out poses are the same are one part; a session's held-out poses too few to
  re-register its instrument are left out of the training and not judged.

Every fit's stroke is that of its training poses (:func:`start_for`); a noise learned from the
data is learned once per candidate from all the sessions and held in its fits (it weighs the
kinds of residual against each other; learning it in each fold cost eight times the fit). Each
held-out part is judged by :func:`hexcal.calibration.validate` (which re-registers an
instrument's free frame and tool on the held-out data by its own cross-validation, so that a
frame fitted with the machine does not carry the fit's errors over); the score is the held-out
leg RMS (mm), pooled over all the parts. A candidate that predicts the stroke's ends worse than the simplest
candidate (linear legs: pooled held-out leg MSE of those parts above its) is not chosen: a
curve must not make the machine worse where the campaign did not measure. Among the others the
choice is the least score, a tie going to the simpler one (the order of :data:`CANDIDATES`): a
candidate ties with the best when its mean squared held-out leg residual exceeds the best's by
no more than one standard error of their paired difference over the parts (the
one-standard-error rule, paired). A more flexible model is thus chosen only when it predicts
better by more than the scatter of the parts.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from hexcal.core.geometry import Geometry
from hexcal.core.legs import LEG_MODELS, LegModel, LinearLegs
from hexcal.core.progress import task
from hexcal.core.stroke_legs import (
    DEFAULT_DEGREE,
    StrokeExcess,
    StrokeLegs,
    stroke_excess,
    stroke_of,
    with_leg_model,
)
from hexcal.errors import UsageError
from hexcal.instruments.base import Session

#: The candidates of ``auto``, simplest first.
CANDIDATES = ("linear", "stroke:2", "stroke:3", "stroke:4")

#: Folds of the cross-validation over the poses of one session.
DEFAULT_FOLDS = 5


def parse_leg_model(spec: str) -> tuple[str, int | None]:
    """``(name, degree)`` of a ``--leg-model`` value: ``auto``, a registered name, or
    ``stroke:DEGREE``; :class:`UsageError` naming the choices otherwise."""
    name, _, degree = str(spec).strip().partition(":")
    if name == "auto" and not degree:
        return name, None
    if name not in LEG_MODELS:
        raise UsageError(f"--leg-model {spec!r}: choose auto, {', '.join(LEG_MODELS)} (stroke:DEGREE)")
    if not degree:
        return name, DEFAULT_DEGREE if name == StrokeLegs.name else None
    if name != StrokeLegs.name or not degree.isdigit():
        raise UsageError(f"--leg-model {spec!r}: only the stroke model takes a degree, e.g. stroke:3")
    return name, int(degree)


def model_for(spec: str, geometry: Geometry, sessions: Sequence[Session] = ()) -> LegModel:
    """The leg model ``spec`` names for ``geometry`` and the readings of ``sessions``."""
    name, degree = parse_leg_model(spec)
    if name == "auto":
        raise UsageError("--leg-model auto: choose the model first (choose_leg_model)")
    if name == LinearLegs.name:
        return LinearLegs()
    if name == StrokeLegs.name:
        readings = [s.instrument.readings(s.data) for s in sessions]
        low, high = stroke_of(geometry, np.concatenate(readings) if readings else None)
        return StrokeLegs(int(degree or DEFAULT_DEGREE), low, high)
    return LEG_MODELS[name]()


def start_for(spec: str, geometry: Geometry, sessions: Sequence[Session] = ()) -> Geometry:
    """``geometry`` with the leg model ``spec`` (module docstring)."""
    return with_leg_model(geometry, model_for(spec, geometry, sessions))


def fit_for(fit: str | Sequence[str] | None, model: LegModel, default: str = "joints,l0") -> Any:
    """The fitted groups with the model's own group added (when it has terms)."""
    fit = default if fit is None else fit
    if not model.terms:
        return fit
    groups = [g.strip() for g in fit.split(",")] if isinstance(fit, str) else list(fit)
    if model.name in groups:
        return fit
    return ",".join([*groups, model.name]) if isinstance(fit, str) else [*groups, model.name]


@dataclass(frozen=True)
class LegModelChoice:
    """The cross-validated choice of a leg model.

    Attributes
    ----------
    choice : str
        The chosen candidate (``linear``, ``stroke:3``, ...).
    scheme : str
        ``leave-one-session-out`` or ``K-fold over poses``, and the stroke's ends when scored.
    scores : dict of str to dict
        Per candidate: held-out ``leg_rms_mm`` over all the parts (the score),
        ``within_leg_rms_mm`` and ``ends_leg_rms_mm`` (the two kinds of parts),
        ``position_rms_mm``, ``orientation_rms_rad``, ``part_leg_rms_mm`` (each held-out
        part's), ``parameters`` (the machine parameters fitted) and ``beyond_ends`` (whether
        it predicts the stroke's ends worse than the simplest candidate: not chosen then).
    folds, seed : int
    beyond_stroke : dict
        How much of the held-out predictions lies beyond their training stroke, per kind of
        part (``within``, ``ends``): ``rows``, ``beyond_rows``, ``beyond_share`` and
        ``largest_share_of_stroke`` (:class:`hexcal.core.stroke_legs.StrokeExcess`).
    """

    choice: str
    scheme: str
    scores: dict[str, dict[str, Any]] = field(default_factory=dict)
    folds: int = DEFAULT_FOLDS
    seed: int = 0
    beyond_stroke: dict[str, dict[str, Any]] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON form (``leg_model_choice``)."""
        return {
            "choice": self.choice,
            "scheme": self.scheme,
            "folds": self.folds,
            "seed": self.seed,
            "rule": "least held-out leg MSE over all the parts; ties (within one standard error of the "
            "paired difference over the parts) to the simpler candidate; not a candidate that predicts "
            "the stroke's ends worse than the simplest",
            "scores": self.scores,
            "beyond_stroke": self.beyond_stroke,
        }

    def lines(self) -> list[str]:
        """The choice and the scores as text, one candidate a line (:func:`choice_lines`)."""
        return choice_lines(self.to_dict())


def choice_lines(choice: dict[str, Any]) -> list[str]:
    """The lines of a leg-model choice's JSON form (:meth:`LegModelChoice.to_dict`): what the text
    report says of it, the same from a result and from a file."""
    out = [f"leg model chosen by cross-validation ({choice['scheme']}): {choice['choice']}"]
    for name, s in choice["scores"].items():
        mark = " <- chosen" if name == choice["choice"] else ""
        if s.get("beyond_ends"):
            mark += " (worse than the simplest at the stroke's ends: not chosen)"
        ends = s.get("ends_leg_rms_mm")
        split = ""
        if ends is not None:
            split = f" (within {s['within_leg_rms_mm']:.4g}, at the stroke's ends {ends:.4g})"
        out.append(
            f"  {name:<10} held-out leg RMS {s['leg_rms_mm']:.4g} mm{split}, position RMS "
            f"{_figure(s['position_rms_mm'], '.4g')} mm, orientation RMS "
            f"{_figure(s['orientation_rms_rad'], '.3g')} rad ({s['parameters']:d} machine parameters){mark}"
        )
    for kind, words in (("within", "the other parts"), ("ends", "the stroke's ends")):
        b = (choice.get("beyond_stroke") or {}).get(kind)
        if b and b["rows"]:
            out.append(
                f"  held-out poses beyond their training stroke, {words}: {b['beyond_share']:.0%} of "
                f"{b['rows']} (by up to {b['largest_share_of_stroke']:.0%} of it)"
            )
    return out


def _figure(value: Any, spec: str) -> str:
    """A figure of the JSON form (None where it was not finite)."""
    return "nan" if value is None else format(float(value), spec)


class Split(NamedTuple):
    """A fit and what it predicts: the training sessions (``parents``: the index of each in
    the sessions given), the held-out sessions and the kind of part (``within``, ``ends``)."""

    train: list[Session]
    held: list[Session]
    kind: str
    parents: tuple[int, ...]


def _splits(sessions: Sequence[Session], folds: int, seed: int) -> tuple[str, list[Split]]:
    """The within scheme and its splits."""
    if len(sessions) > 1:
        pairs = []
        for k, held in enumerate(sessions):
            others = [j for j in range(len(sessions)) if j != k]
            pairs.append(Split([sessions[j] for j in others], [held], "within", tuple(others)))
        return "leave-one-session-out", pairs
    if folds < 2:
        raise UsageError(f"folds must be at least 2, got {folds}")
    session = sessions[0]
    folds = _pose_folds(session, folds)
    fold = np.random.default_rng(seed).permutation(len(session)) % folds
    pairs = [
        Split(
            [session.subset(np.flatnonzero(fold != f))],
            [session.subset(np.flatnonzero(fold == f))],
            "within",
            (0,),
        )
        for f in range(folds)
    ]
    return f"{folds}-fold over poses", pairs


def _end_splits(sessions: Sequence[Session], folds: int) -> list[Split]:
    """Per leg, the poses at both ends of its stroke held out (module docstring): the lowest and
    highest readings of the leg over all the sessions, ``len // k`` poses in all (``k`` the
    folds of the within scheme over one session, :func:`_pose_folds`; ``folds`` over several)."""
    sizes = [len(s) for s in sessions]
    total = sum(sizes)
    k = _pose_folds(sessions[0], folds) if len(sessions) == 1 else folds
    count = total // max(k, 2)
    if count < 2:
        return []
    readings = np.concatenate([s.instrument.readings(s.data) for s in sessions])  # (total, 6)
    owner = np.repeat(np.arange(len(sessions)), sizes)
    local = np.concatenate([np.arange(n) for n in sizes])
    seen: set[bytes] = set()
    out: list[Split] = []
    for leg in range(readings.shape[1]):
        order = np.argsort(readings[:, leg], kind="stable")
        held = np.zeros(total, dtype=bool)
        held[order[: count // 2]] = True
        held[order[total - (count - count // 2) :]] = True
        key = held.tobytes()
        if key in seen:
            continue
        seen.add(key)
        train, judged, parents = [], [], []
        for j, session in enumerate(sessions):
            mine = owner == j
            keep, out_j = local[mine & ~held], local[mine & held]
            if len(keep):
                train.append(session.subset(keep))
                parents.append(j)
            if len(out_j) and _enough_to_register(session, len(out_j), folds):
                judged.append(session.subset(out_j))
        if train and judged:
            out.append(Split(train, judged, "ends", tuple(parents)))
    return out


def _enough_to_register(session: Session, poses: int, folds: int) -> bool:
    """Whether ``poses`` of the session suffice for :func:`~hexcal.calibration.validate` to
    re-register its instrument's free quantities in ``folds`` folds."""
    free = int(np.sum(session.instrument.parameters().vary))
    if not free and not session.instrument.unregistered:
        return poses > 0
    return poses - -(-poses // folds) >= max(free, 3)


def _pose_folds(session: Session, folds: int) -> int:
    """The most folds, up to ``folds``, whose held-out parts keep enough poses for
    :func:`~hexcal.calibration.validate` to re-register the instrument's free quantities in
    ``folds`` folds of their own (at least 2)."""
    for k in range(folds, 1, -1):
        if _enough_to_register(session, len(session) // k, folds):
            return k
    return 2


def choose_leg_model(
    start: Geometry,
    sessions: Sequence[Session],
    candidates: Iterable[str] = CANDIDATES,
    *,
    method: str = "ml",
    fit: str | Sequence[str] | None = None,
    fix: Iterable[str] = (),
    noise: Any = "auto",
    folds: int = DEFAULT_FOLDS,
    seed: int = 0,
    ends: bool = True,
) -> LegModelChoice:
    """Choose the leg model that best predicts held-out data (module docstring).

    Parameters
    ----------
    start : Geometry
        The nominal machine (any leg model: each candidate replaces it).
    sessions : sequence of Session
    candidates : iterable of str
        ``--leg-model`` values, simplest first (default :data:`CANDIDATES`).
    method, fit, fix, noise
        As :func:`hexcal.calibration.estimate` (the model's own group is added to ``fit``);
        a noise learned from the data (``"auto"``) is learned once per candidate from all the
        sessions and held in its folds.
    folds, seed : int
        The folds over the poses of a single session and their seed; also the folds of the
        re-registration of a free instrument in each validation.
    ends : bool
        Also hold out the ends of each leg's stroke (default); without, the within parts
        alone (the choice of hexcal before issue 32).

    Returns
    -------
    LegModelChoice
    """

    sessions = list(sessions)
    candidates = list(candidates)
    if not sessions:
        raise UsageError("choose_leg_model: no session")
    if not candidates:
        raise UsageError("choose_leg_model: no candidate")
    scheme, splits = _splits(sessions, folds, seed)
    if ends:
        end_splits = _end_splits(sessions, folds)
        if end_splits:
            splits += end_splits
            scheme += f" and the stroke's ends ({len(end_splits)} parts)"
    beyond = _beyond(start, splits)
    kinds = np.array([split.kind for split in splits for _ in split.held])
    scores: dict[str, dict[str, Any]] = {}
    parts: dict[str, np.ndarray] = {}
    candidates = list(candidates)
    with task("leg model: cross-validation fits", total=len(candidates) * len(splits)) as step:
        for spec in candidates:
            _score(
                spec,
                start,
                sessions,
                splits,
                kinds,
                scores,
                parts,
                method,
                fit,
                fix,
                noise,
                folds,
                seed,
                step,
            )
    return LegModelChoice(_decide(scores, parts), scheme, scores, folds, seed, beyond)


def _score(
    spec: str,
    start: Geometry,
    sessions: list[Session],
    splits: list[Split],
    kinds: np.ndarray,
    scores: dict[str, dict[str, Any]],
    parts: dict[str, np.ndarray],
    method: str,
    fit: Any,
    fix: Iterable[str],
    noise: Any,
    folds: int,
    seed: int,
    step: Any,
) -> None:
    """One candidate fitted on every part and judged on what each held out: its ``scores`` and
    its parts' mean squared leg residuals (``step()`` after each part)."""
    from hexcal.calibration.identify import estimate
    from hexcal.calibration.validation import validate

    legs, positions, angles, part_mse = [], [], [], []
    n_free = 0
    noises = _session_noises(spec, start, sessions, method, fit, fix, noise)
    for train, held, _, parents in splits:
        geometry = start_for(spec, start, train)  # the stroke of the training poses
        groups = fit_for(fit, geometry.leg_model)
        own = [noises[j] for j in parents]
        own = own[0] if len(own) == 1 or any(n is None for n in own) else own
        result = estimate(
            geometry, train, method, noise=own, fit=groups, fix=fix, with_bound=False, verdict=False
        )
        n_free = int(sum(n in set(geometry.machine_names()) for n in result.names))
        for session in held:
            v = validate(result.geometry, session, folds=folds, seed=seed)
            res = v.leg_residuals[np.isfinite(v.leg_residuals)]
            legs.append(res)
            part_mse.append(float(np.mean(res**2)))
            positions.append(v.position_error[np.isfinite(v.position_error)])
            angles.append(v.orientation_error[np.isfinite(v.orientation_error)])
        step()
    parts[spec] = np.array(part_mse)
    scores[spec] = {
        "leg_rms_mm": _rms(legs),
        "within_leg_rms_mm": _rms([r for r, k in zip(legs, kinds, strict=True) if k == "within"]),
        "position_rms_mm": _rms(positions),
        "orientation_rms_rad": _rms(angles),
        "part_leg_rms_mm": [float(np.sqrt(v)) for v in part_mse],
        "parameters": n_free,
    }
    if np.any(kinds == "ends"):
        scores[spec]["ends_leg_rms_mm"] = _rms([r for r, k in zip(legs, kinds, strict=True) if k == "ends"])


def _session_noises(
    spec: str,
    start: Geometry,
    sessions: list[Session],
    method: str,
    fit: Any,
    fix: Iterable[str],
    noise: Any,
) -> list[Any]:
    """Each session's noise model for the candidate's fits: given (one for all, or one per
    session), or, for ``auto``, learned once from all the sessions with the candidate (an
    estimate of the noise in every fold cost eight times the fit; the noise only weighs the
    kinds of residual against each other)."""
    from hexcal.calibration.identify import AUTO, estimate

    if isinstance(noise, str) and noise == AUTO:
        geometry = start_for(spec, start, sessions)
        groups = fit_for(fit, geometry.leg_model)
        whole = estimate(
            geometry, sessions, method, noise=AUTO, fit=groups, fix=fix, with_bound=False, verdict=False
        )
        return list(whole.noises) if len(whole.noises) == len(sessions) else [whole.noise] * len(sessions)
    if isinstance(noise, Sequence) and not isinstance(noise, str):
        if len(noise) != len(sessions):
            raise UsageError(f"choose_leg_model: {len(noise)} noise models for {len(sessions)} sessions")
        return list(noise)
    return [noise] * len(sessions)


def _beyond(start: Geometry, splits: list[Split]) -> dict[str, dict[str, Any]]:
    """Per kind of part, how much of the held-out readings lies beyond the stroke of the
    training poses (:func:`stroke_of`)."""
    out: dict[str, StrokeExcess] = {}
    for train, held, kind, _ in splits:
        readings = np.concatenate([s.instrument.readings(s.data) for s in train])
        low, high = stroke_of(start, readings)
        probe = with_leg_model(start, StrokeLegs(2, low, high))
        for session in held:
            excess = stroke_excess(probe, session.instrument.readings(session.data))
            out[kind] = out[kind].merge(excess) if kind in out else excess  # type: ignore[arg-type]
    return {
        kind: {
            k: v
            for k, v in e.to_dict().items()
            if k in ("rows", "beyond_rows", "beyond_share", "largest_share_of_stroke")
        }
        for kind, e in out.items()
    }


def _decide(scores: dict[str, dict[str, Any]], parts: dict[str, np.ndarray]) -> str:
    """The choice (module docstring): candidates (simplest first) that predict the stroke's
    ends worse than the simplest are marked ``beyond_ends`` and left out; among the others,
    :func:`_least` of the pooled held-out MSE and the per-part MSEs ``parts``."""
    simplest = next(iter(scores))
    for score in scores.values():
        ends = score.get("ends_leg_rms_mm")
        score["beyond_ends"] = bool(ends is not None and ends > scores[simplest]["ends_leg_rms_mm"])
    return _least(
        {spec: (s["leg_rms_mm"] ** 2, parts[spec]) for spec, s in scores.items() if not s["beyond_ends"]}
    )


def _least(mses: dict[str, tuple[float, np.ndarray]]) -> str:
    """The least pooled MSE, ties (within one standard error of the paired per-part
    differences) to the first, simplest candidate."""
    best = min(mses, key=lambda k: mses[k][0])
    for spec, (mse, parts) in mses.items():
        diff = parts - mses[best][1]
        stderr = float(np.std(diff, ddof=1) / np.sqrt(diff.size)) if diff.size > 1 else 0.0
        if mse - mses[best][0] <= stderr:
            return spec
    return best


def _rms(parts: list[np.ndarray]) -> float:
    values = np.concatenate(parts) if parts else np.zeros(0)
    return float(np.sqrt(np.mean(values**2))) if values.size else float("nan")
