"""Position instruments: laser-tracker targets (SMRs) on the platform, in the tracker's frame.

An observation is one pose of the machine: the six leg readings and, for each target of the
setup, its measured position in the instrument frame (or nothing, when the line of sight was
lost). The model predicts ``y_i = R_F (o + R_P q_i) + t_F`` for target ``q_i`` (platform frame)
at the true pose ``(o, R_P)`` with the instrument frame ``(R_F, t_F)``: three residuals per
target seen. Noise: each coordinate of a target has the standard deviation of
:class:`~hexcal.core.noise.NoiseModel`'s ``position`` (independent, isotropic).

>>> from hexcal.instruments.setup import Setup
>>> model = TargetModel(Setup(np.zeros(6), {"t1": [0, 0, 60]}))
>>> model.predict(model.setup.vector(), np.zeros((2, 6)), "XYZ")
array([[ 0.,  0., 60.],
       [ 0.,  0., 60.]])
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.conventions import euler_axes
from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import forward_kinematics, leg_lengths
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import ParameterSet
from hexcal.errors import UsageError
from hexcal.instruments.base import MeasurementModel
from hexcal.instruments.legs import pose_frames
from hexcal.instruments.setup import Setup, frame_transform, transform_frame


@dataclass(frozen=True, eq=False)
class TargetMeasurements:
    """Leg readings and measured target positions of every pose.

    Parameters
    ----------
    readings : array_like, shape (m, 6)
        Leg readings ``dl``, mm.
    targets : array_like, shape (m, n, 3)
        Target positions in the instrument frame, mm; a target not seen is NaN (all three).
    names : sequence of str
        Target names ``t1 ...`` (``n``).
    ids : sequence of str, optional
        Pose labels; default the row numbers.
    """

    readings: NDArray[np.float64]
    targets: NDArray[np.float64]
    names: tuple[str, ...]
    ids: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        readings = np.array(self.readings, dtype=float)
        targets = np.array(self.targets, dtype=float)
        names = tuple(self.names)
        m = len(readings)
        if readings.ndim != 2 or readings.shape[1] != 6:
            raise UsageError(f"leg readings must have shape (m, 6), got {readings.shape}")
        if targets.shape != (m, len(names), 3):
            raise UsageError(f"target positions must have shape ({m}, {len(names)}, 3), got {targets.shape}")
        ids = tuple(str(i) for i in self.ids) or tuple(str(k + 1) for k in range(m))
        if len(ids) != m:
            raise UsageError(f"{len(ids)} ids for {m} poses")
        bad = np.flatnonzero(~np.all(np.isfinite(readings), axis=1))
        if bad.size:
            raise UsageError(f"leg readings contain NaN or inf (pose {ids[bad[0]]}, row {bad[0] + 1})")
        nan = np.isnan(targets)
        partial = np.flatnonzero(np.any(nan.any(axis=2) & ~nan.all(axis=2), axis=1))
        if partial.size or np.isinf(targets).any():
            k = partial[0] if partial.size else int(np.argwhere(np.isinf(targets))[0, 0])
            raise UsageError(f"pose {ids[k]} (row {k + 1}): a target needs all three coordinates or none")
        unseen = np.flatnonzero(nan.all(axis=(1, 2)))
        if unseen.size:
            k = unseen[0]
            raise UsageError(f"pose {ids[k]} (row {k + 1}): no target seen (every target cell is empty)")
        for arr in (readings, targets):
            arr.flags.writeable = False
        object.__setattr__(self, "readings", readings)
        object.__setattr__(self, "targets", targets)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "ids", ids)

    def __len__(self) -> int:
        return int(self.readings.shape[0])

    @property
    def seen(self) -> NDArray[np.bool_]:
        """Which target was seen at which pose, ``(m, n)``."""
        return ~np.isnan(self.targets[..., 0])

    def subset(self, index: ArrayLike) -> TargetMeasurements:
        """The poses at ``index`` (integer or boolean)."""
        idx = np.arange(len(self))[np.asarray(index)]
        return TargetMeasurements(
            self.readings[idx], self.targets[idx], self.names, tuple(self.ids[i] for i in idx)
        )


def cross_axes(axes: NDArray[np.float64], vectors: NDArray[np.float64]) -> NDArray[np.float64]:
    """``w_k × v`` for axes ``(..., 3 (k), 3)`` and vectors ``(..., 3)``: ``(..., 3 (coord), 3 (k))``."""
    return np.moveaxis(np.cross(axes, vectors[..., None, :]), -2, -1)


def fk_start_poses(geometry: Geometry, readings: NDArray[np.float64]) -> NDArray[np.float64]:
    """Forward kinematics of leg readings on ``geometry`` (home pose where it fails)."""
    home = geometry.home_pose if geometry.home_pose is not None else np.zeros(6)
    fk = forward_kinematics(geometry, leg_lengths(geometry, readings), guess=home)
    return np.where(fk.converged[:, None], fk.poses, home)


class FramedModel(MeasurementModel):
    """An instrument in its own frame: the setup is the frame's pose (first six values) and
    what the instrument sees on the platform (the rest); poses start from the forward
    kinematics of the leg readings."""

    def start_poses(self, geometry: Geometry, setup: NDArray[np.float64], data: Any) -> NDArray[np.float64]:
        return fk_start_poses(geometry, data.readings)

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
        """Setup values after new base (``p' = R_b p + t_b``) and platform coordinates."""
        frame = transform_frame(setup[:6], base, euler)
        return np.concatenate([frame, self.platform_setup(setup[6:], platform, euler)])


class TargetModel(FramedModel):
    """Target positions in the instrument frame: ``3 n`` values per pose, any subset present.

    Setup parameters: the instrument frame (6), then the targets (``3 n``), see
    :mod:`hexcal.instruments.setup`.
    """

    name = "targets"
    measures_pose = False

    def __init__(self, setup: Setup | None = None) -> None:
        self.setup = Setup(None, {"t1": np.zeros(3)}) if setup is None else setup
        if self.setup.kind != "targets":
            raise UsageError("the target model needs a setup with targets")
        self.n_targets = len(self.setup.targets)
        self.size = 3 * self.n_targets

    def parameters(self) -> ParameterSet:
        return self.setup.parameters()

    def observed(self, data: TargetMeasurements) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        if tuple(data.names) != self.setup.target_names:
            raise UsageError(f"the data have targets {data.names}, the setup {self.setup.target_names}")
        present = np.repeat(data.seen, 3, axis=1)
        return np.nan_to_num(data.targets.reshape(len(data), -1)), present

    def _points(self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str) -> tuple:
        rot_f, t_f = frame_transform(setup[:6], euler)
        q = setup[6:].reshape(-1, 3)
        rot_p, pos = pose_frames(poses, euler)
        rq = np.einsum("mjk,ik->mij", rot_p, q)  # (m, n, 3)
        return rot_f, t_f, q, rot_p, rq, pos[:, None, :] + rq

    def predict(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        rot_f, t_f, _, _, _, p = self._points(setup, poses, euler)
        return (p @ rot_f.T + t_f).reshape(len(poses), -1)

    def pose_jacobian(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        rot_f, _, _, _, rq, _ = self._points(setup, poses, euler)
        m, n = rq.shape[:2]
        axes = euler_axes(poses[:, 3:], euler)  # (m, 3, 3) rows w_k
        jac = np.empty((m, n, 3, 6))
        jac[..., :3] = rot_f
        jac[..., 3:] = np.einsum("ab,mnbk->mnak", rot_f, cross_axes(axes[:, None], rq))
        return jac.reshape(m, 3 * n, 6)

    def setup_jacobian(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        rot_f, _, _, rot_p, _, p = self._points(setup, poses, euler)
        m, n = p.shape[:2]
        axes_f = euler_axes(setup[3:6], euler)
        jac = np.zeros((m, n, 3, 6 + 3 * n))
        jac[..., :3] = np.eye(3)
        jac[..., 3:6] = cross_axes(axes_f, p @ rot_f.T)
        rr = np.einsum("ab,mbc->mac", rot_f, rot_p)  # d y_i / d q_i
        for i in range(n):  # loop over targets, not poses
            jac[:, i, :, 6 + 3 * i : 9 + 3 * i] = rr
        return jac.reshape(m, 3 * n, -1)

    def covariance(self, noise: NoiseModel) -> NDArray[np.float64]:
        return noise.sigmas[1] ** 2 * np.eye(self.size)

    def platform_setup(
        self, values: NDArray[np.float64], platform: tuple[NDArray, NDArray], euler: str
    ) -> NDArray[np.float64]:
        rp, tp = platform
        return (values.reshape(-1, 3) @ rp.T + tp).ravel()
