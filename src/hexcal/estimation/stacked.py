"""Identification problems stacked over trials: ``T`` campaigns of one layout, solved together.

A :class:`Stack` is what the solvers work on. It holds ``T`` campaigns that share the machine's
leg model and Euler sequence, the sessions' instruments (their kinds, what their setups fix,
their layouts) and the parameter layout and vary flags, but not the data or the start values
(the nominal machine, an instrument frame registered per trial). Each session is a
:class:`StackPart` whose arrays have a leading trial axis: readings ``(T, m, 6)``, the
instrument's values and which are present ``(T, m, k)``; the start values are ``(T, N)``.

One identification is a stack of one (:meth:`Stack.of_problem`: ``T = 1``, every session of the
:class:`~hexcal.estimation.problem.Problem` a part); a Monte Carlo study's cell is a stack of its
trials (:meth:`Stack.of_sessions`, one session each). The solvers evaluate the same equations on
both (:mod:`hexcal.estimation.equations`).

Observations may be padded to a common count per trial: a padded observation has no value
present, so its pose follows from its legs alone and it adds no information.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.machine import leg_columns
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import ParameterSet
from hexcal.errors import UsageError
from hexcal.estimation.equations import Observations, session_weights
from hexcal.estimation.gauge import gauge_generators
from hexcal.estimation.problem import Problem
from hexcal.instruments.base import MeasurementModel, Session


@dataclass(frozen=True, eq=False)
class StackPart:
    """One session of every campaign of a stack.

    Attributes
    ----------
    instrument : MeasurementModel
        Its instrument (the values are those of each trial's start values).
    block : slice
        Its parameters within the full parameter vector.
    readings : ndarray, shape (T, m, 6)
    observed : ndarray, shape (T, m, k)
    present : ndarray of bool, shape (T, m, k)
    start_poses : ndarray, shape (T, m, 6)
        Initial estimates of the true poses.
    """

    instrument: MeasurementModel
    block: slice
    readings: NDArray[np.float64]
    observed: NDArray[np.float64]
    present: NDArray[np.bool_]
    start_poses: NDArray[np.float64]

    def rows(self, rows: Any) -> StackPart:
        """The trials ``rows`` (copies)."""
        return replace(
            self,
            readings=np.array(self.readings[rows]),
            observed=np.array(self.observed[rows]),
            present=np.array(self.present[rows]),
            start_poses=np.array(self.start_poses[rows]),
        )

    def observations(self, start: Geometry, noise: NoiseModel) -> Observations:
        """The equations' constant inputs under ``noise``."""
        sigma, whitener = session_weights(self.instrument, noise)
        return Observations.of(
            self.instrument,
            start.euler,
            start.leg_model,
            self.readings,
            self.observed,
            self.present,
            sigma,
            whitener,
        )


@dataclass(frozen=True, eq=False)
class Stack:
    """``T`` campaigns of one layout (see the module).

    Attributes
    ----------
    start : Geometry
        The machine the parameter layout and leg model come from (its values are the template).
    parameters : ParameterSet
        Names, blocks, vary flags and solver scales (shared).
    full0 : ndarray, shape (T, N)
        Start values of every trial.
    parts : tuple of StackPart
        Every session.
    sessions : tuple of tuple of Session, optional
        Each trial's sessions (needed for gauge freedoms: their instruments' frames).
    problem : Problem, optional
        The one campaign of a stack of one.
    """

    start: Geometry
    parameters: ParameterSet
    full0: NDArray[np.float64]
    parts: tuple[StackPart, ...]
    sessions: tuple[tuple[Session, ...], ...] | None = None
    problem: Problem | None = None

    def __len__(self) -> int:
        return int(self.full0.shape[0])

    @property
    def euler(self) -> str:
        return self.start.euler

    @property
    def mask(self) -> NDArray[np.bool_]:
        return np.asarray(self.parameters.vary)

    @property
    def scales(self) -> NDArray[np.float64]:
        return np.asarray(self.parameters.scales)

    @property
    def machine(self) -> slice:
        joints, legs = self.parameters.span("joints"), self.parameters.span("legs")
        return slice(joints.start, legs.stop)

    @property
    def joints(self) -> slice:
        return self.parameters.span("joints")

    @property
    def legs(self) -> slice:
        return self.parameters.span("legs")

    @property
    def determines_pose(self) -> bool:
        """Whether every session's instrument gives the platform pose by itself."""
        return all(p.instrument.determines_pose for p in self.parts)

    def leg_columns(self) -> NDArray[np.intp]:
        """Full-vector positions of each leg's own parameters ``(6, L)``."""
        return leg_columns(self.start.leg_model) + self.machine.start

    def rows(self, rows: Any) -> Stack:
        """The trials ``rows`` (a slice or indices; copies of the arrays)."""
        idx = np.arange(len(self))[rows]
        sessions = None if self.sessions is None else tuple(self.sessions[i] for i in idx)
        return replace(
            self,
            full0=np.array(self.full0[rows]),
            parts=tuple(p.rows(rows) for p in self.parts),
            sessions=sessions,
        )

    def template(self, trial: int) -> Problem:
        """The one-campaign :class:`Problem` of trial ``trial`` at its start values (for the
        gauge freedoms and the convention, which need the layout and the instruments)."""
        if self.problem is not None:
            return self.problem
        if self.sessions is None:
            raise UsageError("this stack was built from arrays: build it from sessions for its gauges")
        values = self.full0[trial]
        geometry = self.start.with_machine_vector(values[self.machine])
        return Problem(geometry, list(self.sessions[trial]), parameters=self.parameters.with_values(values))

    def gauges(self) -> tuple[tuple[str, ...], NDArray[np.float64]]:
        """The gauge freedoms (labels, the same in every trial) and each trial's generators
        ``(T, n_free, g)`` in solver units at its start values (none unless an instrument
        quantity varies: a frame is free only where the instrument's quantities move with it)."""
        mask = self.mask
        if not any(mask[p.block].any() for p in self.parts):
            return (), np.zeros((len(self), int(mask.sum()), 0))
        return gauge_generators(self.template(0), self.full0)

    # -- construction ---------------------------------------------------------------------
    @classmethod
    def of_problem(cls, problem: Problem, poses: Sequence[NDArray[np.float64]] | None = None) -> Stack:
        """One identification as a stack of one: every session a part, its start poses
        ``poses`` (one array per session) or the instrument's."""
        poses = [problem.start_poses(p) for p in problem.parts] if poses is None else poses
        parts = tuple(
            StackPart(p.instrument, p.block, p.readings[None], p.observed[None], p.present[None], own[None])
            for p, own in zip(problem.parts, poses, strict=True)
        )
        return cls(problem.start, problem.parameters, problem.full0[None], parts, None, problem)

    @classmethod
    def of_sessions(
        cls,
        start: Geometry,
        sessions: Sequence[Session],
        parameters: ParameterSet | None = None,
        *,
        mask: Any = None,
        fit: Any = None,
        fix: Any = (),
    ) -> Stack:
        """The stack of one-session campaigns (the same instrument kind and layout in each);
        each trial's start values are its instrument's (a frame registered per trial) with the
        machine's from ``start``."""
        if not sessions:
            raise UsageError("a stack needs at least one campaign")
        first = Problem(start, sessions[0], parameters=parameters, mask=mask, fit=fit, fix=fix)
        params = first.parameters
        block = params.span("setup.0")
        m = max(len(s) for s in sessions)
        k = sessions[0].instrument.size
        t = len(sessions)
        readings, observed = np.zeros((t, m, 6)), np.zeros((t, m, k))
        present = np.zeros((t, m, k), dtype=bool)
        full0 = np.tile(np.asarray(params.values), (t, 1))
        for i, session in enumerate(sessions):  # gathering the data, not solving
            inst = session.instrument
            values, seen = inst.observed(session.data)
            n = len(values)
            readings[i, :n], observed[i, :n], present[i, :n] = inst.readings(session.data), values, seen
            full0[i, block] = inst.parameters().values
        instrument = sessions[0].instrument
        poses = start_poses(start, instrument, full0, params, block, readings, observed)
        part = StackPart(instrument, block, readings, observed, present, poses)
        return cls(start, params, full0, (part,), tuple((s,) for s in sessions))


def start_poses(
    start: Geometry,
    instrument: MeasurementModel,
    full0: NDArray[np.float64],
    parameters: ParameterSet,
    block: slice,
    readings: NDArray[np.float64],
    observed: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Each trial's start poses ``(T, m, 6)``: the measured platform pose where the instrument
    gives it, else the forward kinematics of the readings on each trial's start machine (what
    :meth:`MeasurementModel.start_poses` gives one campaign, for all trials at once)."""
    if instrument.determines_pose:
        return instrument.platform_from(full0[:, block], observed, start.euler)
    from hexcal.core.kinematics import forward_kinematics_from_arrays

    joints = full0[:, parameters.span("joints")]
    t = len(full0)
    u, s = joints[:, None, :18].reshape(t, 1, 6, 3), joints[:, None, 18:36].reshape(t, 1, 6, 3)
    lengths = start.leg_model.lengths(full0[:, None, parameters.span("legs")], readings)
    home = start.home_pose if start.home_pose is not None else np.zeros(6)
    fk = forward_kinematics_from_arrays(
        u, s, lengths, np.broadcast_to(home, (*lengths.shape[:-1], 6)), start.euler
    )
    return np.where(fk.converged[..., None], fk.poses, home)
