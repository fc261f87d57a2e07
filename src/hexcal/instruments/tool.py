"""Pose instruments: the pose of a tool (probe, marker) frame on the platform, in the
instrument's frame (6-DOF laser trackers, cameras, motion capture).

The tool ``T = (t_T, R_T)`` (platform frame) at the true platform pose ``(o, R_P)`` is seen at
position ``R_F (o + R_P t_T) + t_F`` and orientation ``R = R_F R_P R_T``. The data are read
like a full-pose measurement file (:class:`hexcal.instruments.pose.Measurements`), as the tool's
pose in the instrument frame. Noise: the pose noise of the
:class:`~hexcal.core.noise.NoiseModel` (``position`` per coordinate, ``orientation`` per Euler
angle, or the full ``pose_covariance``), as for the full-pose model.

The orientation residual is not the difference of Euler angles (which jumps by 2π where an
angle wraps): it is the rotation vector ``ω = log(R R_obsᵀ)`` from the measured to the
predicted orientation, expressed in Euler-angle increments at the measured orientation,
``δθ = W_obs⁻ᵀ ω`` (``W`` the rows of the rotation axes,
:func:`hexcal.core.conventions.euler_axes`). To first order it equals the Euler-angle
difference, so the pose noise applies unchanged; it is well defined at any angle away from
gimbal lock of the reported angles. ``ToolModel(setup, orientation="euler")`` uses the
difference of Euler angles instead (wrapped to ``(-π, π]``): with an identity frame and tool
it is exactly the full-pose model.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hexcal.core.conventions import euler_axes, rotation_matrices
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import ParameterSet
from hexcal.errors import UsageError
from hexcal.instruments.legs import pose_frames
from hexcal.instruments.pose import Measurements
from hexcal.instruments.setup import Setup, frame_transform, matrix_to_euler
from hexcal.instruments.targets import FramedModel, cross_axes


def rotation_vectors(matrices: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation vectors ``(..., 3)`` of rotation matrices ``(..., 3, 3)``."""
    from scipy.spatial.transform import Rotation  # deferred: slow to import

    batch = matrices.shape[:-2]
    return Rotation.from_matrix(matrices.reshape(-1, 3, 3)).as_rotvec().reshape(batch + (3,))


class ToolModel(FramedModel):
    """The tool frame's pose in the instrument frame: 6 values per pose.

    Setup parameters: the instrument frame (6), then the tool (6).

    >>> from hexcal.instruments.setup import Setup
    >>> model = ToolModel(Setup(np.zeros(6), tool=[0, 0, 60, 0, 0, 0]))
    >>> model.predict(model.setup.vector(), np.zeros((1, 6)), "XYZ").round(9) + 0.0
    array([[ 0.,  0., 60.,  0.,  0.,  0.]])
    """

    name = "tool"
    size = 6
    measures_pose = False

    def __init__(self, setup: Setup | None = None, orientation: str = "rotvec") -> None:
        self.setup = Setup(None, tool=np.zeros(6)) if setup is None else setup
        if self.setup.kind != "tool":
            raise UsageError("the tool model needs a setup with a tool")
        if orientation not in ("rotvec", "euler"):
            raise UsageError(f"orientation residual must be 'rotvec' or 'euler', got {orientation!r}")
        self.orientation = orientation

    def parameters(self) -> ParameterSet:
        return self.setup.parameters()

    def observed(self, data: Measurements) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        return data.poses, np.ones(data.poses.shape, dtype=bool)

    def _frames(self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str) -> tuple:
        rot_f, t_f = frame_transform(setup[:6], euler)
        rot_t, t_t = frame_transform(setup[6:12], euler)
        rot_p, pos = pose_frames(poses, euler)
        rt = np.einsum("mjk,k->mj", rot_p, t_t)
        point = pos + rt  # tool origin, base frame
        rot = np.einsum("ab,mbc,cd->mad", rot_f, rot_p, rot_t)
        return rot_f, t_f, rot_t, t_t, rot_p, rt, point, rot

    def predict(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        rot_f, t_f, *_, point, rot = self._frames(setup, poses, euler)
        return np.concatenate([point @ rot_f.T + t_f, matrix_to_euler(rot, euler)], axis=1)

    def residual(
        self,
        setup: NDArray[np.float64],
        poses: NDArray[np.float64],
        euler: str,
        observed: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """Position difference and rotation-vector orientation residual ``(m, 6)`` (see module)."""
        rot_f, t_f, *_, point, rot = self._frames(setup, poses, euler)
        if self.orientation == "euler":
            diff = matrix_to_euler(rot, euler) - observed[:, 3:]
            angular = (diff + np.pi) % (2 * np.pi) - np.pi
            return np.concatenate([point @ rot_f.T + t_f - observed[:, :3], angular], axis=1)
        rot_obs = rotation_matrices(observed[:, 3:], euler)
        omega = rotation_vectors(rot @ rot_obs.transpose(0, 2, 1))
        w_obs = euler_axes(observed[:, 3:], euler)
        angular = np.linalg.solve(w_obs.transpose(0, 2, 1), omega[..., None])[..., 0]
        return np.concatenate([point @ rot_f.T + t_f - observed[:, :3], angular], axis=1)

    def _angular(self, rot: NDArray[np.float64], euler: str, phi: NDArray[np.float64]) -> NDArray[np.float64]:
        """Euler-angle increments ``W⁻ᵀ φ`` at the predicted orientation for rotations
        ``φ (m, 3, k)`` (instrument frame)."""
        w = euler_axes(matrix_to_euler(rot, euler), euler)
        return np.linalg.solve(w.transpose(0, 2, 1), phi)

    def pose_jacobian(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        rot_f, _, _, _, _, rt, _, rot = self._frames(setup, poses, euler)
        axes = euler_axes(poses[:, 3:], euler)
        jac = np.zeros((len(poses), 6, 6))
        jac[:, :3, :3] = rot_f
        jac[:, :3, 3:] = rot_f @ cross_axes(axes, rt)
        jac[:, 3:, 3:] = self._angular(rot, euler, rot_f @ axes.transpose(0, 2, 1))
        return jac

    def setup_jacobian(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        rot_f, _, _, _, rot_p, _, point, rot = self._frames(setup, poses, euler)
        m = len(poses)
        axes_f = euler_axes(setup[3:6], euler)
        axes_t = euler_axes(setup[9:12], euler)
        jac = np.zeros((m, 6, 12))
        jac[:, :3, :3] = np.eye(3)
        jac[:, :3, 3:6] = cross_axes(axes_f, point @ rot_f.T)
        rr = np.einsum("ab,mbc->mac", rot_f, rot_p)
        jac[:, :3, 6:9] = rr
        phi = np.concatenate([np.broadcast_to(axes_f.T, (m, 3, 3)), rr @ axes_t.T], axis=2)
        ang = self._angular(rot, euler, phi)
        jac[:, 3:, 3:6], jac[:, 3:, 9:12] = ang[..., :3], ang[..., 3:]
        return jac

    def covariance(self, noise: NoiseModel) -> NDArray[np.float64]:
        return noise.pose_cov()

    def platform_setup(
        self, values: NDArray[np.float64], platform: tuple[NDArray, NDArray], euler: str
    ) -> NDArray[np.float64]:
        rp, tp = platform
        rot_t, t_t = frame_transform(values[:6], euler)
        return np.concatenate([rp @ t_t + tp, matrix_to_euler(rp @ rot_t, euler)])
