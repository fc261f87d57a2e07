"""Pose errors that random kinematic parameter errors cause, for many draws at once.

Draws of parameter errors (:func:`parameter_error_draws`) and the platform pose error they
cause at target poses (:func:`pose_error_samples`: position ``|δp|`` in mm and the angle of
the orientation error in rad), by the first-order map of
:func:`hexcal.calibration.accuracy.pose_error_map` or by the forward kinematics of every
perturbed machine; computed block by block over the poses so that large maps fit in
memory. Imports :mod:`hexcal.core` and :mod:`hexcal.calibration.accuracy`.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.calibration.accuracy import pose_error_map, rotation_vector_map
from hexcal.core import (
    PARAMETER_SCALE,
    Geometry,
    as_poses,
    forward_kinematics_from_arrays,
    inverse_kinematics,
    orientation_error,
)
from hexcal.design.identifiability import as_mask

_CHUNK = 2048  # poses per block of the linear map (with 64 draws; fewer with more draws)


def _blocks(n_poses: int, n_draws: int) -> Iterator[slice]:
    """Slices of the poses such that a block holds about ``_CHUNK * 64`` pose-draw errors."""
    step = max(1, _CHUNK * 64 // n_draws)
    for start in range(0, n_poses, step):
        yield slice(start, start + step)


def parameter_error_draws(
    n_draws: int,
    mask: ArrayLike | None = None,
    amplitude: float = 0.1,
    rng: np.random.Generator | int | None = None,
) -> NDArray[np.float64]:
    """Random parameter errors, uniform in ``±amplitude`` characteristic units, shape (D, n).

    ``amplitude`` is in mm for joints and ``l0`` (the paper's 0.1 mm); gains get
    ``amplitude`` times their scale (1e-3, :data:`hexcal.core.PARAMETER_SCALE`).

    >>> parameter_error_draws(3, rng=0).shape
    (3, 42)
    """
    mask = as_mask(mask)
    if int(n_draws) < 1:
        raise ValueError(f"the number of parameter draws must be at least 1, got {n_draws}")
    if not (np.isfinite(amplitude) and amplitude > 0):
        raise ValueError(f"the parameter error amplitude must be > 0, got {amplitude}")
    gen = np.random.default_rng(rng)
    scale = PARAMETER_SCALE[mask]
    return gen.uniform(-amplitude, amplitude, size=(int(n_draws), scale.size)) * scale


def _linear_errors(
    geometry: Geometry, poses: NDArray[np.float64], draws: NDArray[np.float64], mask: NDArray[np.bool_]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Position and orientation errors (m, D) of flat poses (m, 6) by the first-order map."""
    m, n = poses.shape[0], draws.shape[1]
    e = pose_error_map(geometry, poses, mask)  # (m, 6, n)
    # angle rows to rotation-vector rows first: n columns are fewer than D draws
    e[:, 3:] = np.matmul(rotation_vector_map(geometry, poses), e[:, 3:])
    d = (e.reshape(-1, n) @ draws.T).reshape(m, 6, -1)  # (m, 6, D): δp and ω
    d *= d
    return np.sqrt(d[:, 0] + d[:, 1] + d[:, 2]), np.sqrt(d[:, 3] + d[:, 4] + d[:, 5])


def _exact_errors(
    geometry: Geometry, poses: NDArray[np.float64], draws: NDArray[np.float64], mask: NDArray[np.bool_]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Position and orientation errors (m, D) by the forward kinematics of each perturbed machine."""
    full = geometry.to_vector(gains=True)
    vectors = np.broadcast_to(full, (draws.shape[0], full.size)).copy()
    vectors[:, mask] += draws
    u = vectors[:, :18].reshape(-1, 1, 6, 3)
    s = vectors[:, 18:36].reshape(-1, 1, 6, 3)
    readings = (inverse_kinematics(geometry, poses) - geometry.initial_leg_lengths) / geometry.leg_gains
    lengths = vectors[:, None, 36:42] + vectors[:, None, 42:48] * readings  # (D, m, 6)
    result = forward_kinematics_from_arrays(u, s, lengths, poses, geometry.euler)
    if not result.all_converged:
        raise ValueError(
            f"forward kinematics of the perturbed machines did not converge for "
            f"{int(np.sum(~result.converged))} pose(s)"
        )
    reached = np.swapaxes(result.poses, 0, 1)  # (m, D, 6)
    targets = np.broadcast_to(poses[:, None], reached.shape)
    position = np.linalg.norm(reached[..., :3] - targets[..., :3], axis=-1)
    return position, orientation_error(targets[..., 3:], reached[..., 3:], geometry.euler)


def pose_error_samples(
    geometry: Geometry,
    poses: ArrayLike,
    draws: ArrayLike,
    mask: ArrayLike | None = None,
    method: str = "linear",
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Pose error at every pose for every parameter draw.

    Parameters
    ----------
    geometry : Geometry
        The nominal machine (the controller's parameters).
    poses : array_like, shape (..., 6)
        Target poses.
    draws : array_like, shape (D, n)
        Parameter errors (parameter units), columns the parameters of ``mask``.
    mask : array_like of bool, shape (48,), optional
        Default joints and ``l0``.
    method : {"linear", "exact"}
        First-order map, or forward kinematics of every perturbed machine.

    Returns
    -------
    position : ndarray, shape (..., D), mm
    orientation : ndarray, shape (..., D), rad

    Examples
    --------
    >>> from hexcal.core import preset
    >>> machine = preset("paper-hmt")
    >>> position, orientation = pose_error_samples(machine, machine.home_pose, np.zeros((2, 42)))
    >>> position.tolist(), orientation.tolist()
    ([0.0, 0.0], [0.0, 0.0])
    """
    mask = as_mask(mask)
    poses = as_poses(poses)
    draws = np.atleast_2d(np.asarray(draws, dtype=float))
    if draws.shape[1] != int(mask.sum()):
        raise ValueError(f"draws must have shape (D, {int(mask.sum())}), got {draws.shape}")
    batch = poses.shape[:-1]
    flat = poses.reshape(-1, 6)
    if method == "linear":
        fn = _linear_errors
    elif method == "exact":
        fn = _exact_errors
    else:
        raise ValueError(f"unknown method {method!r}; choose linear or exact")
    pos = np.empty((flat.shape[0], draws.shape[0]))
    ang = np.empty_like(pos)
    for sl in _blocks(flat.shape[0], draws.shape[0]):
        pos[sl], ang[sl] = fn(geometry, flat[sl], draws, mask)
    return pos.reshape(batch + (-1,)), ang.reshape(batch + (-1,))


def mean_pose_errors(
    geometry: Geometry,
    poses: NDArray[np.float64],
    draws: NDArray[np.float64],
    mask: ArrayLike | None = None,
    method: str = "linear",
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean over draws of the position and orientation error, shape ``poses.shape[:-1]``.

    :func:`pose_error_samples` block by block, so that the draws of a large grid never
    sit in memory at once.

    >>> from hexcal.core import preset
    >>> machine = preset("paper-hmt")
    >>> position, _ = mean_pose_errors(machine, machine.home_pose[None], np.zeros((2, 42)))
    >>> position.tolist()
    [0.0]
    """
    flat = poses.reshape(-1, 6)
    pos = np.empty(flat.shape[0])
    ang = np.empty(flat.shape[0])
    for sl in _blocks(flat.shape[0], draws.shape[0]):
        p, a = pose_error_samples(geometry, flat[sl], draws, mask, method)
        pos[sl], ang[sl] = p.mean(axis=-1), a.mean(axis=-1)
    return pos.reshape(poses.shape[:-1]), ang.reshape(poses.shape[:-1])
