"""The ballbar: one distance per pose between a base pivot and a platform ball.

At the true platform pose ``(o, R_P)`` the bar's centre-to-centre distance is
``|o + R_P b - c|`` (``c`` the pivot, base frame; ``b`` the ball, platform frame); the bar
reads ``d = |o + R_P b - c| - length``. One value per observation, the residual
``|o + R_P b - c| - length - d``. Noise: the :class:`~hexcal.core.noise.NoiseModel`'s
``position`` standard deviation (the bar's reading error; reported as the ``ballbar`` group).

What distance data cannot see. The distance does not change when the base frame moves
(with the pivot and every pose) or the platform frame moves (with the ball and every pose):
with the pivot and the ball free these are the twelve gauge freedoms of every instrument with
its own quantities on both sides, removed by hexcal's one convention
(:mod:`hexcal.estimation.gauge`). A pivot held fixed ties the base frame's translation to it,
but not its rotation about it: those three combinations (and the platform's three about a
fixed ball) are not gauges the convention removes and are named by the identifiability
analysis (``observability``) as what the data cannot determine. The bar's ``length`` is seen
through the size of the circles, so it is identified with the rest; it is held fixed only when
the bar was calibrated on its own setting gauge (``fixed: [length]``). Unlike a tracker the
ballbar does not give the platform pose: only the ``ml`` estimator uses it (``gls``,
``length`` and ``paper`` refuse in one line).

>>> model = BallbarModel(BallbarSetup([0, 0, 0], [0, 0, 0], 100.0))
>>> model.predict(model.setup.vector(), np.array([[0.0, 0, 100.5, 0, 0, 0]]), "XYZ")
array([[0.5]])
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.conventions import euler_axes
from hexcal.core.geometry import Geometry
from hexcal.core.machine import pose_frames
from hexcal.core.noise import NoiseModel
from hexcal.errors import UsageError
from hexcal.instruments.ballbar_setup import BallbarMeasurements, BallbarSetup
from hexcal.instruments.base import MeasurementModel
from hexcal.instruments.framed import cross_axes, fk_start_poses
from hexcal.instruments.pose import LENGTH_UNITS


class BallbarModel(MeasurementModel):
    """A ballbar between ``pivot`` (base frame) and ``ball`` (platform frame): 1 value per pose.

    Parameters
    ----------
    setup : BallbarSetup
        Pivot, ball, length and which are fixed.
    """

    name = "ballbar"
    size = 1

    def __init__(self, setup: BallbarSetup | None = None) -> None:
        self.setup = BallbarSetup(np.zeros(3), np.zeros(3), 100.0) if setup is None else setup
        if getattr(self.setup, "kind", None) != "ballbar":
            raise UsageError("the ballbar model needs a ballbar setup")

    # -- parameters ----------------------------------------------------------------------
    def parameters(self) -> Any:
        return self.setup.parameters()

    def with_values(
        self, values: NDArray[np.float64], calibration: dict[str, Any] | None = None
    ) -> BallbarModel:
        return BallbarModel(self.setup.with_vector(values, calibration))

    def describe(self) -> str:
        return f"ballbar of {self.setup.length:g} mm between a base pivot and a platform ball"

    def setup_dict(self) -> dict[str, Any] | None:
        return self.setup.to_dict()

    def after_step(self) -> BallbarModel:
        """A pivot held fixed is free after a step (its cup was knocked)."""
        if "pivot" not in self.setup.fixed:
            return self
        fixed = tuple(f for f in self.setup.fixed if f != "pivot")
        return BallbarModel(dataclasses.replace(self.setup, fixed=fixed, calibration=None))

    @property
    def device(self) -> Any:
        return self.setup.device

    def declared_noise(self) -> dict[str, float]:
        return dict(self.setup.noise or {})

    # -- data ----------------------------------------------------------------------------
    def observed(self, data: BallbarMeasurements) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        values = data.d[:, None]
        return values, np.ones(values.shape, dtype=bool)

    # -- the model: batch-first, setup (..., 7) and poses (..., m, 6) ----------------------
    def _vector(self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str) -> tuple:
        rot, pos = pose_frames(poses, euler)
        pivot, ball = setup[..., None, :3], setup[..., None, 3:6]
        rb = np.einsum("...ij,...j->...i", rot, np.broadcast_to(ball, pos.shape))
        v = pos + rb - pivot
        return rot, rb, v, np.linalg.norm(v, axis=-1, keepdims=True)

    def predict(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        """The reading ``d`` ``(..., m, 1)`` at true poses: distance minus ``length``."""
        return self._vector(setup, poses, euler)[3] - setup[..., None, 6:7]

    def pose_jacobian(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        _, rb, v, dist = self._vector(setup, poses, euler)
        n = v / dist
        axes = euler_axes(poses[..., 3:], euler)
        angles = np.einsum("...i,...ik->...k", n, cross_axes(axes, rb))
        return np.concatenate([n, angles], axis=-1)[..., None, :]

    def residual_and_pose_jacobian(
        self,
        setup: NDArray[np.float64],
        poses: NDArray[np.float64],
        euler: str,
        observed: NDArray[np.float64],
        whitener: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        _, rb, v, dist = self._vector(setup, poses, euler)  # once for both
        n = v / dist
        axes = euler_axes(poses[..., 3:], euler)
        angles = np.einsum("...i,...ik->...k", n, cross_axes(axes, rb))
        jac = np.concatenate([n, angles], axis=-1)[..., None, :]
        return dist - setup[..., None, 6:7] - observed, np.matmul(whitener, jac)

    def setup_jacobian(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        rot, _, v, dist = self._vector(setup, poses, euler)
        n = v / dist
        ball = np.einsum("...i,...ij->...j", n, rot)
        return np.concatenate([-n, ball, -np.ones_like(dist)], axis=-1)[..., None, :]

    def covariance(self, noise: NoiseModel) -> NDArray[np.float64]:
        return np.array([[noise.sigmas[1] ** 2]])

    def group_labels(self) -> dict[str, str]:
        return {"position": "ballbar"}

    def start_poses(self, geometry: Geometry, setup: NDArray[np.float64], data: Any) -> NDArray[np.float64]:
        return fk_start_poses(geometry, data.readings)

    def transform_setup(
        self,
        setup: NDArray[np.float64],
        base: tuple[NDArray, NDArray],
        platform: tuple[NDArray, NDArray],
        euler: str,
    ) -> NDArray[np.float64]:
        (rb, tb), (rp, tp) = base, platform
        pivot = np.einsum("...ij,...j->...i", rb, setup[..., :3]) + tb
        ball = np.einsum("...ij,...j->...i", rp, setup[..., 3:6]) + tp
        return np.concatenate([pivot, ball, setup[..., 6:7]], axis=-1)

    # -- simulation, diagnoses, validation -------------------------------------------------
    def simulate(
        self,
        setup: NDArray[np.float64],
        poses: NDArray[np.float64],
        readings: NDArray[np.float64],
        euler: str,
        noise: NoiseModel | None,
        rng: np.random.Generator,
        ids: tuple[str, ...] = (),
    ) -> BallbarMeasurements:
        """Bar readings at true poses plus the reading noise (``position``'s σ)."""
        d = self.predict(setup, poses, euler)[:, 0]
        if noise is not None:
            d = d + noise.pose_errors(rng, (len(poses),))[:, 0]
        return BallbarMeasurements(readings, d, ids)

    def variants(self, data: BallbarMeasurements) -> tuple[tuple[str, str, Any], ...]:
        return tuple(
            (f"length-units-{unit}", f"the bar readings look like {unit}", data.replace(d=data.d * f))
            for unit, f in LENGTH_UNITS
        )

    def errors(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], data: BallbarMeasurements, euler: str
    ) -> dict[str, NDArray[np.float64]]:
        """The bar reading's prediction error (mm), predicted minus read."""
        return {"bar": self.predict(setup, poses, euler)[:, 0] - data.d}
