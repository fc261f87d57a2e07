"""Pose instruments: the pose of a tool frame on the platform, in the instrument's frame.

6-DOF laser trackers, cameras and motion capture see a tool (probe, marker, rigid body)
``T = (t_T, R_T)`` (platform frame) at the true platform pose ``(o, R_P)`` at position
``R_F (o + R_P t_T) + t_F`` and orientation ``R = R_F R_P R_T`` in their frame ``F``. The data
are a measurement file (:class:`~hexcal.instruments.data.Measurements`) read as the tool's
pose in the instrument frame. Noise: the pose noise of the
:class:`~hexcal.core.noise.NoiseModel` (``position`` per coordinate, ``orientation`` per
Euler angle, or the full ``pose_covariance``).

The **full pose in the base frame** (:class:`FullPoseModel`: CMM or tracker software that
already reports the platform pose in the machine's frame, and simulated data) is this
instrument with the identity frame and tool, both fixed: the same class, not a separate
path. Its observation determines the platform pose, as does any pose instrument whose frame
and tool are both fixed (:attr:`ToolModel.determines_pose`).

The orientation residual is not the difference of Euler angles (which jumps by 2π where an
angle wraps): it is the rotation vector ``ω = log(R R_obsᵀ)`` from the measured to the
predicted orientation, expressed in Euler-angle increments at the measured orientation,
``δθ = W_obs⁻ᵀ ω`` (``W`` the rows of the rotation axes,
:func:`hexcal.core.conventions.euler_axes`). To first order it equals the Euler-angle
difference, so the pose noise applies unchanged; it is well defined at any angle away from
gimbal lock of the reported angles. With ``orientation="euler"`` the residual is the
difference of Euler angles wrapped to ``(-π, π]`` (the full-pose model's).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.conventions import euler_axes, rotation_and_axes, rotation_matrices
from hexcal.core.geometry import Geometry
from hexcal.core.noise import NoiseModel
from hexcal.errors import UsageError
from hexcal.instruments.data import Measurements
from hexcal.instruments.framed import FramedModel, cross_axes
from hexcal.instruments.registration import Registration, register_pose_instrument
from hexcal.instruments.setup import Setup, frame_transform, matrix_to_euler

#: Factors of the unit diagnoses: lengths in metres or inches read as millimetres.
LENGTH_UNITS = (("metres", 1000.0), ("inches", 25.4))


def rotation_vectors(matrices: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation vectors ``(..., 3)`` of rotation matrices ``(..., 3, 3)``."""
    from scipy.spatial.transform import Rotation  # deferred: slow to import

    batch = matrices.shape[:-2]
    return Rotation.from_matrix(matrices.reshape(-1, 3, 3)).as_rotvec().reshape(batch + (3,))


def _wrap(angles: NDArray[np.float64]) -> NDArray[np.float64]:
    return (angles + np.pi) % (2 * np.pi) - np.pi


