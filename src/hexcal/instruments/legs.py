"""The leg equations that every measurement model shares.

Leg ``i`` at a platform pose ``(o, R)`` has the length ``|o + R s_i - u_i|``; the controller's
reading ``dl_i`` says it is ``l0_i + g_i dl_i``. Their difference is the leg residual
(``"length"``, mm); the seed paper's cost (Agheli & Nategh 2009, eq. 3, after Zhuang et al.
1998) uses the difference of squares ``|v|² - (l0 + g dl)²`` (``"paper"``, mm²).

Functions here take the 48 machine parameter values (order of
:data:`hexcal.core.parameters.PARAMETER_NAMES`) and poses as rotation matrices and
positions, and return residuals ``(m, 6)`` and their Jacobian ``(m, 6, 48)`` with respect to
the machine parameters. Imports :mod:`hexcal.core`.

>>> from hexcal.core.presets import preset
>>> machine = preset("paper-hmt")
>>> rot, pos = pose_frames(machine.home_pose[None], machine.euler)
>>> readings = np.zeros((1, 6)) + 800 - 604.8652
>>> leg_residuals(machine.to_vector(gains=True), rot, pos, readings).shape
(1, 6)
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.conventions import as_poses, rotation_matrices
from hexcal.core.parameters import N_ALL_PARAMETERS
from hexcal.errors import UsageError

#: Residual variants of the leg equations.
VARIANTS = ("length", "paper")

_LEG = np.arange(6)
_U_COLS = 3 * _LEG[:, None] + np.arange(3)
_S_COLS = 18 + _U_COLS
_L0_COLS = 36 + _LEG
_G_COLS = 42 + _LEG


def check_variant(variant: str) -> str:
    """Return ``variant`` if it is one of :data:`VARIANTS`, else raise :class:`UsageError`."""
    if variant not in VARIANTS:
        raise UsageError(f"unknown method {variant!r}; choose from {', '.join(VARIANTS)}")
    return variant


def pose_frames(poses: ArrayLike, euler: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rotation matrices ``(m, 3, 3)`` and positions ``(m, 3)`` of poses ``(m, 6)``."""
    poses = as_poses(poses, "poses").reshape(-1, 6)
    return rotation_matrices(poses[:, 3:], euler), np.ascontiguousarray(poses[:, :3])


def _leg_terms(
    values: NDArray[np.float64],
    rotations: NDArray[np.float64],
    positions: NDArray[np.float64],
    readings: NDArray[np.float64],
) -> tuple[NDArray, NDArray]:
    """Leg vectors ``v`` (m, 6, 3) and modelled lengths ``l0 + g dl`` (m, 6)."""
    u, s = values[:18].reshape(6, 3), values[18:36].reshape(6, 3)
    l0, g = values[36:42], values[42:48]
    rotated = np.einsum("mjk,ik->mij", rotations, s)
    legs = rotated + positions[:, None, :] - u
    return legs, l0 + g * readings


def leg_residuals(
    values: NDArray[np.float64],
    rotations: NDArray[np.float64],
    positions: NDArray[np.float64],
    readings: NDArray[np.float64],
    variant: str = "length",
) -> NDArray[np.float64]:
    """Leg residuals of every pose and leg, shape ``(m, 6)`` (mm, or mm² for ``"paper"``)."""
    legs, model = _leg_terms(values, rotations, positions, readings)
    sq = np.einsum("mik,mik->mi", legs, legs)
    if variant == "paper":
        return sq - model**2
    return np.sqrt(sq) - model


def leg_parameter_jacobian(
    values: NDArray[np.float64],
    rotations: NDArray[np.float64],
    positions: NDArray[np.float64],
    readings: NDArray[np.float64],
    variant: str = "length",
) -> NDArray[np.float64]:
    """Jacobian of :func:`leg_residuals` with respect to the 48 machine parameters, ``(m, 6, 48)``."""
    legs, model = _leg_terms(values, rotations, positions, readings)
    m = legs.shape[0]
    if variant == "paper":
        d_leg = 2.0 * legs  # d|v|²/dv
        d_model = -2.0 * model  # d(-(l0 + g dl)²)/d(l0 + g dl)
    else:
        d_leg = legs / np.sqrt(np.einsum("mik,mik->mi", legs, legs))[..., None]
        d_model = -np.ones_like(model)
    jac = np.zeros((m, 6, N_ALL_PARAMETERS))
    jac[:, _LEG[:, None], _U_COLS] = -d_leg
    # d v / d s_i = R_j, so d r / d s_i = (d r / d v) R_j
    jac[:, _LEG[:, None], _S_COLS] = np.einsum("mik,mkj->mij", d_leg, rotations)
    jac[:, _LEG, _L0_COLS] = d_model
    jac[:, _LEG, _G_COLS] = d_model * readings
    return jac
