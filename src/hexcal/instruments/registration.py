"""Registration: a start for an unknown instrument frame (``instrument_frame: auto``).

The nominal machine predicts, from each pose's leg readings (forward kinematics), where the
platform is in the base frame; the instrument measured targets (or a tool frame) in its own
frame. Registration finds the frame that best maps the one onto the other:

- **targets**: the best-fit rigid transform between the measured and the predicted target
  positions (Kabsch; the rotation from
  :meth:`scipy.spatial.transform.Rotation.align_vectors`);
- **a tool** (pose instruments): ``R_F R_P R_T = R_M`` and ``R_F (o + R_P t_T) + t_F = m`` at
  every pose, with the frame ``F`` and, when the tool is free, the tool ``T`` unknown (the
  robot-world/hand-eye problem): the rotations by alternating orthogonal Procrustes fits of
  ``R_F`` and ``R_T`` (each a closed-form SVD step that cannot increase the misfit), then the
  translations by linear least squares. Any frame rotation and distance is found; a start
  that does not depend on the tool being known.

The RMS distance left over says how well the nominal machine and setup explain the data
(millimetres, for a machine known to millimetres; a far larger value means the design or
the leg readings' scale is far from the real machine).

>>> import numpy as np
>>> pts = np.array([[0., 0, 0], [100, 0, 0], [0, 100, 0], [0, 0, 100]])
>>> frame, res = rigid_fit(pts + [1000, 0, 0], pts, "XYZ")
>>> (np.round(frame, 6) + 0.0).tolist(), round(res, 9)
([1000.0, 0.0, 0.0, 0.0, 0.0, 0.0], 0.0)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.conventions import rotation_matrices
from hexcal.core.geometry import Geometry
from hexcal.core.machine import pose_frames
from hexcal.errors import IdentificationError
from hexcal.instruments.framed import fk_start_poses
from hexcal.instruments.setup import Setup, frame_transform, matrix_to_euler

#: Alternations of the rotation fit, and the change (rad) at which it stops.
_ROTATION_ROUNDS, _ROTATION_TOL = 200, 1e-13


@dataclass(frozen=True)
class Registration:
    """A registered instrument frame (and tool).

    Attributes
    ----------
    frame : ndarray, shape (6,)
        The base frame's pose in the instrument frame (mm, rad).
    rms : float
        RMS distance between measured and transformed predicted points (mm).
    max : float
        Largest such distance (mm).
    points : int
        Number of point pairs (or poses) used.
    tool : ndarray, shape (6,), optional
        The registered tool (pose instruments).
    angle_rms : float
        RMS rotation angle between measured and predicted orientations (rad; pose instruments).
    """

    frame: NDArray[np.float64]
    rms: float
    max: float
    points: int
    tool: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    angle_rms: float = float("nan")

    def describe(self) -> str:
        what = f"{self.points} poses" if self.tool.size else f"{self.points} points"
        angle = f", orientation RMS {self.angle_rms:.3g} rad" if np.isfinite(self.angle_rms) else ""
        return (
            f"instrument frame registered from {what}: residual RMS {self.rms:.3f} mm, "
            f"max {self.max:.3f} mm{angle}"
        )

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "frame": self.frame.tolist(),
            "rms_mm": self.rms,
            "max_mm": self.max,
            "points": self.points,
        }
        if self.tool.size:
            out["tool"] = self.tool.tolist()
            out["angle_rms_rad"] = self.angle_rms
        return out


def _procrustes(m: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rotation closest to ``m`` (3, 3) in the Frobenius norm."""
    u, _, vt = np.linalg.svd(m)
    d = np.sign(np.linalg.det(u @ vt)) or 1.0
    return u @ np.diag([1.0, 1.0, d]) @ vt


