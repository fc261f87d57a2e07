"""An identification problem, and the one place that maps solver variables to residuals.

A :class:`Problem` binds the start geometry, one or more measurement sessions (each its data
and the instrument that recorded them, :class:`hexcal.instruments.Session`) and the
parameter set: the machine's blocks ``joints`` and ``legs`` (shared by every session), then
each session's instrument block (``setup.0``, ``setup.1``, ...). Every estimator, the robust
fitting, the noise estimate and the bounds build their residual and Jacobian functions here:

- :meth:`Problem.least_squares_functions`: the leg residuals at the measured poses
  (``length`` or the seed paper's ``paper`` variant), optionally whitened per observation,
  for instruments whose observation determines the pose;
- :meth:`Problem.observation_equations`: the errors-in-variables equations of one session's
  observations at given true poses: whitened leg and instrument residuals, their Jacobian
  with respect to the varied parameters and to the pose.

The solver varies ``x = (θ - θ_start) / scale`` over the varied parameters
(:meth:`hexcal.core.parameters.ParameterSet.unpacker`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.linalg import null_space, numerical_rank, scaled_svd
from hexcal.core.machine import (
    check_variant,
    leg_equations,
    leg_parameter_jacobian,
    leg_residuals,
    leg_table,
    pose_frames,
    spread_legs,
)
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import ParameterSet
from hexcal.errors import IdentificationError, UsageError
from hexcal.estimation.equations import Observations, observation_equations
from hexcal.estimation.sessions import as_sessions, problem_parameters, session_labels
from hexcal.instruments.base import MeasurementModel, Session

Functions = tuple[
    Callable[[NDArray[np.float64]], NDArray[np.float64]], Callable[[NDArray[np.float64]], NDArray]
]


@dataclass(frozen=True, eq=False)
class Part:
    """One session inside a problem: its instrument, data arrays and parameter block.

    Attributes
    ----------
    session : Session
    label : str
    block : slice
        The instrument's parameters within the full parameter vector.
    rows : slice
        Its observations within the problem's (``sum`` over earlier sessions).
    readings : ndarray, shape (m, 6)
    observed : ndarray, shape (m, k)
    present : ndarray of bool, shape (m, k)
    """

    session: Session
    label: str
    block: slice
    rows: slice
    readings: NDArray[np.float64]
    observed: NDArray[np.float64]
    present: NDArray[np.bool_]

    @property
    def instrument(self) -> MeasurementModel:
        return self.session.instrument

    @property
    def data(self) -> Any:
        return self.session.data

    @property
    def complete(self) -> bool:
        return bool(self.present.all())

    def __len__(self) -> int:
        return len(self.readings)


class Problem:
    """Start geometry, measurement sessions and parameters of one identification.

    Parameters
    ----------
    start : Geometry
        Start values of the machine parameters (the nominal geometry) and its leg model.
    data
        A :class:`~hexcal.instruments.Session`, a sequence of sessions, or one data set that
        ``model`` reads (default the full pose in the base frame,
        :class:`~hexcal.instruments.FullPoseModel`).
    model : MeasurementModel, optional
        The instrument of ``data`` when it is not a session.
    mask : array_like of bool, optional
        Varied parameters: one flag per machine parameter (48 for linear legs), or one per
        parameter of the set. Default the machine's joints and ``l0`` and every instrument
        parameter its setup does not fix.
    parameters : ParameterSet, optional
        The whole parameter set (machine blocks, then the sessions' blocks), replacing ``mask``.
    fit, fix
        Groups to vary and names or groups to hold, instead of ``mask``.
    """

    def __init__(
        self,
        start: Geometry,
        data: Any,
        model: MeasurementModel | None = None,
        mask: ArrayLike | None = None,
        parameters: ParameterSet | None = None,
        *,
        fit: str | Sequence[str] | None = None,
        fix: Iterable[str] = (),
    ) -> None:
        self.start = start
        self.sessions = as_sessions(data, model)
        if parameters is None:
            parameters = problem_parameters(start, self.sessions, mask, fit, fix)
        self.parameters = parameters
        self.mask = np.array(parameters.vary)
        self.scale = np.array(parameters.scales[self.mask])
        self.full0 = np.array(parameters.values)
        self.unpack = parameters.unpacker()
        self.euler = start.euler
        self.legs = start.leg_model
        self.joints, self.leg_block = parameters.span("joints"), parameters.span("legs")
        self.machine = slice(self.joints.start, self.leg_block.stop)
        self.machine_mask = self.mask[self.machine]
        labels = session_labels(self.sessions)
        parts, start_row = [], 0
        for k, session in enumerate(self.sessions):
            inst = session.instrument
            observed, present = inst.observed(session.data)
            readings = np.asarray(inst.readings(session.data), dtype=float)
            rows = slice(start_row, start_row + len(readings))
            start_row = rows.stop
            block = parameters.span(f"setup.{k}")
            parts.append(Part(session, labels[k], block, rows, readings, observed, present))
        self.parts: tuple[Part, ...] = tuple(parts)
        self.readings = np.concatenate([p.readings for p in self.parts])
        many = len(self.parts) > 1
        self.ids: tuple[str, ...] = tuple(
            (f"{p.label}:{i}" if many else i) for p in self.parts for i in p.session.ids
        )
        self._frames: tuple[NDArray, NDArray] | None = None
        self._poses: NDArray[np.float64] | None = None
        self._start_poses: list[NDArray[np.float64] | None] = [None] * len(self.parts)

    # -- bookkeeping -------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.readings)

    @property
    def n_free(self) -> int:
        return int(self.mask.sum())

    @property
    def names(self) -> tuple[str, ...]:
        """Names of the varied parameters."""
        return self.parameters.free_names

    @property
    def model(self) -> MeasurementModel:
        """The instrument of a one-session problem."""
        if len(self.parts) != 1:
            raise UsageError("this problem has several sessions: use problem.parts")
        return self.parts[0].instrument

    @property
    def data(self) -> Any:
        """The data of a one-session problem."""
        if len(self.parts) != 1:
            raise UsageError("this problem has several sessions: use problem.parts")
        return self.parts[0].data

    @property
    def determines_pose(self) -> bool:
        """Whether every session's instrument gives the platform pose by itself."""
        return all(p.instrument.determines_pose for p in self.parts)

    def free_in(self, block: slice) -> NDArray[np.bool_]:
        """Which of the varied parameters lie in ``block`` (a mask over the varied ones)."""
        inside = np.zeros(len(self.mask), dtype=bool)
        inside[block] = True
        return inside[self.mask]

    def geometry(self, full: NDArray[np.float64]) -> Geometry:
        """The start geometry with the machine parameters of ``full``."""
        return self.start.with_machine_vector(full[self.machine])

    def setup(self, full: NDArray[np.float64], part: Part | None = None) -> NDArray[np.float64]:
        """A session's instrument parameters in ``full`` (the only session's by default)."""
        if part is None:
            if len(self.parts) != 1:
                raise UsageError("this problem has several sessions: name the session")
            part = self.parts[0]
        return full[part.block]

    def instruments(self, full: NDArray[np.float64]) -> tuple[MeasurementModel, ...]:
        """Every session's instrument with its parameters at ``full``."""
        return tuple(p.instrument.with_values(full[p.block]) for p in self.parts)

    def subset(self, index: ArrayLike) -> Problem:
        """The same problem on the observations at ``index`` (integer or boolean, over all
        sessions' observations in order)."""
        idx = np.arange(len(self))[np.asarray(index)]
        sessions = []
        for p in self.parts:
            own = idx[(idx >= p.rows.start) & (idx < p.rows.stop)] - p.rows.start
            sessions.append(p.session.replace(data=p.instrument.subset(p.data, own)))
        labelled = [s.replace(label=p.label) for s, p in zip(sessions, self.parts, strict=True)]
        return Problem(self.start, labelled, parameters=self.parameters)

    def leg_dimension(self) -> int:
        """Varied parameters of the busiest leg (its joints and leg-model parameters)."""
        from hexcal.core.machine import leg_columns

        cols = leg_columns(self.legs) + self.machine.start
        return int(np.max(np.sum(self.mask[cols], axis=1)))

    def check_size(self) -> None:
        """Refuse data sets too small to determine the varied parameters."""
        m, n = len(self), self.n_free
        if self.determines_pose:
            min_poses = self.leg_dimension()
            if m < min_poses:
                raise IdentificationError(
                    f"{m} poses cannot determine the parameters: at least {min_poses} are needed "
                    f"(each leg has {min_poses} parameters and gets one equation per pose)"
                )
            equations = 6 * m
        else:
            equations = int(sum(p.present.sum() for p in self.parts))
        if equations < n:
            raise IdentificationError(f"{equations} equations for {n} parameters: measure more poses")

    def check_rank(self, jac_scaled: NDArray[np.float64], where: str = "") -> None:
        """Refuse a rank-deficient (scaled) Jacobian, naming the weakest combination."""
        svd = scaled_svd(jac_scaled)
        rank = numerical_rank(svd.singular_values)
        if rank < self.n_free:
            basis, _ = null_space(jac_scaled)
            combos = "; ".join(self.combination(v) for v in basis[:5])
            more = f" and {len(basis) - 5} more" if len(basis) > 5 else ""
            raise IdentificationError(
                f"the poses cannot identify all parameters{where} (rank-deficient Jacobian: rank "
                f"{rank} of {self.n_free}; weakest combination: {self.combination(svd.vt[-1])}; "
                f"undetermined combinations: {combos}{more})"
            )

    def combination(self, vector: NDArray[np.float64], top: int = 4) -> str:
        """Readable form of a parameter combination (its largest components)."""
        order = np.argsort(-np.abs(vector))[:top]
        return " ".join(f"{vector[k]:+.2f}·{self.names[k]}" for k in order)

    # -- measured poses (instruments that determine the pose) --------------------------
    def measured_frames(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Rotations and positions of the measured platform poses (cached)."""
        if self._frames is None:
            self._frames = pose_frames(self.measured_poses(), self.euler)
        return self._frames

    def measured_poses(self) -> NDArray[np.float64]:
        """The platform poses ``(m, 6)`` the observations give (instruments that determine
        the pose; :class:`IdentificationError` otherwise)."""
        if self._poses is None:
            bad = [p for p in self.parts if not p.instrument.determines_pose]
            if bad:
                raise IdentificationError(
                    f"the {bad[0].instrument.name} measurement does not determine the platform pose by "
                    "itself: use the ml estimator"
                )
            self._poses = np.concatenate(
                [p.instrument.platform_poses(self.full0[p.block], p.data, self.euler) for p in self.parts]
            )
        return self._poses

    def leg_residuals(self, full: NDArray[np.float64], variant: str = "length") -> NDArray[np.float64]:
        """Leg residuals at the measured poses, ``(m, 6)``."""
        rot, pos = self.measured_frames()
        return leg_residuals(
            full[self.joints], full[self.leg_block], self.legs, rot, pos, self.readings, variant
        )

    def leg_jacobian(
        self, full: NDArray[np.float64], variant: str = "length", scaled: bool = True
    ) -> NDArray[np.float64]:
        """Jacobian of :meth:`leg_residuals`, ``(6 m, n_free)``, in solver units (or parameter
        units when not ``scaled``); instrument parameters do not enter the legs."""
        rot, pos = self.measured_frames()
        machine = leg_parameter_jacobian(
            full[self.joints], full[self.leg_block], self.legs, rot, pos, self.readings, variant
        ).reshape(-1, self.machine.stop - self.machine.start)
        jac = np.zeros((machine.shape[0], len(self.mask)))
        jac[:, self.machine] = machine
        return jac[:, self.mask] * self.scale if scaled else jac[:, self.mask]

    def least_squares_functions(self, variant: str = "length", weights: NDArray | None = None) -> Functions:
        """``fun(x)`` and ``jac(x)`` of the leg residuals at the measured poses.

        ``weights`` (m, 6, 6) whiten each pose's six residuals (generalised least squares).
        """
        check_variant(variant)
        m, unpack = len(self), self.unpack

        if weights is None:

            def fun(x: NDArray[np.float64]) -> NDArray[np.float64]:
                return self.leg_residuals(unpack(x), variant).ravel()

            def jac(x: NDArray[np.float64]) -> NDArray[np.float64]:
                return self.leg_jacobian(unpack(x), variant)

            return fun, jac

        def wfun(x: NDArray[np.float64]) -> NDArray[np.float64]:
            return np.einsum("mij,mj->mi", weights, self.leg_residuals(unpack(x), variant)).ravel()

        def wjac(x: NDArray[np.float64]) -> NDArray[np.float64]:
            a = self.leg_jacobian(unpack(x), variant).reshape(m, 6, -1)
            return np.matmul(weights, a).reshape(6 * m, -1)

        return wfun, wjac

    # -- errors in variables -----------------------------------------------------------
    def start_poses(self, part: Part) -> NDArray[np.float64]:
        """The instrument's initial estimates of a session's true poses ``(m, 6)`` (cached)."""
        k = self.parts.index(part)
        if self._start_poses[k] is None:
            self._start_poses[k] = part.instrument.start_poses(self.start, self.full0[part.block], part.data)
        return self._start_poses[k]

    def observations(self, part: Part, leg_sigma: float, instrument_whitener: NDArray) -> Observations:
        """A session's constant inputs of :mod:`hexcal.estimation.equations`."""
        return Observations.of(
            part.instrument,
            self.euler,
            self.legs,
            part.readings,
            part.observed,
            part.present,
            leg_sigma,
            instrument_whitener,
        )

    def observation_equations(
        self,
        part: Part,
        full: NDArray[np.float64],
        poses: NDArray[np.float64],
        leg_sigma: float,
        instrument_whitener: NDArray[np.float64],
        parameters: bool = True,
    ) -> tuple[NDArray, NDArray, NDArray | None, NDArray]:
        """Whitened errors-in-variables equations of one session's observations at true ``poses``
        (:func:`hexcal.estimation.equations.observation_equations`).

        Returns
        -------
        e : ndarray, shape (m, 6 + k)
            Leg residuals over ``leg_sigma``, then the whitened instrument residuals
            ``W (h(θ, P) - y)`` (zero where a value is missing).
        b : ndarray, shape (m, 6 + k, 6)
            Their Jacobian with respect to the pose.
        a : ndarray, shape (m, 6 + k, n_free) or None
            Their Jacobian with respect to the varied parameters in solver units (when
            ``parameters``).
        lengths : ndarray, shape (m, 6)
            Leg lengths of the poses on the machine of ``full``.
        """
        obs = self.observations(part, leg_sigma, instrument_whitener)
        eqs = observation_equations(obs, full[self.joints], full[self.leg_block], full[part.block], poses)
        a = (
            self.eiv_parameter_jacobian(part, full, poses, leg_sigma, instrument_whitener)
            if parameters
            else None
        )
        return eqs.residuals(), eqs.pose_rows(instrument_whitener), a, eqs.lengths

    def leg_rows(
        self, part: Part, full: NDArray[np.float64], poses: NDArray[np.float64], variant: str = "length"
    ) -> NDArray[np.float64]:
        """Jacobian of one session's leg residuals at ``poses`` with respect to the varied
        parameters, ``(m, 6, n_free)`` in solver units (instrument parameters do not enter)."""
        rot, pos = pose_frames(poses, self.euler)
        table = leg_table(full[self.joints], full[self.leg_block], self.legs)
        _, local = leg_equations(table, self.legs, rot, pos, part.readings, variant)
        return self.spread_leg_rows(local)

    def spread_leg_rows(self, local: NDArray[np.float64]) -> NDArray[np.float64]:
        """Leg rows in each leg's own columns ``(..., 6, L)`` (parameter units) as rows over the
        varied parameters ``(..., 6, n_free)`` in solver units."""
        legs = spread_legs(local, self.legs)
        out = np.zeros((*legs.shape[:-1], self.n_free))
        in_machine = self.free_in(self.machine)
        out[..., in_machine] = legs[..., self.machine_mask] * self.scale[in_machine]
        return out

    def eiv_parameter_jacobian(
        self,
        part: Part,
        full: NDArray[np.float64],
        poses: NDArray[np.float64],
        leg_sigma: float,
        w: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """Jacobian of one session's observation equations with respect to the varied
        parameters, ``(m, 6 + k, n_free)`` in solver units (see :meth:`observation_equations`)."""
        m, k = len(part), part.instrument.size
        out = np.zeros((m, 6 + k, self.n_free))
        out[:, :6] = self.leg_rows(part, full, poses) / leg_sigma
        own = self.free_in(part.block)
        if own.any():
            setup = full[part.block]
            dsetup = np.matmul(w, part.instrument.setup_jacobian(setup, poses, self.euler))
            if not part.complete:
                dsetup = np.where(part.present[..., None], dsetup, 0.0)
            out[:, 6:, own] = dsetup[:, :, self.mask[part.block]] * self.scale[own]
        return out

    def observation_counts(self) -> NDArray[np.intp]:
        """Equations per observation after the six pose unknowns: ``6 + present values - 6``."""
        return np.concatenate([p.present.sum(axis=1) for p in self.parts])


def session_noises(
    problem: Problem, noise: NoiseModel | Sequence[NoiseModel] | None
) -> tuple[NoiseModel, ...]:
    """One noise model per session (one given for all, or one each; None: the seed paper's)."""
    if noise is None:
        noise = NoiseModel()
    if isinstance(noise, NoiseModel):
        return (noise,) * len(problem.parts)
    noises = tuple(noise)
    if len(noises) != len(problem.parts):
        raise IdentificationError(f"{len(noises)} noise models for {len(problem.parts)} sessions")
    return noises
