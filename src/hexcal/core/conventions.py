"""Conventions shared by all of hexcal, defined once (docs/formats.md "Conventions").

- Lengths are millimetres.
- A pose is ``(x, y, z, a, b, c)``: the platform origin in the base frame and
  three Euler angles in radians.
- The rotation is ``scipy.spatial.transform.Rotation.from_euler(euler, [a, b, c])``
  with the default sequence ``"XYZ"`` (intrinsic, ``R = Rx(a) @ Ry(b) @ Rz(c)``).
  Any other scipy sequence may be chosen per geometry.
- Degrees and quaternions exist only at the I/O edge (:mod:`hexcal.io`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

DEFAULT_EULER = "XYZ"
POSE_NAMES = ("x", "y", "z", "a", "b", "c")
N_LEGS = 6


def check_euler(euler: str) -> str:
    """Return ``euler`` if it is a valid scipy Euler sequence, else raise ``ValueError``."""
    if not isinstance(euler, str) or len(euler) != 3:
        raise ValueError(f"Euler sequence must be 3 characters, got {euler!r}")
    if not (set(euler) <= set("xyz") or set(euler) <= set("XYZ")):
        raise ValueError(f"Euler sequence {euler!r} must use only xyz (extrinsic) or only XYZ (intrinsic)")
    if euler[0] == euler[1] or euler[1] == euler[2]:
        raise ValueError(f"Euler sequence {euler!r} repeats an axis in consecutive positions")
    return euler


def as_poses(poses: ArrayLike, name: str = "poses") -> NDArray[np.float64]:
    """Convert to a float array of shape ``(..., 6)``, raising ``ValueError`` otherwise."""
    arr = np.asarray(poses, dtype=float)
    if arr.ndim < 1 or arr.shape[-1] != 6:
        raise ValueError(f"{name} must have shape (..., 6), got {arr.shape}")
    return arr


def _rotate_columns(m: NDArray[np.float64], axis: str, angle: NDArray[np.float64]) -> None:
    """In place ``m <- m @ E(axis, angle)`` for matrices laid out as ``(3, 3, N)``."""
    k = "xyz".index(axis.lower())
    i, j = (k + 1) % 3, (k + 2) % 3
    c, s = np.cos(angle), np.sin(angle)
    col_i, col_j = m[:, i].copy(), m[:, j]
    m[:, i] = c * col_i + s * col_j
    m[:, j] = c * col_j - s * col_i


def _identity_t(n: int) -> NDArray[np.float64]:
    m = np.zeros((3, 3, n))
    m[0, 0] = m[1, 1] = m[2, 2] = 1.0
    return m


def rotation_and_axes_t(
    angles_t: NDArray[np.float64], euler: str = DEFAULT_EULER, axes: bool = True
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """Rotation matrices and the world axes of the elementary rotations, in one pass.

    Layout ``(3, 3, N)`` from angles ``(3, N)``; ``axes[k]`` is the base-frame axis
    ``w_k`` of :func:`euler_axes` (component, N). Both orders are built by
    right-multiplying elementary rotations: ``E_a E_b E_c`` (intrinsic) or ``E_c E_b E_a``
    (extrinsic); before each factor the current matrix's column of that factor's axis
    is the factor's world axis.
    """
    n = angles_t.shape[1]
    m = _identity_t(n)
    out = np.empty((3, 3, n)) if axes else None
    order = (0, 1, 2) if euler.isupper() else (2, 1, 0)
    for k in order:
        if out is not None:
            out[k] = m[:, "xyz".index(euler[k].lower())]
        _rotate_columns(m, euler[k], angles_t[k])
    return m, out


def rotation_matrices_t(angles_t: NDArray[np.float64], euler: str = DEFAULT_EULER) -> NDArray[np.float64]:
    """Rotation matrices in the transposed layout ``(3, 3, N)`` from angles ``(3, N)``.

    The hot-path form of :func:`rotation_matrices`: each matrix entry is a contiguous
    array, and each elementary rotation touches only the two columns it mixes.
    """
    return rotation_and_axes_t(angles_t, euler, axes=False)[0]


def rotation_matrices(angles: ArrayLike, euler: str = DEFAULT_EULER) -> NDArray[np.float64]:
    """Rotation matrices of Euler angles.

    Equal to ``Rotation.from_euler(euler, angles).as_matrix()`` (tested for every
    sequence), but computed with elementwise numpy arithmetic: scipy builds a
    quaternion per pose first, which is about ten times slower for the millions of
    poses of a workspace scan.

    Parameters
    ----------
    angles : array_like, shape (..., 3)
        Euler angles ``(a, b, c)`` in radians.
    euler : str
        scipy Euler sequence.

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    check_euler(euler)
    angles = np.asarray(angles, dtype=float)
    if angles.shape[-1:] != (3,):
        raise ValueError(f"angles must have shape (..., 3), got {angles.shape}")
    batch = angles.shape[:-1]
    flat_t = angles.reshape(-1, 3).T
    return np.moveaxis(rotation_matrices_t(flat_t, euler), -1, 0).reshape(batch + (3, 3))


