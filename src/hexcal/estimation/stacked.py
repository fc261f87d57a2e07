"""A problem stacked over trials: ``T`` campaigns of one shape, solved together.

A :class:`Stack` is what :class:`~hexcal.estimation.problem.Problem` is for one campaign,
for ``T`` of them that share the machine's leg model and Euler sequence, the instrument (its
kind, what its setup fixes, its layout) and the parameter layout and vary flags, but not the
data or the start values (the nominal machine, an instrument frame registered per trial). Its
arrays have a leading trial axis: readings ``(T, m, 6)``, the instrument's values and which
are present ``(T, m, k)``, start values ``(T, N)``. The batched estimators
(:mod:`hexcal.estimation.batched`) evaluate the same equations as ``Problem`` on these
stacks, through the same leg model and the same instrument functions (batch-first).

Observations may be padded to a common count per trial: a padded observation has no value
present, so its pose follows from its legs alone and it adds no information.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.machine import leg_columns
from hexcal.core.parameters import ParameterSet
from hexcal.errors import UsageError
from hexcal.estimation.gauge import gauge_generators
from hexcal.estimation.problem import Problem
from hexcal.instruments.base import MeasurementModel, Session


@dataclass(frozen=True, eq=False)
class Stack:
    """``T`` campaigns of one shape (see the module).

    Attributes
    ----------
    start : Geometry
        The machine the parameter layout and leg model come from (its values are the template).
    instrument : MeasurementModel
        The instrument of every campaign (its values are those of ``full0``'s rows).
    parameters : ParameterSet
        Names, blocks, vary flags and solver scales (shared).
    full0 : ndarray, shape (T, N)
        Start values of every trial.
    readings : ndarray, shape (T, m, 6)
    observed : ndarray, shape (T, m, k)
    present : ndarray of bool, shape (T, m, k)
    sessions : tuple of Session, optional
        The campaigns themselves (needed for gauge freedoms: their instruments' frames).
    """

    start: Geometry
    instrument: MeasurementModel
    parameters: ParameterSet
    full0: NDArray[np.float64]
    readings: NDArray[np.float64]
    observed: NDArray[np.float64]
    present: NDArray[np.bool_]
    sessions: tuple[Session, ...] | None = None

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
    def setup(self) -> slice:
        return self.parameters.span("setup.0")

    def leg_columns(self) -> NDArray[np.intp]:
        """Full-vector positions of each leg's own parameters ``(6, L)``."""
        return leg_columns(self.start.leg_model) + self.machine.start

    def template(self, trial: int) -> Problem:
        """The one-campaign :class:`Problem` of trial ``trial`` at its start values (for the
        gauge freedoms and the convention, which need the layout and the instrument)."""
        if self.sessions is None:
            raise UsageError("this stack was built from arrays: build it from sessions for its gauges")
        values = self.full0[trial]
        geometry = self.start.with_machine_vector(values[self.machine])
        return Problem(geometry, self.sessions[trial], parameters=self.parameters.with_values(values))

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
        return cls(start, sessions[0].instrument, params, full0, readings, observed, present, tuple(sessions))

    def gauges(self) -> tuple[tuple[str, ...], NDArray[np.float64]]:
        """The gauge freedoms (labels, the same in every trial) and each trial's generators
        ``(T, n_free, g)`` in solver units at its start values (none unless an instrument
        quantity varies: a frame is free only where the instrument's quantities move with it)."""
        if not self.mask[self.setup].any():
            return (), np.zeros((len(self), int(self.mask.sum()), 0))
        return gauge_generators(self.template(0), self.full0)
