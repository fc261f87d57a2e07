"""The full-pose measurement: the platform pose measured in the base frame.

An observation is a measured pose (laser tracker and CMM software that already express the
platform pose in the machine's base frame, or simulated data) together with the six leg
readings the controller reported there. :class:`Measurements` holds the data;
:class:`FullPoseModel` is the measurement model (the instrument reads the pose itself).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.conventions import as_poses
from hexcal.core.geometry import Geometry
from hexcal.core.noise import NoiseModel
from hexcal.errors import UsageError
from hexcal.instruments.base import MeasurementModel


@dataclass(frozen=True, eq=False)
class Measurements:
    """Measured poses and the leg readings at each.

    Parameters
    ----------
    poses : array_like, shape (m, 6)
        Measured poses, mm and rad, in the geometry's Euler convention.
    readings : array_like, shape (m, 6)
        Leg readings ``dl_i``, mm.
    ids : sequence of str, optional
        Pose labels; default ``"1" ... "m"`` (the row numbers).
    """

    poses: NDArray[np.float64]
    readings: NDArray[np.float64]
    ids: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        poses = np.array(as_poses(self.poses, "measured poses"), dtype=float)
        readings = np.array(self.readings, dtype=float)
        if poses.ndim != 2:
            raise UsageError(f"measured poses must have shape (m, 6), got {poses.shape}")
        if readings.shape != poses.shape:
            raise UsageError(
                f"leg readings must have shape {poses.shape} like the poses, got {readings.shape}"
            )
        for what, arr in (("measured poses", poses), ("leg readings", readings)):
            bad = np.flatnonzero(~np.all(np.isfinite(arr), axis=1))
            if bad.size:
                raise UsageError(f"{what} contain NaN or inf (row {bad[0] + 1})")
        ids = tuple(str(i) for i in self.ids) or tuple(str(k + 1) for k in range(len(poses)))
        if len(ids) != len(poses):
            raise UsageError(f"{len(ids)} ids for {len(poses)} poses")
        poses.flags.writeable = False
        readings.flags.writeable = False
        object.__setattr__(self, "poses", poses)
        object.__setattr__(self, "readings", readings)
        object.__setattr__(self, "ids", ids)

    def __len__(self) -> int:
        return int(self.poses.shape[0])

    def subset(self, index: ArrayLike) -> Measurements:
        """The measurements at ``index`` (an integer or boolean index)."""
        idx = np.arange(len(self))[np.asarray(index)]
        return Measurements(self.poses[idx], self.readings[idx], tuple(self.ids[i] for i in idx))


class FullPoseModel(MeasurementModel):
    """The instrument reads the platform pose in the base frame: ``h(P) = P``.

    Its noise is the pose measurement noise of a :class:`~hexcal.core.noise.NoiseModel`
    (``position`` and ``orientation``, or a full 6×6 ``pose_covariance``). The leg residual
    variants ``length`` and ``paper`` evaluate the legs at the measured poses.

    >>> model = FullPoseModel()
    >>> model.predict(np.empty(0), np.zeros((2, 6)), "XYZ").shape
    (2, 6)
    """

    name = "pose"
    size = 6
    measures_pose = True

    def observed(self, data: Measurements) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        return data.poses, np.ones(data.poses.shape, dtype=bool)

    def predict(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        return poses

    def pose_jacobian(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        return np.broadcast_to(np.eye(6), (len(poses), 6, 6))

    def whitened_pose_jacobian(
        self,
        setup: NDArray[np.float64],
        poses: NDArray[np.float64],
        euler: str,
        whitener: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        return np.broadcast_to(whitener, (len(poses), 6, 6))

    def covariance(self, noise: NoiseModel) -> NDArray[np.float64]:
        return noise.pose_cov()

    def start_poses(
        self, geometry: Geometry, setup: NDArray[np.float64], data: Measurements
    ) -> NDArray[np.float64]:
        return np.array(data.poses)
