"""A session split where its instrument moved: the remedy of a step in acquisition order.

When a laser tracker is bumped half-way through a session (or a frame, a tool, a target
slips), the observations before and after it were measured from different places: they are two
sessions, each with its own instrument quantities (:mod:`hexcal.calibration.sequence` finds and
locates such a step). :func:`split_sessions` makes them: a split ``LABEL:ID`` ends the session
``LABEL`` before the observation ``ID`` (``ID`` alone when there is one session); the part after
it measures with :meth:`~hexcal.instruments.MeasurementModel.after_step` (a frame held fixed is
unknown again) and is labelled ``LABEL#2`` (``#3``, ... for more splits; the first part
``LABEL#1``).

>>> from hexcal.instruments import FullPoseModel, Measurements, Session
>>> data = Measurements(np.zeros((10, 6)), np.zeros((10, 6)), tuple("abcdefghij"))
>>> parts, done = split_sessions([Session(data, FullPoseModel(), "s.csv")], ["s.csv:f"])
>>> [(p.label, p.ids[0], len(p), p.instrument.name) for p in parts], done
([('s.csv#1', 'a', 5, 'pose'), ('s.csv#2', 'f', 5, 'tool')], ('s.csv:f',))

Each part needs :data:`~hexcal.calibration.limits.MIN_SEGMENT` poses (its instrument is
registered again).
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise
from typing import Any

import numpy as np

from hexcal.calibration.limits import MIN_SEGMENT
from hexcal.errors import UsageError
from hexcal.estimation.sessions import session_labels
from hexcal.instruments.base import Session


def _parse(spec: str, labels: tuple[str, ...]) -> tuple[int, str]:
    """``(session index, id)`` of a split ``LABEL:ID`` (or ``ID`` with one session)."""
    text = str(spec).strip()
    for k, label in enumerate(labels):  # a label may itself hold ':' (a Windows path)
        if text.startswith(label + ":"):
            return k, text[len(label) + 1 :]
    if len(labels) == 1:
        return 0, text.removeprefix(":")
    raise UsageError(
        f"split {spec!r}: name the session and the first pose after the step, LABEL:ID, with LABEL one of "
        f"{', '.join(labels)}"
    )


def split_sessions(sessions: Sequence[Session], at: Sequence[str]) -> tuple[list[Session], tuple[str, ...]]:
    """The sessions with each split of ``at`` made (module docstring): the new sessions, and the
    splits as ``LABEL:ID`` in the sessions' order; :class:`UsageError` naming a split that names
    no session or pose, or that would leave a part without observations."""
    labels = session_labels(sessions)
    points: dict[int, set[int]] = {}
    for spec in at:
        k, pose = _parse(spec, labels)
        ids = sessions[k].ids
        if pose not in ids:
            raise UsageError(f"split {spec!r}: {labels[k]} has no pose {pose!r}")
        index = ids.index(pose)
        if index == 0:
            raise UsageError(
                f"split {spec!r}: {pose} is the first pose of {labels[k]}: nothing comes before it"
            )
        points.setdefault(k, set()).add(index)
    out: list[Session] = []
    done: list[str] = []
    for k, session in enumerate(sessions):
        cuts = sorted(points.get(k, ()))
        if not cuts:
            out.append(session)
            continue
        bounds = [0, *cuts, len(session)]
        instrument = session.instrument
        for n, (lo, hi) in enumerate(pairwise(bounds)):
            if hi - lo < MIN_SEGMENT:  # its instrument registered again from a handful of poses
                raise UsageError(
                    f"split {labels[k]}:{session.ids[lo if n else hi]}: a part of {labels[k]} would hold "
                    f"{hi - lo} pose(s) ({session.ids[lo]} ... {session.ids[hi - 1]}); each part is a "
                    f"session of its own, its instrument registered again: give it at least {MIN_SEGMENT}"
                )
            part = session.subset(np.arange(lo, hi))
            if n:
                instrument = instrument.after_step()
            out.append(part.replace(instrument=instrument, label=f"{labels[k]}#{n + 1}"))
        done += [f"{labels[k]}:{session.ids[c]}" for c in cuts]
    return out, tuple(done)


def step_splits(verdict: Any) -> tuple[str, ...]:
    """The splits a verdict's steps ask for (``LABEL:ID`` of each step's first pose after it)."""
    if verdict is None:
        return ()
    return tuple(
        f"{r.data['session']}:{r.data['after']}"
        for r in verdict.reasons
        if r.code == "step" and r.data.get("after")
    )


__all__ = ["split_sessions", "step_splits"]
