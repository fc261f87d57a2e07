"""Instruments in their own frame: the frame's pose and what the instrument sees on the platform.

A laser tracker, a camera or a motion-capture system measures in its own frame. Its setup
(:class:`~hexcal.instruments.setup.Setup`) is the base frame's pose in the instrument frame
(first six values) and the instrument's quantities on the platform (targets or a tool,
the rest). :class:`FramedModel` holds what such instruments share: the parameters of the
setup (``fixed`` quantities not varied), the change of coordinates that the gauge freedoms
are made of, the start poses (forward kinematics of the leg readings) and the registration
of an unknown frame (``instrument_frame: auto``) from the data.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import forward_kinematics, leg_lengths
from hexcal.core.parameters import ParameterSet
from hexcal.instruments.base import MeasurementModel
from hexcal.instruments.setup import Setup, transform_frame


def cross_axes(axes: NDArray[np.float64], vectors: NDArray[np.float64]) -> NDArray[np.float64]:
    """``w_k × v`` for axes ``(..., 3 (k), 3)`` and vectors ``(..., 3)``: ``(..., 3 (coord), 3 (k))``."""
    return np.moveaxis(np.cross(axes, vectors[..., None, :]), -2, -1)


def fk_start_poses(geometry: Geometry, readings: NDArray[np.float64]) -> NDArray[np.float64]:
    """Forward kinematics of leg readings on ``geometry`` (home pose where it fails)."""
    home = geometry.home_pose if geometry.home_pose is not None else np.zeros(6)
    fk = forward_kinematics(geometry, leg_lengths(geometry, readings), guess=home)
    return np.where(fk.converged[:, None], fk.poses, home)


class FramedModel(MeasurementModel):
    """An instrument in its own frame with a :class:`Setup` (frame first, then the rest).

    Subclasses say how the platform part of the setup changes with platform coordinates
    (:meth:`platform_setup`) and how the frame is registered (:meth:`register`).
    """

    setup: Setup

    def parameters(self) -> ParameterSet:
        return self.setup.parameters()

    def with_values(self, values: NDArray[np.float64], calibration: dict[str, Any] | None = None) -> Any:
        return type(self)(self.setup.with_vector(values, calibration), **self.options())

    def options(self) -> dict[str, Any]:
        """Constructor options beyond the setup (kept by :meth:`with_values`)."""
        return {}

    def setup_dict(self) -> dict[str, Any] | None:
        return self.setup.to_dict()

    @property
    def device(self) -> Any:
        return self.setup.device

    def declared_noise(self) -> dict[str, float]:
        return dict(self.setup.noise or {})

    @property
    def unregistered(self) -> bool:
        return self.setup.auto

    def as_start(self) -> MeasurementModel:
        if "instrument_frame" in self.setup.fixed:
            return self
        return type(self)(replace(self.setup, frame=None, calibration=None), **self.options())

    def after_step(self) -> MeasurementModel:
        """A frame held fixed is unknown after a step (``auto``, registered from the data);
        everything else keeps its setup."""
        if "instrument_frame" not in self.setup.fixed:
            return self
        fixed = tuple(f for f in self.setup.fixed if f != "instrument_frame")
        setup = replace(self.setup, frame=None, fixed=fixed, calibration=None)
        return type(self)(setup, **self.options())

    def start_poses(self, geometry: Geometry, setup: NDArray[np.float64], data: Any) -> NDArray[np.float64]:
        return fk_start_poses(geometry, self.readings(data))

    def platform_setup(
        self, values: NDArray[np.float64], platform: tuple[NDArray, NDArray], euler: str
    ) -> NDArray[np.float64]:
        """The platform part of the setup in new platform coordinates (``p' = R_p p + t_p``)."""
        raise NotImplementedError

    def transform_setup(
        self,
        setup: NDArray[np.float64],
        base: tuple[NDArray, NDArray],
        platform: tuple[NDArray, NDArray],
        euler: str,
    ) -> NDArray[np.float64]:
        frame = transform_frame(setup[..., :6], base, euler)
        return np.concatenate([frame, self.platform_setup(setup[..., 6:], platform, euler)], axis=-1)
