"""Frame registration: a start for an unknown instrument frame (``instrument_frame: auto``).

The nominal machine predicts, from each pose's leg readings (forward kinematics), where the
targets (or the tool frame) are in the base frame; the instrument measured them in its own
frame. The best-fit rigid transform between the two point sets (Kabsch; the rotation from
:meth:`scipy.spatial.transform.Rotation.align_vectors`) is the frame's start value, and the
RMS distance left over says how well the nominal machine and setup explain the data
(millimetres, for a machine and targets known to millimetres).

>>> import numpy as np
>>> pts = np.array([[0., 0, 0], [100, 0, 0], [0, 100, 0], [0, 0, 100]])
>>> frame, res = rigid_fit(pts + [1000, 0, 0], pts, "XYZ")
>>> (np.round(frame, 6) + 0.0).tolist(), round(res, 9)
([1000.0, 0.0, 0.0, 0.0, 0.0, 0.0], 0.0)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.geometry import Geometry
from hexcal.errors import IdentificationError
from hexcal.instruments.legs import pose_frames
from hexcal.instruments.setup import Setup, frame_transform, matrix_to_euler
from hexcal.instruments.targets import fk_start_poses

#: Length of the tool axes added as points when a pose instrument is registered (mm).
TOOL_AXIS_LENGTH = 100.0


@dataclass(frozen=True)
class Registration:
    """A registered instrument frame.

    Attributes
    ----------
    frame : ndarray, shape (6,)
        The base frame's pose in the instrument frame (mm, rad).
    rms : float
        RMS distance between measured and transformed predicted points, mm.
    max : float
        Largest such distance, mm.
    points : int
        Number of point pairs used.
    """

    frame: NDArray[np.float64]
    rms: float
    max: float
    points: int

    def describe(self) -> str:
        return (
            f"instrument frame registered from {self.points} points: "
            f"residual RMS {self.rms:.3f} mm, max {self.max:.3f} mm"
        )


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


def register_frame(geometry: Geometry, setup: Setup, data: Any, euler: str | None = None) -> Registration:
    """Register the instrument frame from target or tool data with the nominal ``geometry``.

    Parameters
    ----------
    geometry : Geometry
        The nominal machine.
    setup : Setup
        Nominal targets or tool (the frame is ignored).
    data : TargetMeasurements or Measurements
        Target positions, or tool poses, in the instrument frame, with the leg readings.
    euler : str, optional
        Euler sequence (default the geometry's).
    """
    euler = euler or geometry.euler
    poses = fk_start_poses(geometry, data.readings)
    rot_p, pos = pose_frames(poses, euler)
    if setup.kind == "targets":
        predicted = pos[:, None, :] + np.einsum("mjk,ik->mij", rot_p, setup.target_array)
        seen = data.seen
        measured, predicted = data.targets[seen], predicted[seen]
    else:
        rot_t, t_t = frame_transform(setup.tool, euler)
        frames = rot_p @ rot_t
        origin = pos + rot_p @ t_t
        offsets = TOOL_AXIS_LENGTH * np.concatenate([np.zeros((1, 3)), np.eye(3)])
        predicted = (origin[:, None, :] + np.einsum("mjk,ik->mij", frames, offsets)).reshape(-1, 3)
        from hexcal.core.conventions import rotation_matrices

        obs = rotation_matrices(data.poses[:, 3:], euler)
        measured = (data.poses[:, None, :3] + np.einsum("mjk,ik->mij", obs, offsets)).reshape(-1, 3)
    frame, rms = rigid_fit(measured, predicted, euler)
    rot, t = frame_transform(frame, euler)
    dist = np.linalg.norm(measured - (predicted @ rot.T + t), axis=1)
    return Registration(frame, rms, float(dist.max()), len(measured))