def rigid_fit(measured: ArrayLike, predicted: ArrayLike, euler: str) -> tuple[NDArray[np.float64], float]:
    """Frame ``(6,)`` with ``measured ≈ R predicted + t`` (least squares), and the RMS residual (mm)."""
    from scipy.spatial.transform import Rotation  # deferred: slow to import

    a, b = np.asarray(measured, dtype=float), np.asarray(predicted, dtype=float)
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    spread = np.linalg.svd(b - cb, compute_uv=False)
    if len(b) < 3 or spread[1] <= 1e-9 * max(spread[0], 1e-300):
        raise IdentificationError(
            "cannot register the instrument frame: the measured points lie on a line "
            "(measure more varied poses)"
        )
    rot, _ = Rotation.align_vectors(a - ca, b - cb)
    mat = rot.as_matrix()
    frame = np.concatenate([ca - mat @ cb, matrix_to_euler(mat, euler)])
    res = a - (b @ mat.T + frame[:3])
    return frame, float(np.sqrt(np.mean(np.sum(res**2, axis=1))))


def register_targets(geometry: Geometry, setup: Setup, data: Any) -> Registration:
    """Register the instrument frame from target positions with the nominal ``geometry``
    and the setup's nominal targets."""
    euler = geometry.euler
    poses = fk_start_poses(geometry, data.readings)
    rot_p, pos = pose_frames(poses, euler)
    predicted = pos[:, None, :] + np.einsum("mjk,ik->mij", rot_p, setup.target_array)
    seen = data.seen
    measured, predicted = data.targets[seen], predicted[seen]
    frame, rms = rigid_fit(measured, predicted, euler)
    rot, t = frame_transform(frame, euler)
    dist = np.linalg.norm(measured - (predicted @ rot.T + t), axis=1)
    return Registration(frame, rms, float(dist.max()), len(measured))


def register_pose_instrument(geometry: Geometry, setup: Setup, data: Any) -> Registration:
    """Register the frame (and the tool, unless the setup fixes it) from tool poses with the
    nominal ``geometry`` (see the module: alternating Procrustes, then linear least squares)."""
    euler = geometry.euler
    poses = fk_start_poses(geometry, data.readings)
    rot_p, pos = pose_frames(poses, euler)
    rot_m = rotation_matrices(data.poses[:, 3:], euler)
    m_pos = data.poses[:, :3]
    free_tool = "tool" not in setup.fixed
    rot_t, t_t = frame_transform(setup.tool, euler)
    if len(poses) < 3:
        raise IdentificationError("cannot register the instrument frame from fewer than 3 poses")
    rot_f = np.eye(3)
    for _ in range(_ROTATION_ROUNDS):
        # R_F = argmax tr(R_Fᵀ Σ R_M (R_P R_T)ᵀ); then R_T = argmax tr(R_Tᵀ Σ (R_F R_P)ᵀ R_M)
        new_f = _procrustes(np.einsum("mij,mkj->ik", rot_m, rot_p @ rot_t))
        new_t = rot_t
        if free_tool:
            new_t = _procrustes(np.einsum("mji,mjk->ik", np.einsum("ab,mbc->mac", new_f, rot_p), rot_m))
        change = max(np.abs(new_f - rot_f).max(), np.abs(new_t - rot_t).max())
        rot_f, rot_t = new_f, new_t
        if change < _ROTATION_TOL:
            break
    rr = np.einsum("ab,mbc->mac", rot_f, rot_p)  # R_F R_P, (m, 3, 3)
    rhs = m_pos - pos @ rot_f.T
    if free_tool:
        # [R_F R_P | I] [t_T; t_F] = m - R_F o, stacked over the poses
        a = np.concatenate([rr, np.broadcast_to(np.eye(3), rr.shape)], axis=2).reshape(-1, 6)
        sol, *_ = np.linalg.lstsq(a, rhs.ravel(), rcond=None)
        t_t, t_f = sol[:3], sol[3:]
    else:
        t_f = np.mean(rhs - rr @ t_t, axis=0)
    predicted = pos @ rot_f.T + rr @ t_t + t_f
    dist = np.linalg.norm(m_pos - predicted, axis=1)
    rot_pred = rr @ rot_t
    cos = (np.einsum("mij,mij->m", rot_pred, rot_m) - 1.0) / 2.0
    angles = np.arccos(np.clip(cos, -1.0, 1.0))
    frame = np.concatenate([t_f, matrix_to_euler(rot_f, euler)])
    tool = np.concatenate([t_t, matrix_to_euler(rot_t, euler)])
    rms = float(np.sqrt(np.mean(dist**2)))
    return Registration(frame, rms, float(dist.max()), len(poses), tool, float(np.sqrt(np.mean(angles**2))))
