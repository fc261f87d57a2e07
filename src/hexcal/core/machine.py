"""The machine's leg equations, shared by every instrument and every solver: residuals and their
Jacobians, batch-first.

Leg ``i`` at a platform pose ``(o, R)`` has the length ``|o + R s_i - u_i|``; the controller's
reading ``dl_i`` says it is ``f(θ_i, dl_i)`` through the leg model (:mod:`hexcal.core.legs`;
``l0_i + g_i dl_i`` for linear legs). Their difference is the leg residual (``"length"``, mm);
the seed paper's cost (Agheli & Nategh 2009, eq. 3, after Zhuang et al. 1998) uses the
difference of squares ``|v|² - f²`` (``"paper"``, mm²).

Each leg's residual depends only on that leg's own parameters: its base joint ``u_i``, its
platform joint ``s_i`` and its leg-model parameters ``θ_i``, the *leg table* ``(..., 6, L)``
(:func:`leg_table`; ``L = 8`` for linear legs; the columns :func:`leg_columns` of the machine's
parameters). :func:`leg_equations` evaluates the residuals ``(..., m, 6)`` and their Jacobian
in each leg's own columns ``(..., m, 6, L)`` for any leading batch shape (one campaign, or a
stack of trials): the one implementation that every estimator, bound and study uses.
:func:`leg_residuals` and :func:`leg_parameter_jacobian` take the machine's two blocks by
name: ``joints`` (36 values, base joints then platform joints) and ``legs`` (the leg model's
block); the latter returns the Jacobian over all ``36 + p`` machine parameters.

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


def leg_columns(model: LegModel) -> NDArray[np.intp]:
    """Machine-parameter positions of each leg's own parameters ``(6, 6 + per_leg)``: its base
    joint, its platform joint, then its leg-model parameters (the legs' residuals are
    separable: leg ``i`` depends on these alone)."""
    return np.concatenate([_U_COLS, _S_COLS, N_JOINTS + model.index()], axis=1)


def leg_table(joints: ArrayLike, legs: ArrayLike, model: LegModel) -> NDArray[np.float64]:
    """Each leg's own parameters ``(..., 6, L)`` of joint blocks ``(..., 36)`` and leg blocks
    ``(..., p)``: base joint, platform joint, then the leg model's parameters."""
    machine = np.concatenate([np.asarray(joints, dtype=float), np.asarray(legs, dtype=float)], axis=-1)
    return machine[..., leg_columns(model)]


