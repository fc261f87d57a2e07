"""The leg model of an identification: by name, or chosen by cross-validation.

``--leg-model`` names a model of :data:`hexcal.core.legs.LEG_MODELS`, with a degree for the
stroke model (``linear``, ``stroke``, ``stroke:2``); :func:`start_for` gives the nominal
geometry that model (its ``l0`` and gains kept, the new terms at 0; the stroke model's
stroke from the geometry's leg length limits, else from the readings of the sessions,
:func:`hexcal.core.stroke_legs.stroke_of`) and :func:`fit_for` adds the model's own group
to the fitted groups.

``auto`` chooses among :data:`CANDIDATES` by how well each predicts data it was not fitted to
(:func:`choose_leg_model`):

- several sessions: **leave one session out**: the machine fitted on the others predicts it;
- one session: **K-fold over its poses** (``folds``, dealt at random with ``seed``; fewer
  when a held-out fold would keep too few poses to re-register a free instrument).

Each held-out part is judged by :func:`hexcal.calibration.validate` (which re-registers an
instrument's free frame and tool on the held-out data by its own cross-validation, so that a
frame fitted with the machine does not carry the fit's errors over); the score is the held-out
leg RMS (mm), pooled over the parts. The choice is the candidate of the least score, a tie
going to the simpler one (the order of :data:`CANDIDATES`): a candidate ties with the best when
its mean squared held-out leg residual exceeds the best's by no more than one standard error of
their paired difference over the parts (the one-standard-error rule, paired). A more flexible
model is thus chosen only when it predicts better by more than the scatter of the folds; with
two sessions, only when it predicts each of them better.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hexcal.core.geometry import Geometry
from hexcal.core.legs import LEG_MODELS, LegModel, LinearLegs
from hexcal.core.stroke_legs import DEFAULT_DEGREE, StrokeLegs, stroke_of, with_leg_model
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
        ``leave-one-session-out`` or ``K-fold over poses``.
    scores : dict of str to dict
        Per candidate: held-out ``leg_rms_mm`` (the score), ``position_rms_mm``,
        ``orientation_rms_rad``, ``part_leg_rms_mm`` (each held-out part's) and ``parameters``
        (the machine parameters fitted).
    folds, seed : int
    """

    choice: str
    scheme: str
    scores: dict[str, dict[str, float]] = field(default_factory=dict)
    folds: int = DEFAULT_FOLDS
    seed: int = 0

    def to_dict(self) -> dict[str, Any]:
        """The JSON form (``leg_model_choice``)."""
        return {
            "choice": self.choice,
            "scheme": self.scheme,
            "folds": self.folds,
            "seed": self.seed,
            "rule": "least held-out leg MSE; ties (within one standard error of the paired difference "
            "over the parts) to the simpler candidate",
            "scores": self.scores,
        }

    def lines(self) -> list[str]:
        """The choice and the scores as text, one candidate a line."""
        out = [f"leg model chosen by cross-validation ({self.scheme}): {self.choice}"]
        for name, s in self.scores.items():
            mark = " <- chosen" if name == self.choice else ""
            out.append(
                f"  {name:<10} held-out leg RMS {s['leg_rms_mm']:.4g} mm, position RMS "
                f"{s['position_rms_mm']:.4g} mm, orientation RMS {s['orientation_rms_rad']:.3g} rad "
                f"({s['parameters']:d} machine parameters){mark}"
            )
        return out


def _splits(sessions: Sequence[Session], folds: int, seed: int) -> tuple[str, list[tuple[list, list]]]:
    """The scheme and its ``(training sessions, held-out sessions)`` pairs."""
    if len(sessions) > 1:
        pairs = [([s for j, s in enumerate(sessions) if j != k], [held]) for k, held in enumerate(sessions)]
        return "leave-one-session-out", pairs
    if folds < 2:
        raise UsageError(f"folds must be at least 2, got {folds}")
    session = sessions[0]
    folds = _pose_folds(session, folds)
    fold = np.random.default_rng(seed).permutation(len(session)) % folds
    pairs = [
        ([session.subset(np.flatnonzero(fold != f))], [session.subset(np.flatnonzero(fold == f))])
        for f in range(folds)
    ]
    return f"{folds}-fold over poses", pairs


def _pose_folds(session: Session, folds: int) -> int:
    """The most folds, up to ``folds``, whose held-out parts keep enough poses for
    :func:`~hexcal.calibration.validate` to re-register the instrument's free quantities in
    ``folds`` folds of their own (at least 2)."""
    free = int(np.sum(session.instrument.parameters().vary))
    if not free and not session.instrument.unregistered:
        return folds
    for k in range(folds, 1, -1):
        held = len(session) // k
        if held - -(-held // folds) >= max(free, 3):
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
        As :func:`hexcal.calibration.estimate` (the model's own group is added to ``fit``).
    folds, seed : int
        The folds over the poses of a single session and their seed; also the folds of the
        re-registration of a free instrument in each validation.

    Returns
    -------
    LegModelChoice
    """
    from hexcal.calibration.identify import estimate
    from hexcal.calibration.validation import validate

    sessions = list(sessions)
    if not sessions:
        raise UsageError("choose_leg_model: no session")
    scheme, pairs = _splits(sessions, folds, seed)
    scores: dict[str, dict[str, float]] = {}
    mses: dict[str, tuple[float, float]] = {}
    for spec in candidates:
        geometry = start_for(spec, start, sessions)
        groups = fit_for(fit, geometry.leg_model)
        legs, positions, angles, part_mse = [], [], [], []
        n_free = 0
        for train, held in pairs:
            result = estimate(
                geometry, train, method, noise=noise, fit=groups, fix=fix, with_bound=False, verdict=False
            )
            n_free = int(sum(n in set(geometry.machine_names()) for n in result.names))
            for session in held:
                v = validate(result.geometry, session, folds=folds, seed=seed)
                res = v.leg_residuals[np.isfinite(v.leg_residuals)]
                legs.append(res)
                part_mse.append(float(np.mean(res**2)))
                positions.append(v.position_error[np.isfinite(v.position_error)])
                angles.append(v.orientation_error[np.isfinite(v.orientation_error)])
        mse = float(np.mean(np.concatenate(legs) ** 2))
        mses[spec] = (mse, np.array(part_mse))
        scores[spec] = {
            "leg_rms_mm": float(np.sqrt(mse)),
            "position_rms_mm": _rms(positions),
            "orientation_rms_rad": _rms(angles),
            "part_leg_rms_mm": [float(np.sqrt(v)) for v in part_mse],
            "parameters": n_free,
        }
    return LegModelChoice(_least(mses), scheme, scores, folds, seed)


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
