"""Sessions as one problem: the sessions of a calibration and the parameter layout they share.

The machine's blocks (``joints``, ``legs``) come first, then each session's instrument block
(``setup.0``, ``setup.1``, ...); with several sessions an instrument's parameter names and
groups carry the session's prefix (``session2.frame.x``, group ``session2.frame``) and the
plain groups (``frame``, ``tool``, ``targets``) gather every session's.
"""

from __future__ import annotations

import os
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
    if isinstance(data, str | os.PathLike):
        raise UsageError(f"{data!r}: give sessions, not a file name (hexcal.read_sessions reads files)")
    if isinstance(data, Sequence) and len(data) == 0:
        raise UsageError("no session: give at least one (hexcal.read_sessions reads them from files)")
    if isinstance(data, Sequence) and data and all(isinstance(s, Session) for s in data):
        if model is not None:
            raise UsageError("give the instrument with each session, not as model=")
        return tuple(data)
    return (Session(data, full_pose() if model is None else model),)


def refuse_repeated_sessions(sessions: Sequence[Session]) -> None:
    """Refuse a session given twice: two sessions with the same observations (the same ids, leg
    readings and instrument values, in any row order), :class:`UsageError` naming both. The
    same poses measured again (another station, another day) are new observations and pass."""
    seen: list[tuple[int, type, tuple[Any, ...]]] = []
    labels = session_labels(sessions)
    for k, session in enumerate(sessions):
        kind, rows = type(session.instrument), _observations(session)
        for j, o_kind, o_rows in seen:
            if (
                kind is o_kind
                and len(rows[0]) == len(o_rows[0])
                and all(np.array_equal(a, b) for a, b in zip(rows, o_rows, strict=True))
            ):
                raise UsageError(
                    f"the same session twice ({labels[j]} and {labels[k]} hold the same observations: ids, "
                    "leg readings and measured values): each session counts once; give it once"
                )
        seen.append((k, kind, rows))


def _observations(session: Session) -> tuple[Any, ...]:
    """A session's ids, leg readings, which values are present and the values, its rows in a
    canonical order (a file's rows reordered hold the same observations)."""
    inst = session.instrument
    ids = np.asarray(session.ids, dtype=str)
    readings = np.asarray(inst.readings(session.data), dtype=float).reshape(len(ids), -1)
    values, present = inst.observed(session.data)
    present = np.asarray(present, dtype=bool).reshape(len(ids), -1)
    values = np.where(present, np.asarray(values, dtype=float).reshape(len(ids), -1), 0.0)
    keys = np.hstack([readings, present, values])
    order = np.lexsort((*keys.T[::-1], ids))  # by id, then by the numbers (ids may repeat)
    return ids[order], readings[order], present[order], values[order]


def session_labels(sessions: Sequence[Session]) -> tuple[str, ...]:
    """Each session's label (its own, else ``session k``), made unique."""
    labels: list[str] = []
    for k, s in enumerate(sessions, start=1):
        label = s.label or f"session {k}"
        if label in labels:
            label = f"{label} ({k})"
        labels.append(label)
    return tuple(labels)


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


def setup_blocks(instruments: Sequence[MeasurementModel]) -> list[ParameterSet]:
    """Each session's instrument parameters as its block ``setup.{k}`` of a problem; with
    several sessions their names and groups carry the session's prefix (``session2.``)."""
    many = len(instruments) > 1
    out = []
    for k, inst in enumerate(instruments):
        own = inst.parameters()
        out.append(own.renamed(f"session{k + 1}." if many else "", {f"setup.{k}": (0, len(own))}))
    return out


def parameter_units(start: Geometry, instruments: Sequence[MeasurementModel]) -> dict[str, str]:
    """The unit of every parameter of a problem over sessions of ``instruments`` from ``start``,
    by name as the problem names it (the machine's, then each session's setup): what its result
    reports in. Each comes from where the parameter is made (the geometry's leg model, the
    instrument's setup)."""
    units = start.machine_parameters(DEFAULT_FIT).unit_of()
    for own in setup_blocks(instruments):
        units |= own.unit_of()
    return units


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
    blocks = setup_blocks([s.instrument for s in sessions])
    params = machine
    held = []
    for own in blocks:
        params = params + own
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
        instrument_groups = [g for own in blocks for g in own.groups if "." not in g]
        fit = list(dict.fromkeys([*groups, *instrument_groups]))
        vary = np.array(params.select(fit, fix).vary) & instrument_held
        _check_model_terms(start, params, groups, vary)
    if not vary.any():
        raise UsageError("no parameter left to identify")
    return params.with_vary(vary)
