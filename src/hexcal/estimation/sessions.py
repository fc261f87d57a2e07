"""Sessions as one problem: the sessions of a calibration and the parameter layout they share.

The machine's blocks (``joints``, ``legs``) come first, then each session's instrument block
(``setup.0``, ``setup.1``, ...); with several sessions an instrument's parameter names and
groups carry the session's prefix (``session2.frame.x``, group ``session2.frame``) and the
plain groups (``frame``, ``tool``, ``targets``) gather every session's.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.parameters import DEFAULT_FIT, ParameterSet
from hexcal.errors import UsageError
from hexcal.instruments.base import MeasurementModel, Session
from hexcal.instruments.registry import full_pose


def as_sessions(data: Any, model: MeasurementModel | None = None) -> tuple[Session, ...]:
    """Sessions of ``data``: a session or a sequence of sessions as they are, or one data set
    read by ``model`` (default the full pose in the base frame)."""
    if isinstance(data, Session):
        return (data,)
    if isinstance(data, Sequence) and data and all(isinstance(s, Session) for s in data):
        if model is not None:
            raise UsageError("give the instrument with each session, not as model=")
        return tuple(data)
    return (Session(data, full_pose() if model is None else model),)


def refuse_repeated_sessions(sessions: Sequence[Session]) -> None:
    """Refuse a session given twice: two sessions with the same observations (the same ids, leg
    readings and instrument values), :class:`UsageError` naming both. The same poses measured
    again (another station, another day) are new observations and pass."""
    seen: list[tuple[int, Session]] = []
    labels = session_labels(sessions)
    for k, session in enumerate(sessions):
        inst = session.instrument
        readings = np.asarray(inst.readings(session.data), dtype=float)
        values, present = inst.observed(session.data)
        for j, other in seen:
            o_inst = other.instrument
            if (
                type(o_inst) is type(inst)
                and session.ids == other.ids
                and np.array_equal(readings, np.asarray(o_inst.readings(other.data), dtype=float))
                and np.array_equal(present, o_inst.observed(other.data)[1])
                and np.array_equal(
                    np.where(present, values, 0.0), np.where(present, o_inst.observed(other.data)[0], 0.0)
                )
            ):
                raise UsageError(
                    f"the same session twice ({labels[j]} and {labels[k]} hold the same observations: ids, "
                    "leg readings and measured values): each session counts once; give it once"
                )
        seen.append((k, session))


def session_labels(sessions: Sequence[Session]) -> tuple[str, ...]:
    """Each session's label (its own, else ``session k``), made unique."""
    labels: list[str] = []
    for k, s in enumerate(sessions, start=1):
        label = s.label or f"session {k}"
        if label in labels:
            label = f"{label} ({k})"
        labels.append(label)
    return tuple(labels)


def _prefixed(params: ParameterSet, prefix: str) -> ParameterSet:
    """A session's instrument parameters with ``prefix`` on every name and group."""
    names = tuple(prefix + n for n in params.names)
    groups = {prefix + g: tuple(prefix + n for n in v) for g, v in params.groups.items()}
    groups |= {g: tuple(prefix + n for n in v) for g, v in params.groups.items()}  # shared groups
    return ParameterSet(names, params.values, params.vary, params.scales, groups, params.blocks)


def _check_model_terms(start: Geometry, params: ParameterSet, groups: Sequence[str], vary: NDArray) -> None:
    """Refuse a leg model asked for (its group in ``fit``) whose terms are all held and all 0:
    the model identified and written would be the linear one under the other model's name."""
    model = start.leg_model
    if not model.terms or model.name not in groups or model.name not in params.groups:
        return
    names = params.groups[model.name]
    index = [params.index(n) for n in names]
    if not vary[index].any() and not np.any(np.asarray(params.values)[index]):
        raise UsageError(
            f"--fix holds every term of the {model.name} leg model at 0, so the model identified would be "
            f"the linear one under the {model.name} name; fit its terms (leave --fix {model.name} out), "
            "or use --leg-model linear"
        )


def problem_parameters(
    start: Geometry,
    sessions: Sequence[Session],
    mask: ArrayLike | None = None,
    fit: str | Sequence[str] | None = None,
    fix: Iterable[str] = (),
) -> ParameterSet:
    """The machine's blocks and each session's instrument block, varied as asked.

    ``fit`` names the machine's groups to vary (default ``joints,l0``); every instrument
    quantity its setup does not fix varies too. ``fix`` names parameters or groups to hold
    (``frame``, ``tool``, ``targets``, ``l0``...). A ``mask`` over the machine's parameters
    (48 for linear legs), or over all, replaces ``fit``.
    """
    machine = start.machine_parameters(DEFAULT_FIT)
    many = len(sessions) > 1
    blocks = []
    for k, session in enumerate(sessions):
        own = session.instrument.parameters()
        own = _prefixed(own, f"session{k + 1}.") if many else own
        blocks.append((f"setup.{k}", own))
    params = machine
    held = []
    for key, own in blocks:
        sub = ParameterSet(own.names, own.values, own.vary, own.scales, own.groups, {key: (0, len(own))})
        params = params + sub
        held.append(own.vary)
    instrument_held = np.concatenate([np.ones(len(machine), bool), *held])
    fix = list(fix)
    for group in [f for f in fix if f in params.groups]:  # a group name holds the whole group
        fix.remove(group)
        fix.extend(params.groups[group])
    if mask is not None:
        flags = np.asarray(mask, dtype=bool)
        if flags.shape == (len(machine),):
            flags = np.concatenate([flags, *held]) if held else flags
        if flags.shape != (len(params),):
            raise UsageError(f"mask must have shape ({len(machine)},) or ({len(params)},), got {flags.shape}")
        vary = flags & instrument_held
        for name in fix:
            if name not in params:
                raise UsageError(f"unknown parameter {name!r} (names are like u1.x, s3.z, l0_2, g4)")
            vary[params.index(name)] = False
    else:
        # ``fit`` names the machine's groups; the instruments' quantities vary as their setups
        # say (hold them with ``fix``)
        fit = DEFAULT_FIT if fit is None else fit
        groups = [g.strip() for g in fit.split(",") if g.strip()] if isinstance(fit, str) else list(fit)
        instrument_groups = [g for _, own in blocks for g in own.groups if "." not in g]
        fit = list(dict.fromkeys([*groups, *instrument_groups]))
        vary = np.array(params.select(fit, fix).vary) & instrument_held
        _check_model_terms(start, params, groups, vary)
    if not vary.any():
        raise UsageError("no parameter left to identify")
    return params.with_vary(vary)