def rotation_and_axes(angles: ArrayLike, euler: str = DEFAULT_EULER) -> tuple[NDArray, NDArray]:
    """:func:`rotation_matrices` and :func:`euler_axes` of the same angles ``(..., 3)`` in one
    pass: ``(rotations (..., 3, 3), axes (..., 3, 3))``, each equal to its function's."""
    check_euler(euler)
    angles = np.asarray(angles, dtype=float)
    batch = angles.shape[:-1]
    rot, out = rotation_and_axes_t(angles.reshape(-1, 3).T, euler)
    return np.moveaxis(rot, -1, 0).reshape(batch + (3, 3)), np.moveaxis(out, -1, 0).reshape(batch + (3, 3))


def euler_axes(angles: ArrayLike, euler: str = DEFAULT_EULER) -> NDArray[np.float64]:
    """World-frame axes of the three elementary rotations.

    With ``R(a, b, c)`` the rotation of ``angles``, ``dR/dθ_k = [w_k]× R`` where
    ``w_k`` is returned in ``[..., k, :]``. For an intrinsic sequence ``R = R1 R2 R3``
    this gives ``w_1 = e1, w_2 = R1 e2, w_3 = R1 R2 e3``; for an extrinsic one
    ``R = R3 R2 R1`` it gives ``w_3 = e3, w_2 = R3 e2, w_1 = R3 R2 e1``.

    Parameters
    ----------
    angles : array_like, shape (..., 3)
    euler : str

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Row ``k`` is the unit axis ``w_k`` in the base frame.
    """
    check_euler(euler)
    angles = np.asarray(angles, dtype=float)
    batch = angles.shape[:-1]
    flat_t = angles.reshape(-1, 3).T
    _, out = rotation_and_axes_t(flat_t, euler)
    return np.moveaxis(out, -1, 0).reshape(batch + (3, 3))


def orientation_error(
    angles_a: ArrayLike, angles_b: ArrayLike, euler: str = DEFAULT_EULER
) -> NDArray[np.float64]:
    """Angle (rad) of the rotation between two orientations, shape ``(...)``."""
    from scipy.spatial.transform import Rotation  # deferred: scipy.spatial is slow to import

    ra = rotation_matrices(angles_a, euler)
    rb = rotation_matrices(angles_b, euler)
    rel = np.einsum("...ji,...jk->...ik", ra, rb)
    batch = rel.shape[:-2]
    if rel.reshape(-1, 3, 3).shape[0] == 0:
        return np.empty(batch)
    return np.linalg.norm(Rotation.from_matrix(rel.reshape(-1, 3, 3)).as_rotvec(), axis=-1).reshape(batch)
