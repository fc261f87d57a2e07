"""The measurement-model interface: what an instrument measures at a platform pose.

Every observation ``j`` (one measured pose of the machine) has six leg readings and some
instrument values ``y_j``. Its unknowns are the parameters ``θ`` (the machine's, and the
instrument setup's that the model adds) and the true platform pose ``P_j`` (a nuisance
parameter). A model predicts the instrument values ``h(θ, P_j)`` and gives their Jacobians
with respect to the setup parameters and to the pose, which observation values are present
(a laser tracker loses a target now and then), and their noise covariance. The leg
equations (:mod:`hexcal.instruments.legs`) are the same for every model, so a new instrument is
one new subclass of :class:`MeasurementModel`.

Imports :mod:`hexcal.core` only.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import ParameterSet


class MeasurementModel(ABC):
    """An instrument: predicted values of an observation, their Jacobians and their noise.

    Attributes
    ----------
    name : str
        Registry name.
    size : int
        Instrument values per observation (missing values are masked, see :meth:`observed`).
    measures_pose : bool
        Whether one observation determines the platform pose by itself (the estimators that
        treat the measured pose as exact, ``paper``, ``length`` and ``gls``, need this).
    """

    name: str = ""
    size: int = 0
    measures_pose: bool = False

    def parameters(self) -> ParameterSet:
        """The parameters this model adds to the machine's (none by default)."""
        return ParameterSet((), np.empty(0))

    @abstractmethod
    def observed(self, data: Any) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Instrument values ``(m, size)`` of the data and which are present (same shape)."""

    @abstractmethod
    def predict(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        """Predicted instrument values ``(m, size)`` at true poses ``(m, 6)``."""

    def residual(
        self,
        setup: NDArray[np.float64],
        poses: NDArray[np.float64],
        euler: str,
        observed: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """Instrument residual ``(m, size)`` at true poses: ``predict - observed`` by default; a
        model overrides it where a plain difference is not a distance (orientations)."""
        return self.predict(setup, poses, euler) - observed

    @abstractmethod
    def pose_jacobian(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        """``d predict / d pose``, shape ``(m, size, 6)``."""

    def whitened_pose_jacobian(
        self,
        setup: NDArray[np.float64],
        poses: NDArray[np.float64],
        euler: str,
        whitener: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """``W d predict / d pose`` for a whitening matrix ``W`` (size, size): ``(m, size, 6)``."""
        return np.matmul(whitener, self.pose_jacobian(setup, poses, euler))

    def setup_jacobian(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        """``d predict / d setup parameters``, shape ``(m, size, q)`` (none by default)."""
        return np.zeros((len(poses), self.size, len(setup)))

    @abstractmethod
    def covariance(self, noise: NoiseModel) -> NDArray[np.float64]:
        """Noise covariance of one observation's instrument values, ``(size, size)``."""

    @abstractmethod
    def start_poses(self, geometry: Geometry, setup: NDArray[np.float64], data: Any) -> NDArray[np.float64]:
        """Initial estimates of the true poses ``(m, 6)``."""

    def readings(self, data: Any) -> NDArray[np.float64]:
        """Leg readings ``(m, 6)`` of the data."""
        return data.readings

    def ids(self, data: Any) -> tuple[str, ...]:
        """Observation labels."""
        return tuple(data.ids)

    def subset(self, data: Any, index: NDArray[np.intp]) -> Any:
        """The observations at ``index``."""
        return data.subset(index)
