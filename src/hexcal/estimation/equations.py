"""The errors-in-variables observation equations of a session, batch-first: where the leg
equations (:mod:`hexcal.core.machine`) and an instrument's (:class:`MeasurementModel`) meet.

Per observation ``j`` at its true pose ``P_j``, with the leg σ ``σ_leg`` and the instrument's
whitener ``W`` (``Wᵀ W = Σ_inst⁻¹``):

    e_leg,j  = (|o(P_j) + R(P_j) s_i - u_i| - f(θ_i, dl_ij)) / σ_leg      (6 values)
    e_inst,j = W (h(θ, P_j) - y_j)                                     (k values, 0 where absent)

with their Jacobians with respect to the pose (``b``) and to the parameters (the leg rows in each
leg's own columns, :func:`hexcal.core.machine.leg_equations`; the instrument rows in its own
quantities). Every function takes any leading batch shape: one campaign
(:meth:`hexcal.estimation.problem.Problem.observation_equations`) or a stack of trials
(:mod:`hexcal.estimation.likelihood`), through the same code.

Imports :mod:`hexcal.core` and the instrument interface.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hexcal.core.kinematics import pose_jacobian_from_arrays
from hexcal.core.legs import LegModel
from hexcal.core.linalg import floored_whitener
from hexcal.core.machine import leg_equations, pose_frames
from hexcal.core.noise import NoiseModel
from hexcal.instruments.base import MeasurementModel

#: Smallest leg sensor σ used in the likelihood (mm): a zero σ makes the legs exact
#: constraints, which this floor approximates without dividing by zero.
LEG_SIGMA_FLOOR = 1e-7

#: Smallest pose error variance used in the likelihood (mm², rad²), for the same reason.
POSE_VARIANCE_FLOOR = 1e-18


def session_weights(instrument: MeasurementModel, noise: NoiseModel) -> tuple[float, NDArray[np.float64]]:
    """The leg σ (floored) and the instrument's whitener ``(k, k)`` under ``noise``."""
    sigma = max(noise.sigmas[0], LEG_SIGMA_FLOOR)
    return sigma, floored_whitener(instrument.covariance(noise), POSE_VARIANCE_FLOOR)


@dataclass(frozen=True)
class Observations:
    """One session's constant inputs of the equations (arrays with any leading batch shape).

    Attributes
    ----------
    instrument : MeasurementModel
    euler : str
    model : LegModel
    readings : ndarray, shape (..., m, 6)
    observed : ndarray, shape (..., m, k)
    present : ndarray of bool, shape (..., m, k)
    sigma : float
        The leg σ (mm), floored.
    whitener : ndarray, shape (k, k)
    constant : bool
        The instrument rows of the pose Jacobian are the whitener itself (:meth:`of`).
    """

    instrument: MeasurementModel
    euler: str
    model: LegModel
    readings: NDArray[np.float64]
    observed: NDArray[np.float64]
    present: NDArray[np.bool_]
    sigma: float
    whitener: NDArray[np.float64]
    constant: bool = False

    @classmethod
    def of(cls, instrument, euler, model, readings, observed, present, sigma, whitener) -> Observations:
        """The inputs, ``constant`` where the instrument rows of the pose Jacobian are the whitener
        itself (the full pose, every value present)."""
        constant = bool(instrument.constant_pose_jacobian and np.all(present))
        return cls(instrument, euler, model, readings, observed, present, sigma, whitener, constant)

    @property
    def complete(self) -> bool:
        return bool(self.present.all())

    def take(self, idx: NDArray[np.intp]) -> Observations:
        """The trials ``idx`` of a stacked session."""
        return Observations(
            self.instrument,
            self.euler,
            self.model,
            self.readings[idx],
            self.observed[idx],
            self.present[idx],
            self.sigma,
            self.whitener,
            self.constant,
        )


