"""Simulated instrument data, and instrument values predicted from leg readings.

Library functions for ``hexcal synthesize --setup`` and ``hexcal validate --setup``.
Simulation follows the campaign protocol (:mod:`hexcal.simulation.campaign`): the readings
are the nominal inverse kinematics of the commanded poses, the true machine reaches the
forward kinematics of its own parameters at those readings plus the leg sensor error, and
the instrument sees the true setup there plus its noise: each target coordinate the
``position`` noise of the :class:`~hexcal.core.noise.NoiseModel`, a tool pose the pose noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import forward_kinematics, inverse_kinematics, leg_lengths, leg_readings
from hexcal.core.noise import NoiseModel
from hexcal.errors import SimulationError, ValidationError
from hexcal.instruments.pose import Measurements
from hexcal.instruments.setup import Setup
from hexcal.instruments.targets import TargetMeasurements, TargetModel
from hexcal.instruments.tool import ToolModel


def instrument_model(setup: Setup) -> TargetModel | ToolModel:
    """The measurement model of a setup (targets or tool)."""
    return TargetModel(setup) if setup.kind == "targets" else ToolModel(setup)


def true_poses(
    nominal: Geometry, true: Geometry, poses: ArrayLike, noise: NoiseModel | None, rng: np.random.Generator
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Leg readings ``(m, 6)`` of commanded poses and the poses the true machine reaches."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 6)
    readings = leg_readings(nominal, inverse_kinematics(nominal, poses))
    lengths = leg_lengths(true, readings)
    if noise is not None:
        lengths = lengths + noise.leg_errors(rng, (len(poses),))
    reached = forward_kinematics(true, lengths, guess=poses)
    if not reached.all_converged:
        raise SimulationError("the true machine cannot reach every commanded pose")
    return readings, reached.poses


def simulate_target_measurements(
    nominal: Geometry,
    true: Geometry,
    setup: Setup,
    poses: ArrayLike,
    noise: NoiseModel | None = None,
    missing_rate: float = 0.0,
    rng: np.random.Generator | int | None = None,
) -> TargetMeasurements:
    """A simulated tracker export: target positions (instrument frame) at commanded poses.

    ``setup`` is the true setup (frame given). Each target observation is lost with
    probability ``missing_rate``; a pose where every target was lost is left out (the ids
    keep the commanded pose numbers). Noise-free when
    ``noise`` is None.
    """
    rng = np.random.default_rng(rng)
    if setup.frame is None:
        raise SimulationError("simulation needs the true instrument frame (not auto)")
    readings, reached = true_poses(nominal, true, poses, noise, rng)
    model = TargetModel(setup)
    m, n = len(reached), model.n_targets
    values = model.predict(setup.vector(), reached, true.euler).reshape(m, n, 3)
    if noise is not None:
        values = values + noise.pose_errors(rng, (m, n))[..., :3]
    lost = rng.random((m, n)) < missing_rate
    values[lost] = np.nan
    keep = ~lost.all(axis=1)  # a pose with no target seen is not recorded
    ids = tuple(str(k + 1) for k in np.flatnonzero(keep))
    return TargetMeasurements(readings[keep], values[keep], setup.target_names, ids)


def simulate_tool_measurements(
    nominal: Geometry,
    true: Geometry,
    setup: Setup,
    poses: ArrayLike,
    noise: NoiseModel | None = None,
    rng: np.random.Generator | int | None = None,
) -> Measurements:
    """Simulated tool poses (instrument frame) at commanded poses (noise-free if ``noise`` is None)."""
    rng = np.random.default_rng(rng)
    if setup.frame is None:
        raise SimulationError("simulation needs the true instrument frame (not auto)")
    readings, reached = true_poses(nominal, true, poses, noise, rng)
    values = ToolModel(setup).predict(setup.vector(), reached, true.euler)
    if noise is not None:
        values = values + noise.pose_errors(rng, (len(values),))
    return Measurements(values, readings)


def predict_instrument(geometry: Geometry, setup: Setup, readings: ArrayLike) -> NDArray[np.float64]:
    """Instrument values predicted from leg readings: forward kinematics on ``geometry``, then
    the setup. Targets ``(m, n, 3)`` or tool poses ``(m, 6)``; NaN where the forward
    kinematics fails."""
    readings = np.asarray(readings, dtype=float).reshape(-1, 6)
    home = geometry.home_pose if geometry.home_pose is not None else np.zeros(6)
    fk = forward_kinematics(geometry, leg_lengths(geometry, readings), guess=home)
    model = instrument_model(setup)
    out = model.predict(setup.vector(), np.where(fk.converged[:, None], fk.poses, home), geometry.euler)
    out[~fk.converged] = np.nan
    return out.reshape(len(readings), -1, 3) if setup.kind == "targets" else out


@dataclass(frozen=True)
class InstrumentValidation:
    """Held-out instrument values against their prediction from the leg readings.

    ``errors``: distance per target observation ``(m, n)`` (NaN where not seen), or tool
    position error ``(m,)``; ``rms``, ``max`` in mm over all seen values.
    """

    errors: NDArray[np.float64]
    rms: float
    max: float
    count: int


def validate_instrument(
    geometry: Geometry, setup: Setup, data: TargetMeasurements | Measurements
) -> InstrumentValidation:
    """Compare measured target positions (or tool positions) with their prediction."""
    if setup.frame is None:
        raise ValidationError("validation needs a calibrated setup (the instrument frame is auto)")
    pred = predict_instrument(geometry, setup, data.readings)
    if setup.kind == "targets":
        errors = np.linalg.norm(pred - data.targets, axis=-1)
    else:
        errors = np.linalg.norm(pred[:, :3] - data.poses[:, :3], axis=-1)
    good = errors[np.isfinite(errors)]
    if good.size == 0:
        raise ValidationError("no held-out value could be predicted (forward kinematics failed)")
    return InstrumentValidation(errors, float(np.sqrt(np.mean(good**2))), float(good.max()), int(good.size))
