"""The machine's leg equations, shared by every instrument: residuals and their Jacobians.

Leg ``i`` at a platform pose ``(o, R)`` has the length ``|o + R s_i - u_i|``; the controller's
reading ``dl_i`` says it is ``f(θ_i, dl_i)`` through the leg model (:mod:`hexcal.core.legs`;
``l0_i + g_i dl_i`` for linear legs). Their difference is the leg residual (``"length"``, mm);
the seed paper's cost (Agheli & Nategh 2009, eq. 3, after Zhuang et al. 1998) uses the
difference of squares ``|v|² - f²`` (``"paper"``, mm²).

The functions take the machine's two blocks by name: ``joints`` (36 values, base joints
then platform joints) and ``legs`` (the leg model's block), and poses as rotation matrices
and positions; they return residuals ``(m, 6)`` and the Jacobian ``(m, 6, 36 + p)`` with
respect to the joints and the leg block, in that order.

>>> from hexcal.core.presets import preset
>>> machine = preset("paper-hmt")
>>> rot, pos = pose_frames(machine.home_pose[None], machine.euler)
>>> readings = np.zeros((1, 6)) + 800 - 604.8652
>>> r = leg_residuals(machine.joint_block(), machine.leg_block(), machine.leg_model, rot, pos, readings)
>>> r.shape
(1, 6)
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.conventions import as_poses, rotation_matrices
from hexcal.core.legs import LegModel
from hexcal.errors import UsageError

#: Residual variants of the leg equations.
VARIANTS = ("length", "paper")

#: Joint coordinates (36) of the machine's parameters.
N_JOINTS = 36

_LEG = np.arange(6)
_U_COLS = 3 * _LEG[:, None] + np.arange(3)
_S_COLS = 18 + _U_COLS


def check_variant(variant: str) -> str:
    """Return ``variant`` if it is one of :data:`VARIANTS`, else raise :class:`UsageError`."""
    if variant not in VARIANTS:
        raise UsageError(f"unknown method {variant!r}; choose from {', '.join(VARIANTS)}")
    return variant


def pose_frames(poses: ArrayLike, euler: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rotation matrices ``(..., 3, 3)`` and positions ``(..., 3)`` of poses ``(..., 6)``."""
    poses = as_poses(poses, "poses")
    return rotation_matrices(poses[..., 3:], euler), np.ascontiguousarray(poses[..., :3])


def leg_vectors_of(
    joints: NDArray[np.float64], rotations: NDArray[np.float64], positions: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Leg vectors ``o + R s_i - u_i`` ``(m, 6, 3)`` of a joint block and pose frames."""
    u, s = joints[:18].reshape(6, 3), joints[18:36].reshape(6, 3)
    rotated = np.einsum("mjk,ik->mij", rotations, s)
    return rotated + positions[:, None, :] - u


def leg_residuals(
    joints: NDArray[np.float64],
    legs: NDArray[np.float64],
    model: LegModel,
    rotations: NDArray[np.float64],
    positions: NDArray[np.float64],
    readings: NDArray[np.float64],
    variant: str = "length",
) -> NDArray[np.float64]:
    """Leg residuals of every pose and leg, shape ``(m, 6)`` (mm, or mm² for ``"paper"``)."""
    vectors = leg_vectors_of(joints, rotations, positions)
    sq = np.einsum("mik,mik->mi", vectors, vectors)
    lengths = model.lengths(legs, readings)
    if variant == "paper":
        return sq - lengths**2
    return np.sqrt(sq) - lengths


def leg_parameter_jacobian(
    joints: NDArray[np.float64],
    legs: NDArray[np.float64],
    model: LegModel,
    rotations: NDArray[np.float64],
    positions: NDArray[np.float64],
    readings: NDArray[np.float64],
    variant: str = "length",
) -> NDArray[np.float64]:
    """Jacobian of :func:`leg_residuals` with respect to the joints and the leg block,
    ``(m, 6, 36 + p)``."""
    vectors = leg_vectors_of(joints, rotations, positions)
    m = vectors.shape[0]
    lengths = model.lengths(legs, readings)
    if variant == "paper":
        d_leg = 2.0 * vectors  # d|v|²/dv
        d_model = -2.0 * lengths  # d(-f²)/df
    else:
        d_leg = vectors / np.sqrt(np.einsum("mik,mik->mi", vectors, vectors))[..., None]
        d_model = -np.ones_like(lengths)
    jac = np.zeros((m, 6, N_JOINTS + model.size))
    jac[:, _LEG[:, None], _U_COLS] = -d_leg
    # d v / d s_i = R_j, so d r / d s_i = (d r / d v) R_j
    jac[:, _LEG[:, None], _S_COLS] = np.einsum("mik,mkj->mij", d_leg, rotations)
    jac[..., N_JOINTS:] = d_model[..., None] * model.jacobian(legs, readings)
    return jac


def leg_columns(model: LegModel) -> NDArray[np.intp]:
    """Machine-parameter positions of each leg's own parameters ``(6, 6 + per_leg)``: its base
    joint, its platform joint, then its leg-model parameters (the legs' residuals are
    separable: leg ``i`` depends on these alone)."""
    return np.concatenate([_U_COLS, _S_COLS, N_JOINTS + model.index()], axis=1)
