"""Inverse and forward kinematics, the pose Jacobian and the workspace.

All functions are batch-first: poses have shape ``(..., 6)`` and broadcast.
A leg's length is ``l_i = |o + R s_i - u_i|``; its reading becomes a length through the
geometry's leg model (:mod:`hexcal.core.legs`; ``l0_i + g_i dl_i`` for linear legs).

The low-level functions take the joint arrays directly, so that a batch of
different machines (one per Monte Carlo trial, say) broadcasts like a batch of
poses: ``base_joints`` and ``platform_joints`` have shape ``(..., 6, 3)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.conventions import (
    as_poses,
    check_euler,
    orientation_error,
    rotation_and_axes_t,
    rotation_matrices,
    rotation_matrices_t,
)
from hexcal.core.covariate_legs import geometry_inputs
from hexcal.core.geometry import Geometry

#: Default convergence tolerance of the forward kinematics, mm of leg length.
FK_TOLERANCE = 1e-9


def rotate_points(rotations: NDArray[np.float64], points: ArrayLike) -> NDArray[np.float64]:
    """``R @ p_i`` for rotations ``(..., 3, 3)`` and points ``(..., k, 3)``: shape ``(..., k, 3)``.

    Written as three broadcast products, which is faster than einsum for these shapes.
    """
    p = np.asarray(points, dtype=float)
    return (
        p[..., :, 0, None] * rotations[..., None, :, 0]
        + p[..., :, 1, None] * rotations[..., None, :, 1]
        + p[..., :, 2, None] * rotations[..., None, :, 2]
    )


def leg_vectors_from_arrays(
    base_joints: ArrayLike,
    platform_joints: ArrayLike,
    poses: ArrayLike,
    euler: str,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Leg vectors ``o + R s_i - u_i`` and rotated platform joints ``R s_i``.

    Parameters
    ----------
    base_joints, platform_joints : array_like, shape (..., 6, 3)
    poses : array_like, shape (..., 6)
    euler : str

    Returns
    -------
    legs : ndarray, shape (..., 6, 3)
    rotated : ndarray, shape (..., 6, 3)
        ``R s_i`` in the base frame.
    """
    poses = as_poses(poses)
    rotated = rotate_points(rotation_matrices(poses[..., 3:], euler), platform_joints)
    legs = rotated + (poses[..., None, :3] - np.asarray(base_joints))
    return legs, rotated


def leg_vectors(geometry: Geometry, poses: ArrayLike) -> NDArray[np.float64]:
    """Leg vectors ``o + R s_i - u_i`` in the base frame, shape ``(..., 6, 3)``, mm."""
    legs, _ = leg_vectors_from_arrays(geometry.base_joints, geometry.platform_joints, poses, geometry.euler)
    return legs


_IK_CHUNK = 2048  # poses per block: temporaries stay below the allocator's mmap threshold (128 KiB)


def _squared_length_coefficients(geometry: Geometry) -> NDArray[np.float64]:
    """Coefficients ``C`` (6, 17) with ``l_i² = C[i] @ features(pose)``.

    ``|o + R s - u|² = |o|² - 2 u·o + 2 s·(Rᵀo) - 2 uᵀ R s + |u|² + |s|²``: linear in
    the 17 features ``(o, Rᵀo, R (row-major), |o|², 1)`` of a pose.
    """
    u, s = geometry.base_joints, geometry.platform_joints
    outer = np.einsum("ij,ik->ijk", u, s).reshape(6, 9)
    const = np.einsum("ij,ij->i", u, u) + np.einsum("ij,ij->i", s, s)
    return np.concatenate([-2 * u, 2 * s, -2 * outer, np.ones((6, 1)), const[:, None]], axis=1)


def _inverse_kinematics_block(
    coefficients: NDArray[np.float64], poses: NDArray[np.float64], euler: str
) -> NDArray[np.float64]:
    pt = np.ascontiguousarray(poses.T)
    rot = rotation_matrices_t(pt[3:], euler).reshape(9, -1)
    o = pt[:3]
    rt_o = np.einsum("jkn,jn->kn", rot.reshape(3, 3, -1), o)
    features = np.concatenate([o, rt_o, rot, np.einsum("jn,jn->n", o, o)[None], np.ones((1, o.shape[1]))])
    return np.sqrt(np.maximum(coefficients @ features, 0.0)).T