def leg_equations(
    table: NDArray[np.float64],
    model: LegModel,
    rotations: NDArray[np.float64],
    positions: NDArray[np.float64],
    readings: NDArray[np.float64],
    variant: str = "length",
    jacobian: bool = True,
    legs_first: bool = False,
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """Leg residuals of every pose and leg and their Jacobian in each leg's own parameters.

    Parameters
    ----------
    table : ndarray, shape (..., 6, L)
        Each leg's parameters (:func:`leg_table`).
    model : LegModel
    rotations, positions : ndarray, shape (..., m, 3, 3) and (..., m, 3)
        Pose frames (:func:`pose_frames`).
    readings : ndarray, shape (..., m, 6)
    variant : {"length", "paper"}
    jacobian : bool
        Also the Jacobian (else None).
    legs_first : bool
        The leg axis before the pose axis in the results (the layout of the per-leg normal
        equations of stacked solvers).

    Returns
    -------
    r : ndarray, shape (..., m, 6), or (..., 6, m) with ``legs_first``
        Residuals (mm, or mm² for ``paper``); the batch shapes broadcast.
    jac : ndarray, shape (..., m, 6, L), or (..., 6, m, L) with ``legs_first``
        ``d r / d table[..., i, :]`` of leg ``i`` in parameter units.

    Notes
    -----
    With ``v_ji = R_j s_i + o_j - u_i`` and ``f`` the leg model, ``r = |v| - f`` and
    ``dr/du_i = -v/|v|``, ``dr/ds_i = (v/|v|)ᵀ R_j``, ``dr/dθ_i = -df/dθ_i`` (``paper``:
    ``r = |v|² - f²``, ``2 v``, ``2 vᵀ R_j``, ``-2 f df/dθ_i``). The sums over coordinates are
    evaluated as the two layouts always were in hexcal (by ``einsum`` for a campaign's poses, by
    components for stacks: faster for those shapes), so that every result keeps its last bits
    (pose selection breaks near-ties of mirror-image poses by them).
    """
    theta = table[..., None, :, 6:]  # the leg model's per-leg functions take the leg axis last
    lengths = model.length(theta, readings)  # (..., m, 6)
    if legs_first:
        # v[..., i, j] = R_j s_i + o_j - u_i, by components
        p, r_ = table[..., :, None, :], rotations[..., None, :, :, :]  # (..., 6, 1, L), (..., 1, m, 3, 3)
        pos = positions[..., None, :, :]
        v = [
            r_[..., a, 0] * p[..., 3]
            + r_[..., a, 1] * p[..., 4]
            + r_[..., a, 2] * p[..., 5]
            + (pos[..., a] - p[..., a])
            for a in range(3)
        ]
        sq = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
        lengths = np.swapaxes(lengths, -1, -2)
    else:
        u, s = table[..., :3], np.ascontiguousarray(table[..., 3:6])
        v = np.einsum("...mjk,...ik->...mij", rotations, s) + positions[..., :, None, :] - u[..., None, :, :]
        sq = np.einsum("...ik,...ik->...i", v, v)
    if variant == "paper":
        r = sq - lengths**2
    else:
        length = np.sqrt(sq)
        r = length - lengths
    if not jacobian:
        return r, None
    dmodel = model.length_jacobian(theta, readings)  # (..., m, 6, q)
    jac = np.empty((*r.shape, table.shape[-1]))
    if variant == "paper":
        jac[..., 6:] = (-2.0 * lengths)[..., None] * (np.swapaxes(dmodel, -3, -2) if legs_first else dmodel)
    else:
        jac[..., 6:] = -(np.swapaxes(dmodel, -3, -2) if legs_first else dmodel)
    # d r / d u_i = -d r / d v; d v / d s_i = R_j, so d r / d s_i = (d r / d v) R_j
    if legs_first:
        inv = None if variant == "paper" else 1.0 / length
        d = [2.0 * c if inv is None else c * inv for c in v]  # d r / d v
        for a in range(3):
            jac[..., a] = -d[a]
            jac[..., 3 + a] = d[0] * r_[..., 0, a] + d[1] * r_[..., 1, a] + d[2] * r_[..., 2, a]
    else:
        d = 2.0 * v if variant == "paper" else v / length[..., None]
        jac[..., :3] = -d
        jac[..., 3:6] = np.einsum("...mik,...mkj->...mij", d, rotations)
    return r, jac


def leg_residuals(
    joints: NDArray[np.float64],
    legs: NDArray[np.float64],
    model: LegModel,
    rotations: NDArray[np.float64],
    positions: NDArray[np.float64],
    readings: NDArray[np.float64],
    variant: str = "length",
) -> NDArray[np.float64]:
    """Leg residuals of every pose and leg, shape ``(..., m, 6)`` (mm, or mm² for ``"paper"``)."""
    return leg_equations(
        leg_table(joints, legs, model), model, rotations, positions, readings, variant, False
    )[0]


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
    ``(..., m, 6, 36 + p)`` (:func:`leg_equations`' columns placed in the machine's)."""
    table = leg_table(joints, legs, model)
    _, local = leg_equations(table, model, rotations, positions, readings, variant)
    return spread_legs(local, model)


def spread_legs(local: NDArray[np.float64], model: LegModel) -> NDArray[np.float64]:
    """A leg Jacobian ``(..., 6, L)`` in each leg's own columns placed in the machine's
    ``(..., 6, 36 + p)`` (zero where a leg does not depend on a parameter)."""
    out = np.zeros((*local.shape[:-1], N_JOINTS + model.size))
    out[..., _LEG[:, None], leg_columns(model)] = local
    return out