@dataclass(frozen=True)
class Equations:
    """The whitened observation equations at some true poses (batch-first).

    Attributes
    ----------
    e_leg : ndarray, shape (..., m, 6)
    e_inst : ndarray, shape (..., m, k)
    b_leg : ndarray, shape (..., m, 6, 6)
        ``d e_leg / d pose``.
    b_inst : ndarray, shape (..., m, k, 6) or None
        ``d e_inst / d pose``; None where it is the whitener itself (:attr:`Observations.constant`).
    lengths : ndarray, shape (..., m, 6)
        Leg lengths of the poses on the machine.
    """

    e_leg: NDArray[np.float64]
    e_inst: NDArray[np.float64]
    b_leg: NDArray[np.float64]
    b_inst: NDArray[np.float64] | None
    lengths: NDArray[np.float64]

    def pose_rows(self, whitener: NDArray[np.float64]) -> NDArray[np.float64]:
        """The whole pose Jacobian ``b`` ``(..., m, 6 + k, 6)``."""
        b_inst = self.b_inst
        if b_inst is None:
            b_inst = np.broadcast_to(whitener, (*self.e_inst.shape[:-1], *whitener.shape))
        return np.concatenate([self.b_leg, b_inst], axis=-2)

    def residuals(self) -> NDArray[np.float64]:
        """The whole residual ``e`` ``(..., m, 6 + k)``."""
        return np.concatenate([self.e_leg, self.e_inst], axis=-1)

    def gram(self, whitener: NDArray[np.float64]) -> NDArray[np.float64]:
        """``bᵀ b`` of every observation ``(..., m, 6, 6)``."""
        leg = np.matmul(np.swapaxes(self.b_leg, -1, -2), self.b_leg)
        if self.b_inst is None:
            return leg + whitener.T @ whitener
        return leg + np.matmul(np.swapaxes(self.b_inst, -1, -2), self.b_inst)

    def rhs(self, whitener: NDArray[np.float64]) -> NDArray[np.float64]:
        """``bᵀ e`` of every observation ``(..., m, 6)``."""
        leg = np.einsum("...mki,...mk->...mi", self.b_leg, self.e_leg)
        if self.b_inst is None:
            return leg + self.e_inst @ whitener
        return leg + np.einsum("...mki,...mk->...mi", self.b_inst, self.e_inst)

    def take(self, idx: NDArray[np.intp] | NDArray[np.bool_]) -> Equations:
        """The trials ``idx`` of stacked equations."""
        return Equations(
            self.e_leg[idx],
            self.e_inst[idx],
            self.b_leg[idx],
            None if self.b_inst is None else self.b_inst[idx],
            self.lengths[idx],
        )

    def put(self, idx: NDArray[np.intp], other: Equations) -> None:
        """Write ``other`` into the trials ``idx`` (in place)."""
        self.e_leg[idx], self.e_inst[idx], self.b_leg[idx], self.lengths[idx] = (
            other.e_leg,
            other.e_inst,
            other.b_leg,
            other.lengths,
        )
        if self.b_inst is not None:
            self.b_inst[idx] = other.b_inst


def model_lengths(session: Observations, legs: NDArray[np.float64]) -> NDArray[np.float64]:
    """The lengths ``(..., m, 6)`` the leg model gives the session's readings for leg blocks
    ``legs`` ``(..., p)``."""
    return session.model.lengths(legs[..., None, :], session.readings)


def observation_equations(
    session: Observations,
    joints: NDArray[np.float64],
    legs: NDArray[np.float64],
    setup: NDArray[np.float64],
    poses: NDArray[np.float64],
    lengths_of_readings: NDArray[np.float64] | None = None,
) -> Equations:
    """The whitened equations of a session's observations at true ``poses`` ``(..., m, 6)``
    for the machine's ``joints`` ``(..., 36)`` and leg block ``legs`` ``(..., p)`` and the
    instrument's parameters ``setup`` ``(..., q)`` (see the module); ``lengths_of_readings``
    are :func:`model_lengths` when known (they do not depend on the poses)."""
    lead = joints.shape[:-1]
    u = joints[..., :18].reshape(*lead, 1, 6, 3)
    s = joints[..., 18:36].reshape(*lead, 1, 6, 3)
    lengths, jp = pose_jacobian_from_arrays(u, s, poses, session.euler)
    model = model_lengths(session, legs) if lengths_of_readings is None else lengths_of_readings
    e_leg = (lengths - model) / session.sigma
    b_leg = jp / session.sigma
    w, inst = session.whitener, session.instrument
    if session.constant:
        delta = inst.residual(setup, poses, session.euler, session.observed)
        return Equations(e_leg, delta @ w.T, b_leg, None, lengths)
    delta, dh = inst.residual_and_pose_jacobian(setup, poses, session.euler, session.observed, w)
    if session.complete:
        return Equations(e_leg, delta @ w.T, b_leg, dh, lengths)
    present = session.present
    e_inst = np.where(present, np.where(present, delta, 0.0) @ w.T, 0.0)
    return Equations(e_leg, e_inst, b_leg, np.where(present[..., None], dh, 0.0), lengths)


def parameter_rows(
    session: Observations,
    table: NDArray[np.float64],
    setup: NDArray[np.float64],
    poses: NDArray[np.float64],
    leg_scales: NDArray[np.float64],
    instrument_columns: NDArray[np.intp] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """The equations' Jacobian with respect to the parameters of stacked trials: the leg rows in
    each leg's own columns, legs first, ``(k, 6, m, L)`` (the leg table ``table`` ``(k, 6, L)``,
    :func:`hexcal.core.machine.leg_table`; columns in solver units of ``leg_scales`` ``(6, L)``),
    and the whitened instrument rows in the instrument's quantities ``instrument_columns``
    ``(k, m, K, q)`` (parameter units; None when none is asked)."""
    rot, pos = pose_frames(poses, session.euler)
    _, legs = leg_equations(table, session.model, rot, pos, session.readings, legs_first=True)
    legs = legs * (leg_scales / session.sigma)[:, None, :]
    if instrument_columns is None or len(instrument_columns) == 0:
        return legs, None
    d = session.instrument.setup_jacobian(setup, poses, session.euler)[..., instrument_columns]
    d = np.matmul(session.whitener, d)
    if not session.complete:
        d = np.where(session.present[..., None], d, 0.0)
    return legs, d
