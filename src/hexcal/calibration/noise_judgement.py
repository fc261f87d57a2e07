"""The learned noise held against what the instruments can do: is it noise, or model error?

With the noise learned from the data (``noise="auto"``), whatever the model does not describe
(a bumped instrument, legs that warm up, a leg curve that linear legs miss) is absorbed into a
larger noise, and the fit looks consistent. Each learned σ is therefore compared with what its
instrument can plausibly do (:mod:`hexcal.instruments.known_noise`): the σ a setup declares
(``noise:``), else the most that instruments of its kind show, and the legs with what leg
encoders show. A learned σ more than :data:`MODEL_ERROR_FACTOR` times that reference (and
beyond it by more than two of its standard errors) means the model does not describe the data:
``warn``, naming the session, the group and the factor; more than :data:`MODEL_ERROR_FAIL`
times the most such instruments show is ``fail``.

A group these data cannot determine is held at its reference's deterministic value: the
declared σ, else the kind's typical σ (:func:`reference_noises`, the ``fallback`` of
:func:`hexcal.estimation.noise_estimation.estimate_noise`), and the verdict says so.

>>> from hexcal.instruments import FullPoseModel
>>> refs = group_references([FullPoseModel()])
>>> [(r.group, r.high) for r in refs]
[('leg', 0.05), ('position', 1.0), ('orientation', 0.01)]
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hexcal.calibration.limits import MODEL_ERROR_FACTOR, MODEL_ERROR_FAIL
from hexcal.calibration.reasons import Reason
from hexcal.core.noise import NoiseModel
from hexcal.estimation.noise_estimation import MIN_REDUNDANCY, NOISE_UNITS
from hexcal.instruments.known_noise import LEG_ENCODERS, NoiseRange


@dataclass(frozen=True)
class GroupReference:
    """What one noise group of one session is held against.

    Attributes
    ----------
    session : int
    group : str
        ``leg``, ``position`` or ``orientation``.
    what : str
        The instrument ("leg encoders", "a laser tracker", ...).
    range : NoiseRange
        The noise such instruments have.
    declared : float or None
        The σ the setup declares.
    """

    session: int
    group: str
    what: str
    range: NoiseRange
    declared: float | None = None

    @property
    def value(self) -> float:
        """The deterministic σ of an undetermined group: the declared one, else the typical."""
        return self.range.typical if self.declared is None else self.declared

    @property
    def source(self) -> str:
        if self.declared is not None:
            return "as the setup declares"
        return f"typical of {self.what}"

    @property
    def high(self) -> float:
        """The largest σ that is still the instrument: the declared one, else the most such
        instruments show."""
        return self.range.high if self.declared is None else self.declared


def group_references(instruments: Sequence[Any]) -> list[GroupReference]:
    """The reference of every noise group of sessions measured by ``instruments``, legs first
    in each session (the order of :func:`hexcal.estimation.noise_estimation.problem_groups`)."""
    out = []
    for k, instrument in enumerate(instruments):
        out.append(GroupReference(k, "leg", "leg encoders", LEG_ENCODERS))
        device, declared = instrument.device, instrument.declared_noise()
        for group in instrument.noise_groups():
            found = device.ranges.get(group)
            if found is None:  # an instrument kind that does not know this group: no judgement
                found = NoiseRange(0.0, declared.get(group, NoiseModel().sigmas[1]), np.inf)
            out.append(GroupReference(k, group, device.label, found, declared.get(group)))
    return out


def reference_noises(instruments: Sequence[Any]) -> tuple[NoiseModel, ...]:
    """One normal :class:`NoiseModel` per session at its references' deterministic values: the
    start and the fallback of the noise estimation."""
    refs = group_references(instruments)
    out = []
    for k in range(len(instruments)):
        values = {r.group: r.value for r in refs if r.session == k}
        out.append(
            NoiseModel(
                values.get("leg", 0.0),
                values.get("position", NoiseModel().sigmas[1]),
                values.get("orientation", NoiseModel().sigmas[2]),
                distribution="normal",
            )
        )
    return tuple(out)


def _find(refs: list[GroupReference], key: tuple[int, str]) -> GroupReference | None:
    return next((r for r in refs if (r.session, r.group) == key), None)


def noise_findings(noise_estimate: Any, noise_check: Any, instruments: Sequence[Any] = ()) -> list[Reason]:
    """The verdict's reasons about the noise: the given noise against the data, the learned noise
    (its figures, the groups held at their fallback and why), and the learned noise against what
    the instruments can do."""
    out = []
    if noise_check is not None and noise_check.disagree:
        out.append(
            Reason(
                "noise-model",
                "warn",
                f"the given noise disagrees with the data: {noise_check.describe()} "
                "(estimate it from the data: noise auto)",
                noise_check.to_dict(),
            )
        )
    if noise_estimate is None:
        return out
    est = noise_estimate
    parts = [
        f"{g} σ {s:.3g} ± {e:.2g}" if np.isfinite(e) else f"{g} σ {s:.3g} (not estimated)"
        for g, s, e in zip(est.groups, est.sigmas, est.stderr, strict=True)
    ]
    out.append(Reason("noise-estimated", "info", "noise from the data: " + ", ".join(parts)))
    if not est.converged:
        out.append(Reason("noise-not-converged", "warn", "the variance components did not converge"))
    refs = group_references(instruments) if instruments else []
    for k, (g, ok, s, r) in enumerate(
        zip(est.groups, est.estimated, est.sigmas, est.redundancy, strict=True)
    ):
        if ok:
            continue
        # a stated fallback, not a fault: a group the others' noise hides in these data (the legs
        # under the seed paper's pose noise in 1 of 8 15-pose campaigns, one pivot's ballbar circles)
        why = (
            f"the others' noise hides it: it fell towards 0 over {r:.2g} degrees of freedom"
            if est.hidden_groups[k]
            else f"only {np.floor(r * 100) / 100:g} degrees of freedom, {MIN_REDUNDANCY:g} are needed"
        )
        ref = _find(refs, est.keys[k]) if est.keys else None
        unit = NOISE_UNITS.get(est.keys[k][1], "") if est.keys else ""
        held = f"held at σ {s:.3g} {unit}".rstrip() + (f", {ref.source}" if ref else "")
        text = f"the {g} noise is not determined by these data ({why}): {held} (give --noise if it is known)"
        out.append(Reason("noise-not-estimated", "info", text, {"group": g, "sigma": float(s)}))
    out += _plausibility(est, refs)
    return out


def _plausibility(est: Any, refs: list[GroupReference]) -> list[Reason]:
    """Each learned σ against its reference: an info line of the comparison, and a warn (fail)
    where the learned σ is beyond what the instrument can do."""
    if not refs or not est.keys:
        return []
    lines, beyond = [], []
    for k, key in enumerate(est.keys):
        ref = _find(refs, key)
        if ref is None or not est.estimated[k]:
            continue
        sigma, se = float(est.sigmas[k]), float(est.stderr[k])
        unit = NOISE_UNITS.get(key[1], "")
        factor = sigma / ref.high
        where = (
            f"{ref.declared:.3g} {unit} as declared"
            if ref.declared is not None
            else f"{ref.range.low:.3g}-{ref.range.high:.3g} {unit} for {ref.what}"
        )
        lines.append(f"{est.groups[k]} σ {sigma:.3g} {unit} ({factor:.2g}× the reference; {where})")
        margin = 2.0 * se if np.isfinite(se) else 0.0
        if factor > MODEL_ERROR_FACTOR and sigma - MODEL_ERROR_FACTOR * ref.high > margin:
            severity = "fail" if sigma > MODEL_ERROR_FAIL * ref.range.high else "warn"
            beyond.append((severity, k, factor, ref, unit))
    out = [Reason("noise-plausibility", "info", "learned noise against the instruments: " + "; ".join(lines))]
    for severity, k, factor, ref, unit in beyond:
        most = "what the setup declares" if ref.declared is not None else f"the most {ref.what} show"
        out.append(
            Reason(
                "model-error",
                severity,
                f"the model does not describe the data: {est.groups[k]} σ {est.sigmas[k]:.3g} {unit} is "
                f"{factor:.3g}× {most} ({ref.high:.3g} {unit}); the learned noise has absorbed an error "
                "the model lacks (a bumped instrument, a drift, a leg curve: see the other findings)",
                {
                    "group": est.groups[k],
                    "sigma": float(est.sigmas[k]),
                    "reference": ref.high,
                    "factor": factor,
                },
            )
        )
    return out


__all__ = [
    "MODEL_ERROR_FACTOR",
    "MODEL_ERROR_FAIL",
    "GroupReference",
    "group_references",
    "noise_findings",
    "reference_noises",
]