class ToolModel(FramedModel):
    """The tool frame's pose in the instrument frame: 6 values per pose.

    Parameters: the instrument frame (6), then the tool (6), see
    :mod:`hexcal.instruments.setup`.

    >>> model = ToolModel(Setup(np.zeros(6), tool=[0, 0, 60, 0, 0, 0]))
    >>> model.predict(model.setup.vector(), np.zeros((1, 6)), "XYZ").round(9) + 0.0
    array([[ 0.,  0., 60.,  0.,  0.,  0.]])
    """

    name = "tool"
    size = 6

    def __init__(self, setup: Setup | None = None, orientation: str = "rotvec") -> None:
        self.setup = Setup(None, tool=np.zeros(6)) if setup is None else setup
        if self.setup.kind != "tool":
            raise UsageError("the tool model needs a setup with a tool")
        if orientation not in ("rotvec", "euler"):
            raise UsageError(f"orientation residual must be 'rotvec' or 'euler', got {orientation!r}")
        self.orientation = orientation
        fixed = {"instrument_frame", "tool"} <= set(self.setup.fixed)
        # frame and tool fixed at the identity: the instrument reads the platform pose itself
        self.identity = (
            fixed
            and self.setup.frame is not None
            and not np.any(self.setup.frame)
            and not np.any(self.setup.tool)
        )

    def options(self) -> dict[str, Any]:
        return {"orientation": self.orientation}

    def describe(self) -> str:
        if self.identity:
            return "full pose in the base frame"
        frame = f"frame {self.setup.frame_state}"
        return f"tool pose in the instrument frame ({frame})"

    def observed(self, data: Measurements) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        return data.poses, np.ones(data.poses.shape, dtype=bool)

    # The functions below are batch-first: ``setup`` (..., 12) and ``poses`` (..., m, 6) with
    # broadcasting batch shapes (one campaign: ``setup`` (12,), ``poses`` (m, 6)).
    def _frames(self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str) -> tuple:
        """The frame, the tool, the platform's and the tool's predicted frames and the platform's
        Euler axes (each rotation computed once: this is the pose solve's inner loop)."""
        setup = np.asarray(setup, dtype=float)
        both = rotation_matrices(np.stack([setup[..., 3:6], setup[..., 9:12]], axis=-2), euler)
        rot_f, rot_t = both[..., 0, :, :], both[..., 1, :, :]
        t_f, t_t = setup[..., :3].copy(), setup[..., 6:9].copy()
        poses = np.asarray(poses, dtype=float)
        rot_p, axes = rotation_and_axes(poses[..., 3:], euler)
        rt = np.einsum("...mjk,...k->...mj", rot_p, t_t)
        point = poses[..., :3] + rt  # tool origin, base frame
        rot = rot_f[..., None, :, :] @ rot_p @ rot_t[..., None, :, :]
        return rot_f, t_f, rot_t, t_t, rot_p, rt, point, rot, axes

    @staticmethod
    def _to_instrument(rot_f: NDArray, t_f: NDArray, point: NDArray) -> NDArray[np.float64]:
        """Base-frame points ``(..., m, 3)`` in instrument coordinates."""
        return np.einsum("...ij,...mj->...mi", rot_f, point) + t_f[..., None, :]

    def predict(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        if self.identity:
            return np.array(poses)
        rot_f, t_f, *_, point, rot, _ = self._frames(setup, poses, euler)
        return np.concatenate([self._to_instrument(rot_f, t_f, point), matrix_to_euler(rot, euler)], axis=-1)

    def residual(
        self,
        setup: NDArray[np.float64],
        poses: NDArray[np.float64],
        euler: str,
        observed: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """Position difference and orientation residual ``(..., m, 6)`` (see the module)."""
        if self.identity:
            diff = poses - observed
            if self.orientation == "euler":
                diff[..., 3:] = _wrap(diff[..., 3:])
                return diff
        return self._residual(self._frames(setup, poses, euler), euler, observed)

    def residual_and_pose_jacobian(
        self,
        setup: NDArray[np.float64],
        poses: NDArray[np.float64],
        euler: str,
        observed: NDArray[np.float64],
        whitener: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        if self.identity:
            return self.residual(setup, poses, euler, observed), self.whitened_pose_jacobian(
                setup, poses, euler, whitener
            )
        frames = self._frames(setup, poses, euler)  # once for both
        jac = np.matmul(whitener, self._pose_jacobian(frames, poses, euler))
        return self._residual(frames, euler, observed), jac

    def _residual(self, frames: tuple, euler: str, observed: NDArray[np.float64]) -> NDArray[np.float64]:
        rot_f, t_f, *_, point, rot, _ = frames
        position = self._to_instrument(rot_f, t_f, point) - observed[..., :3]
        if self.orientation == "euler":
            return np.concatenate([position, _wrap(matrix_to_euler(rot, euler) - observed[..., 3:])], axis=-1)
        rot_obs, w_obs = rotation_and_axes(observed[..., 3:], euler)
        omega = rotation_vectors(rot @ np.swapaxes(rot_obs, -1, -2))
        angular = np.linalg.solve(np.swapaxes(w_obs, -1, -2), omega[..., None])[..., 0]
        return np.concatenate([position, angular], axis=-1)

    def _angular(self, rot: NDArray[np.float64], euler: str, phi: NDArray[np.float64]) -> NDArray[np.float64]:
        """Euler-angle increments ``W⁻ᵀ φ`` at the predicted orientation for rotations
        ``φ (..., m, 3, k)`` (instrument frame)."""
        w = euler_axes(matrix_to_euler(rot, euler), euler)
        return np.linalg.solve(np.swapaxes(w, -1, -2), phi)

    def pose_jacobian(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        if self.identity:
            return np.broadcast_to(np.eye(6), (*np.shape(poses)[:-1], 6, 6))
        return self._pose_jacobian(self._frames(setup, poses, euler), poses, euler)

    def _pose_jacobian(self, frames: tuple, poses: NDArray[np.float64], euler: str) -> NDArray[np.float64]:
        rot_f, _, _, _, _, rt, _, rot, axes = frames
        rf = rot_f[..., None, :, :]
        jac = np.zeros((*rot.shape[:-2], 6, 6))
        jac[..., :3, :3] = rf
        jac[..., :3, 3:] = rf @ cross_axes(axes, rt)
        jac[..., 3:, 3:] = self._angular(rot, euler, rf @ np.swapaxes(axes, -1, -2))
        return jac

    def whitened_pose_jacobian(
        self,
        setup: NDArray[np.float64],
        poses: NDArray[np.float64],
        euler: str,
        whitener: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        if self.identity:
            return np.broadcast_to(whitener, (*np.shape(poses)[:-1], 6, 6))
        return np.matmul(whitener, self.pose_jacobian(setup, poses, euler))

    def setup_jacobian(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        rot_f, t_f, _, _, rot_p, _, point, rot, _ = self._frames(setup, poses, euler)
        lead = rot.shape[:-2]
        axes_f = euler_axes(setup[..., 3:6], euler)[..., None, :, :]  # (..., 1, 3, 3)
        axes_t = euler_axes(setup[..., 9:12], euler)[..., None, :, :]
        jac = np.zeros((*lead, 6, 12))
        jac[..., :3, :3] = np.eye(3)
        jac[..., :3, 3:6] = cross_axes(axes_f, self._to_instrument(rot_f, t_f, point) - t_f[..., None, :])
        rr = rot_f[..., None, :, :] @ rot_p
        jac[..., :3, 6:9] = rr
        phi = np.concatenate(
            [np.broadcast_to(np.swapaxes(axes_f, -1, -2), (*lead, 3, 3)), rr @ np.swapaxes(axes_t, -1, -2)],
            axis=-1,
        )
        ang = self._angular(rot, euler, phi)
        jac[..., 3:, 3:6], jac[..., 3:, 9:12] = ang[..., :3], ang[..., 3:]
        return jac

    def covariance(self, noise: NoiseModel) -> NDArray[np.float64]:
        return noise.pose_cov()

    def start_poses(
        self, geometry: Geometry, setup: NDArray[np.float64], data: Measurements
    ) -> NDArray[np.float64]:
        if self.determines_pose:
            return self.platform_poses(setup, data, geometry.euler)
        return super().start_poses(geometry, setup, data)

    def platform_setup(
        self, values: NDArray[np.float64], platform: tuple[NDArray, NDArray], euler: str
    ) -> NDArray[np.float64]:
        rp, tp = platform
        rot_t, t_t = frame_transform(values[..., :6], euler)
        moved = np.einsum("...ij,...j->...i", rp, t_t) + tp
        return np.concatenate([moved, matrix_to_euler(rp @ rot_t, euler)], axis=-1)

    def register(self, geometry: Geometry, data: Measurements) -> tuple[Any, Registration | None]:
        if not self.setup.auto:
            return self, None
        reg = register_pose_instrument(geometry, self.setup, data)
        return self.with_values(np.concatenate([reg.frame, reg.tool])), reg

    @property
    def constant_pose_jacobian(self) -> bool:
        return bool(self.identity)

    # -- the pose itself ----------------------------------------------------------------
    @property
    def determines_pose(self) -> bool:
        return {"instrument_frame", "tool"} <= set(self.setup.fixed) and self.setup.frame is not None

    def platform_poses(self, setup: NDArray[np.float64], data: Any, euler: str) -> NDArray[np.float64]:
        """Platform poses of measured tool poses: ``P = F⁻¹ M T⁻¹`` (frame and tool fixed)."""
        if not self.determines_pose:
            return super().platform_poses(setup, data, euler)
        return self.platform_from(setup, data.poses, euler)

    def platform_from(
        self, setup: NDArray[np.float64], measured: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        """``P = F⁻¹ M T⁻¹`` of measured tool poses ``(..., m, 6)`` (batch-first)."""
        if self.identity:
            return np.array(measured)
        rot_f, t_f = frame_transform(setup[..., :6], euler)
        rot_t, t_t = frame_transform(setup[..., 6:12], euler)
        rot_m = rotation_matrices(measured[..., 3:], euler)
        rot_p = (
            np.swapaxes(rot_f, -1, -2)[..., None, :, :] @ rot_m @ np.swapaxes(rot_t, -1, -2)[..., None, :, :]
        )
        origin = np.einsum("...mi,...ij->...mj", measured[..., :3] - t_f[..., None, :], rot_f)  # base frame
        position = origin - np.einsum("...mij,...j->...mi", rot_p, t_t)
        return np.concatenate([position, matrix_to_euler(rot_p, euler)], axis=-1)

    def platform_covariance(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], noise: NoiseModel, euler: str
    ) -> NDArray[np.float64]:
        if self.identity:
            return np.broadcast_to(noise.pose_cov(), (*np.shape(poses)[:-1], 6, 6))
        return super().platform_covariance(setup, poses, noise, euler)

    # -- simulation and diagnoses -------------------------------------------------------
    def simulate(
        self,
        setup: NDArray[np.float64],
        poses: NDArray[np.float64],
        readings: NDArray[np.float64],
        euler: str,
        noise: NoiseModel | None,
        rng: np.random.Generator,
        ids: tuple[str, ...] = (),
        missing_rate: float = 0.0,
    ) -> Measurements:
        if missing_rate:
            raise UsageError(f"a missing rate applies to targets; the {self.describe()} records whole poses")
        values = self.predict(setup, poses, euler)
        if noise is not None:
            values = values + noise.pose_errors(rng, (len(values),))
        return Measurements(values, readings, ids)

    @property
    def has_angles(self) -> bool:
        return True

    def variants(self, data: Measurements) -> tuple[tuple[str, str, Any], ...]:
        out = []
        for unit, factor in LENGTH_UNITS:
            poses = np.array(data.poses)
            poses[:, :3] *= factor
            out.append((f"length-units-{unit}", f"the positions look like {unit}", data.replace(poses=poses)))
        angles = np.abs(np.asarray(data.poses)[:, 3:])
        for code, factor, text in (
            ("radians", np.pi / 180, "the angles look like degrees in radian columns"),
            ("degrees", 180 / np.pi, "the angles look like radians in degree columns (a_deg)"),
        ):
            if code == "degrees" and np.max(angles, initial=0.0) * 180 / np.pi > np.pi:
                continue  # read as degrees, these angles would pass a half turn
            if code == "radians" and np.max(angles, initial=0.0) <= np.pi / 2:
                # no angle beyond a quarter turn (the reader's own test for degrees): read as
                # degrees they would leave the platform all but unrotated, a re-reading that
                # "explains" any misfit of the orientations (a wrong Euler sequence) by
                # dropping them
                continue
            poses = np.array(data.poses)
            poses[:, 3:] *= factor
            out.append((f"angle-units-{code}", text, data.replace(poses=poses)))
        return tuple(out)

    def errors(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], data: Measurements, euler: str
    ) -> dict[str, NDArray[np.float64]]:
        """Position (mm) and orientation (rad, rotation angle) error of each predicted pose."""
        from hexcal.core.conventions import orientation_error

        predicted = self.predict(setup, poses, euler)
        position = np.linalg.norm(predicted[:, :3] - data.poses[:, :3], axis=1)
        return {
            "position": position,
            "orientation": orientation_error(predicted[:, 3:], data.poses[:, 3:], euler),
        }


class FullPoseModel(ToolModel):
    """The platform pose measured in the base frame: the pose instrument with the identity
    frame and tool, both fixed (``h(P) = P``; orientation residual the wrapped Euler-angle
    difference).

    >>> model = FullPoseModel()
    >>> model.predict(model.setup.vector(), np.zeros((2, 6)), "XYZ").shape
    (2, 6)
    >>> model.determines_pose, model.parameters().n_free
    (True, 0)
    """

    name = "pose"

    def __init__(self, setup: Setup | None = None, orientation: str = "euler") -> None:
        identity = Setup(np.zeros(6), tool=np.zeros(6), fixed=("instrument_frame", "tool"))
        super().__init__(identity if setup is None else setup, orientation)

    def options(self) -> dict[str, Any]:
        return {}

    def after_step(self) -> ToolModel:
        """The platform pose in an instrument frame of its own, unknown (the measuring system
        moved): a tool instrument with the identity tool, fixed, and the frame ``auto``."""
        return ToolModel(replace(self.setup, frame=None, fixed=("tool",), calibration=None), "euler")