def inverse_kinematics(geometry: Geometry, poses: ArrayLike) -> NDArray[np.float64]:
    """Leg lengths of poses.

    Parameters
    ----------
    geometry : Geometry
    poses : array_like, shape (..., 6)
        ``(x, y, z, a, b, c)`` in mm and rad.

    Returns
    -------
    ndarray, shape (..., 6)
        ``l_i = |o + R s_i - u_i|``, mm.

    Notes
    -----
    Evaluated as a matrix product of 17 pose features with per-leg coefficients
    (:func:`_squared_length_coefficients`), block by block; the rounding error of
    the squared form is below 1e-12 mm for machines of metre size.
    """
    poses = as_poses(poses)
    flat = poses.reshape(-1, 6)
    coefficients = _squared_length_coefficients(geometry)
    out = np.empty((flat.shape[0], 6))
    for start in range(0, flat.shape[0], _IK_CHUNK):
        block = flat[start : start + _IK_CHUNK]
        out[start : start + _IK_CHUNK] = _inverse_kinematics_block(coefficients, block, geometry.euler)
    return out.reshape(poses.shape)


def leg_readings(
    geometry: Geometry, lengths: ArrayLike, inputs: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Leg readings of absolute leg lengths through the geometry's leg model (``(l - l0) / g``
    for linear legs), shape ``(..., 6)``; ``inputs`` ``(..., 6, K)`` are each pose's for a leg
    model with covariates (:meth:`hexcal.core.legs.LegModel.leg_inputs`)."""
    if inputs is None:
        return geometry.leg_model.readings(geometry.leg_block(), lengths)
    return geometry.leg_model.readings(geometry.leg_block(), lengths, inputs)


def leg_lengths(
    geometry: Geometry, readings: ArrayLike, inputs: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Absolute leg lengths of leg readings through the geometry's leg model (``l0 + g dl``
    for linear legs), shape ``(..., 6)``; ``inputs`` as in :func:`leg_readings`."""
    return geometry.leg_model.lengths(geometry.leg_block(), readings, inputs)


def pose_jacobian_from_arrays(
    base_joints: ArrayLike,
    platform_joints: ArrayLike,
    poses: ArrayLike,
    euler: str,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Leg lengths and their analytic Jacobian with respect to the pose.

    Returns
    -------
    lengths : ndarray, shape (..., 6)
    jacobian : ndarray, shape (..., 6, 6)
        ``J[..., i, k] = d l_i / d pose_k``.

    Notes
    -----
    With ``n_i`` the unit leg vector and ``w_k`` the base-frame axis of the k-th
    elementary rotation (:func:`hexcal.core.conventions.euler_axes`),
    ``d l_i / d o = n_i`` and ``d l_i / d θ_k = w_k · (R s_i × n_i)``.
    """
    poses = as_poses(poses)
    check_euler(euler)
    batch = poses.shape[:-1]
    # rotations and rotation axes from one pass over the angles (the trigonometry dominates)
    rot_t, axes_t = rotation_and_axes_t(np.ascontiguousarray(poses.reshape(-1, 6)[:, 3:].T), euler)
    rot = np.moveaxis(rot_t, -1, 0).reshape(*batch, 3, 3)
    axes = np.moveaxis(axes_t, -1, 0).reshape(*batch, 3, 3)
    rotated = rotate_points(rot, platform_joints)
    legs = rotated + (poses[..., None, :3] - np.asarray(base_joints))
    lengths = np.sqrt(np.einsum("...k,...k->...", legs, legs))
    unit = legs / lengths[..., None]
    # moment = rotated × unit, by components (np.cross costs more than it computes here)
    rx, ry, rz = rotated[..., 0], rotated[..., 1], rotated[..., 2]
    ux, uy, uz = unit[..., 0], unit[..., 1], unit[..., 2]
    moment = np.stack([ry * uz - rz * uy, rz * ux - rx * uz, rx * uy - ry * ux], axis=-1)
    # angular columns: jac[..., i, 3 + k] = w_k · moment_i
    angular = (
        moment[..., :, 0, None] * axes[..., None, :, 0]
        + moment[..., :, 1, None] * axes[..., None, :, 1]
        + moment[..., :, 2, None] * axes[..., None, :, 2]
    )
    jac = np.concatenate([unit, angular], axis=-1)
    return lengths, jac


def pose_jacobian(geometry: Geometry, poses: ArrayLike) -> NDArray[np.float64]:
    """Analytic Jacobian ``d l / d pose`` of the inverse kinematics, shape ``(..., 6, 6)``.

    Rows are legs, columns the pose coordinates ``(x, y, z, a, b, c)``; units mm/mm
    and mm/rad.
    """
    _, jac = pose_jacobian_from_arrays(geometry.base_joints, geometry.platform_joints, poses, geometry.euler)
    return jac


@dataclass(frozen=True)
class ForwardResult:
    """Result of :func:`forward_kinematics`.

    Attributes
    ----------
    poses : ndarray, shape (..., 6)
        Solved poses; NaN where the iteration did not converge.
    converged : ndarray of bool, shape (...)
    iterations : ndarray of int, shape (...)
    residual : ndarray, shape (...)
        Largest leg length error ``max_i |l_i(pose) - l_i|``, mm, at the last iterate.
    """

    poses: NDArray[np.float64]
    converged: NDArray[np.bool_]
    iterations: NDArray[np.int_]
    residual: NDArray[np.float64]

    @property
    def all_converged(self) -> bool:
        return bool(np.all(self.converged))


def _solve_steps(jac: NDArray[np.float64], rhs: NDArray[np.float64]) -> NDArray[np.float64]:
    try:
        return np.linalg.solve(jac, rhs[..., None])[..., 0]
    except np.linalg.LinAlgError:
        # at least one singular pose in the batch: the pseudo-inverse keeps the rest going
        return np.einsum("...ij,...j->...i", np.linalg.pinv(jac), rhs)


def _rows(joints: NDArray[np.float64], index: slice | NDArray[np.intp]) -> NDArray[np.float64]:
    """The joints of some poses: all of them for one machine ``(6, 3)``, else ``joints[index]``."""
    return joints if joints.ndim == 2 else joints[index]


_FK_CHUNK = 2048  # poses per block: keeps the Newton iterates in cache


def _newton_block(
    u: NDArray[np.float64],
    s: NDArray[np.float64],
    target: NDArray[np.float64],
    pose: NDArray[np.float64],
    euler: str,
    tol: float,
    max_iter: int,
) -> tuple[NDArray[np.bool_], NDArray[np.int_], NDArray[np.float64]]:
    """Damped Newton iteration on one block; updates ``pose`` in place."""
    n = pose.shape[0]
    converged = np.zeros(n, dtype=bool)
    iterations = np.zeros(n, dtype=np.int_)
    cur, jac = pose_jacobian_from_arrays(u, s, pose, euler)
    err = cur - target
    residual = np.max(np.abs(err), axis=-1)
    active = np.arange(n)
    for _ in range(max_iter):
        done = residual[active] <= tol
        converged[active[done]] = True
        keep = ~done & np.isfinite(residual[active])
        active, jac, err = active[keep], jac[keep], err[keep]
        if active.size == 0:
            break
        iterations[active] += 1
        step = _solve_steps(jac, err)
        norm0 = np.linalg.norm(err, axis=-1)
        alpha = np.ones(active.size)
        new_pose = pose[active] - step
        new_len, new_jac = pose_jacobian_from_arrays(_rows(u, active), _rows(s, active), new_pose, euler)
        new_err = new_len - target[active]
        # damping: halve the Newton step of poses whose residual grew
        for _halving in range(20):
            worse = ~(np.linalg.norm(new_err, axis=-1) < norm0) & (alpha > 1e-6)
            if not worse.any():
                break
            idx = np.flatnonzero(worse)
            alpha[idx] *= 0.5
            new_pose[idx] = pose[active[idx]] - alpha[idx, None] * step[idx]
            sub = active[idx]
            ln, jn = pose_jacobian_from_arrays(_rows(u, sub), _rows(s, sub), new_pose[idx], euler)
            new_len[idx], new_jac[idx] = ln, jn
            new_err[idx] = ln - target[active[idx]]
        pose[active] = new_pose
        err, jac = new_err, new_jac
        residual[active] = np.max(np.abs(err), axis=-1)
    else:
        done = residual[active] <= tol
        converged[active[done]] = True
    return converged, iterations, residual


def forward_kinematics_from_arrays(
    base_joints: ArrayLike,
    platform_joints: ArrayLike,
    lengths: ArrayLike,
    guess: ArrayLike,
    euler: str,
    tol: float = FK_TOLERANCE,
    max_iter: int = 50,
) -> ForwardResult:
    """Forward kinematics for a batch of machines and leg lengths (see :func:`forward_kinematics`).

    ``base_joints`` and ``platform_joints`` of shape ``(..., 6, 3)`` broadcast with
    ``lengths`` of shape ``(..., 6)``.
    """
    lengths = np.asarray(lengths, dtype=float)
    if lengths.shape[-1:] != (6,):
        raise ValueError(f"lengths must have shape (..., 6), got {lengths.shape}")
    u = np.asarray(base_joints, dtype=float)
    s = np.asarray(platform_joints, dtype=float)
    batch = np.broadcast_shapes(lengths.shape[:-1], u.shape[:-2], s.shape[:-2], np.shape(guess)[:-1])
    target = np.broadcast_to(lengths, batch + (6,)).reshape(-1, 6)
    # one machine for all poses: keep its joints unbatched (no per-pose copies)
    single = u.ndim == 2 and s.ndim == 2
    if not single:
        u = np.broadcast_to(u, batch + (6, 3)).reshape(-1, 6, 3)
        s = np.broadcast_to(s, batch + (6, 3)).reshape(-1, 6, 3)
    pose = np.array(np.broadcast_to(as_poses(guess, "guess"), batch + (6,)).reshape(-1, 6))
    n = pose.shape[0]
    converged = np.zeros(n, dtype=bool)
    iterations = np.zeros(n, dtype=np.int_)
    residual = np.full(n, np.inf)
    for start in range(0, n, _FK_CHUNK):
        blk = slice(start, start + _FK_CHUNK)
        converged[blk], iterations[blk], residual[blk] = _newton_block(
            _rows(u, blk), _rows(s, blk), target[blk], pose[blk], euler, tol, max_iter
        )
    out = np.where(converged[:, None], pose, np.nan)
    return ForwardResult(
        poses=out.reshape(batch + (6,)),
        converged=converged.reshape(batch),
        iterations=iterations.reshape(batch),
        residual=residual.reshape(batch),
    )


def forward_kinematics(
    geometry: Geometry,
    lengths: ArrayLike,
    guess: ArrayLike | None = None,
    tol: float = FK_TOLERANCE,
    max_iter: int = 50,
) -> ForwardResult:
    """Poses that produce given absolute leg lengths (damped Newton iteration).

    Parameters
    ----------
    geometry : Geometry
    lengths : array_like, shape (..., 6)
        Absolute leg lengths, mm (use :func:`leg_lengths` for readings).
    guess : array_like, shape (..., 6), optional
        Starting poses; default the geometry's home pose.
    tol : float
        Convergence when every leg length matches within ``tol`` mm.
    max_iter : int

    Returns
    -------
    ForwardResult
        Poses (NaN where not converged), per-pose ``converged``, ``iterations`` and
        ``residual``.

    Notes
    -----
    Newton's method on ``l(pose) - lengths = 0`` with the analytic Jacobian of
    :func:`pose_jacobian`; a step that does not reduce the residual norm is halved
    (up to 20 times). Converges quadratically near a solution; from the home pose it
    finds the assembly mode of the workspace.
    """
    if guess is None:
        if geometry.home_pose is None:
            raise ValueError("forward kinematics needs a guess: the geometry has no home_pose")
        guess = geometry.home_pose
    return forward_kinematics_from_arrays(
        geometry.base_joints,
        geometry.platform_joints,
        lengths,
        guess,
        geometry.euler,
        tol=tol,
        max_iter=max_iter,
    )


def forward_with_covariates(
    geometry: Any,
    readings: ArrayLike,
    covariates: Any,
    guess: ArrayLike,
    where: str = "the data",
    sensor: ArrayLike | None = None,
) -> tuple[Any, NDArray[np.float64] | None]:
    """The poses of ``readings`` ``(m, 6)`` on ``geometry`` under each pose's ``covariates``
    (forward kinematics from ``guess``; ``sensor`` mm added to the lengths), and the inputs used.

    The axial forces of a compliance term depend on the pose: they are taken at ``guess``, then
    once more at the poses found (the first order of the module: a second pass changes the
    poses by parts in 10⁵ of the deflection). Returns the
    :class:`~hexcal.core.kinematics.ForwardResult` and the inputs ``(m, 6, K)`` (None for a
    model without covariates)."""
    readings = np.asarray(readings, dtype=float)
    extra = 0.0 if sensor is None else np.asarray(sensor, dtype=float)
    inputs = geometry_inputs(geometry, covariates, guess, where)
    fk = forward_kinematics(geometry, leg_lengths(geometry, readings, inputs) + extra, guess=guess)
    if inputs is not None and geometry.leg_model.inputs_need_poses and fk.all_converged:
        inputs = geometry_inputs(geometry, covariates, fk.poses, where)
        fk = forward_kinematics(geometry, leg_lengths(geometry, readings, inputs) + extra, guess=fk.poses)
    return fk, inputs


def pose_errors(
    targets: ArrayLike, reached: ArrayLike, euler: str
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Position error (mm) and orientation error (rad, rotation angle) of each pose.

    ``targets`` and ``reached`` of shape ``(..., 6)``; NaN errors where ``reached`` is NaN.

    Examples
    --------
    >>> position, angle = pose_errors(np.zeros((1, 6)), np.array([[3.0, 4, 0, 0, 0, 0]]), "xyz")
    >>> float(position[0]), float(angle[0])
    (5.0, 0.0)
    """
    targets, reached = np.asarray(targets, dtype=float), np.asarray(reached, dtype=float)
    position = np.linalg.norm(reached[..., :3] - targets[..., :3], axis=-1)
    finite = np.all(np.isfinite(reached), axis=-1)
    if finite.all():
        return position, orientation_error(targets[..., 3:], reached[..., 3:], euler)
    orientation = np.full(finite.shape, np.nan)  # NaN where not reached
    if finite.any():
        target = np.broadcast_to(targets, reached.shape)
        orientation[finite] = orientation_error(target[finite][:, 3:], reached[finite][:, 3:], euler)
    return position, orientation
