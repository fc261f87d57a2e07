"""Predicted accuracy after calibration: the one formula, for planning and for the verdict.

A controller that uses identified parameters ``θ̂`` misses a target by the pose error
``δpose = E (θ̂ - θ)`` to first order, with the map ``E = -J⁻¹ A`` from parameter errors to
platform pose errors (:func:`pose_error_map`: ``J`` the pose Jacobian of the legs, ``A`` the
leg residual's Jacobian with respect to the machine's parameters, any leg model). With the
parameters' covariance ``Σθ`` the pose error has the covariance ``E Σθ Eᵀ``;
:func:`predicted_pose_errors` gives its RMS position error and RMS rotation angle (the
rotation vector of the orientation error) at test poses, and
:func:`predicted_pose_accuracy` the summary over the workspace that ``identify`` predicts and
``validate`` measures. With a leg model whose curve holds over a calibrated stroke, the test
poses may take legs beyond it, where the model holds its curve
(:mod:`hexcal.core.stroke_legs`): the prediction is then made with that continuation, and
:func:`poses_stroke_excess` says how much of it lies there (``beyond_stroke``).

Imports :mod:`hexcal.core`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core import (
    Geometry,
    as_poses,
    euler_axes,
    inverse_kinematics,
    leg_readings,
    pose_jacobian,
    random_poses,
    workspace_corners,
)
from hexcal.core.machine import leg_parameter_jacobian, pose_frames
from hexcal.core.noise import NoiseModel
from hexcal.core.stroke_legs import STROKE_MARGIN, StrokeExcess, stroke_excess


def machine_mask(
    geometry: Geometry, mask: ArrayLike | None = None, names: tuple[str, ...] | None = None
) -> NDArray:
    """A mask over the geometry's machine parameters: given, from parameter ``names``, or the
    default joints and ``l0``."""
    all_names = geometry.machine_names()
    if names is not None:
        return np.isin(all_names, names)
    if mask is None:
        return np.array(geometry.machine_parameters().vary)
    return np.asarray(mask, dtype=bool)


def machine_jacobian(
    geometry: Geometry, poses: ArrayLike, mask: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Jacobian ``(m, 6, n)`` of the leg length residuals at poses a geometry reaches exactly
    (readings from its own inverse kinematics), columns the machine parameters of ``mask``."""
    flat = as_poses(poses).reshape(-1, 6)
    readings = leg_readings(geometry, inverse_kinematics(geometry, flat))
    rot, pos = pose_frames(flat, geometry.euler)
    jac = leg_parameter_jacobian(
        geometry.joint_block(), geometry.leg_block(), geometry.leg_model, rot, pos, readings, "length"
    )
    return jac[:, :, machine_mask(geometry, mask)]


def pose_error_map(
    geometry: Geometry, poses: ArrayLike, mask: ArrayLike | None = None
) -> NDArray[np.float64]:
    """First-order map from parameter errors to platform pose errors, shape (..., 6, n).

    Parameters
    ----------
    geometry : Geometry
        The controller's (nominal) geometry.
    poses : array_like, shape (..., 6)
        Commanded poses.
    mask : array_like of bool, optional
        Machine parameters with errors (default joints and ``l0``).

    Returns
    -------
    ndarray, shape (..., 6, n)
        ``E`` with ``δpose = E δθ`` (mm and rad per parameter unit).

    Notes
    -----
    The controller commands the nominal leg readings of a pose; a machine whose
    parameters differ by ``δθ`` reaches the pose where its leg equations
    ``r = |o + R s_i - u_i| - (l0_i + g_i dl_i) = 0`` hold. To first order
    ``J δpose + A δθ = 0``, so ``E = -J⁻¹ A`` with ``J`` the pose Jacobian and ``A`` the
    identification Jacobian of the leg length residual.

    Examples
    --------
    >>> from hexcal.core import preset
    >>> machine = preset("paper-hmt")
    >>> pose_error_map(machine, machine.home_pose).shape
    (6, 42)
    """
    poses = as_poses(poses)
    batch = poses.shape[:-1]
    flat = poses.reshape(-1, 6)
    a = machine_jacobian(geometry, flat, mask)
    jac_inv = np.linalg.inv(pose_jacobian(geometry, flat))
    out = -np.matmul(jac_inv, a)
    return out.reshape(batch + out.shape[-2:])


def rotation_vector_map(geometry: Geometry, poses: ArrayLike) -> NDArray[np.float64]:
    """Matrices ``W`` (..., 3, 3) with ``ω = W δ(a, b, c)``: small angle changes to the
    rotation vector of the orientation error, rad per rad (columns are the Euler axes).

    >>> from hexcal.core import preset
    >>> machine = preset("paper-hmt")
    >>> rotation_vector_map(machine, np.zeros(6)).shape
    (3, 3)
    """
    poses = as_poses(poses)
    return np.swapaxes(euler_axes(poses[..., 3:], geometry.euler), -1, -2)


def predicted_pose_errors(
    geometry: Geometry,
    test_poses: ArrayLike,
    covariance: ArrayLike,
    mask: ArrayLike | None = None,
    rigid: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """RMS position and orientation error after calibration at test poses.

    Parameters
    ----------
    geometry : Geometry
    test_poses : array_like, shape (t, 6)
    covariance : array_like, shape (n, n)
        Covariance of the identified parameters (parameter units).
    mask : array_like of bool, optional
        Machine parameters of the covariance (default joints and ``l0``).
    rigid : array_like, shape (n, g), optional
        Parameter directions whose pose errors are rigid motions of the workspace (the gauge
        freedoms of an instrument in its own frame): removed as re-registering the frames
        would (:func:`without_rigid_motions`).

    Returns
    -------
    position : ndarray, shape (t,), mm
        ``sqrt(E[|δp|²])``.
    orientation : ndarray, shape (t,), rad
        ``sqrt(E[|ω|²])``, ``ω`` the rotation vector of the orientation error.

    Notes
    -----
    A controller with the identified parameters misses a target by
    ``δpose = E (θ̂ - θ)`` (:func:`pose_error_map`), whose covariance is ``E Σθ Eᵀ``.

    Examples
    --------
    >>> from hexcal.core import preset
    >>> machine = preset("paper-hmt")
    >>> position, orientation = predicted_pose_errors(machine, [machine.home_pose], np.zeros((42, 42)))
    >>> position.tolist(), orientation.tolist()
    ([0.0], [0.0])
    """
    tp = as_poses(test_poses).reshape(-1, 6)
    cov = np.asarray(covariance, dtype=float)
    e = pose_error_map(geometry, tp, mask)
    w = rotation_vector_map(geometry, tp)
    e_pos = e[:, :3]
    e_rot = np.einsum("tij,tjk->tik", w, e[:, 3:])
    if rigid is not None and np.size(rigid):
        cov = without_rigid_motions(cov, e_pos, e_rot, np.asarray(rigid, dtype=float), geometry)
    pos = np.einsum("tip,pq,tiq->t", e_pos, cov, e_pos)
    rot = np.einsum("tip,pq,tiq->t", e_rot, cov, e_rot)
    return np.sqrt(np.clip(pos, 0, None)), np.sqrt(np.clip(rot, 0, None))


def without_rigid_motions(
    covariance: NDArray[np.float64],
    e_pos: NDArray[np.float64],
    e_rot: NDArray[np.float64],
    rigid: NDArray[np.float64],
    geometry: Geometry,
) -> NDArray[np.float64]:
    """The parameter covariance with the directions ``rigid`` (n, g) projected out as a
    re-registration of the frames removes them: the pose errors along them are rigid motions of
    the workspace (gauge freedoms), so the projection is the one that minimises the pose error
    over the test poses (angles weighted by the platform radius, so a milliradian at the edge
    of the platform counts as its displacement)."""
    proj = rigid_projection(e_pos, e_rot, rigid, geometry)
    return proj @ covariance @ proj.T


def rigid_projection(
    e_pos: NDArray[np.float64], e_rot: NDArray[np.float64], rigid: NDArray[np.float64], geometry: Geometry
) -> NDArray[np.float64]:
    """The projection ``(n, n)`` of :func:`without_rigid_motions` (``cov -> P cov Pᵀ``)."""
    radius = float(np.max(np.linalg.norm(geometry.platform_joints[:, :2], axis=1)))
    metric = np.einsum("tip,tiq->pq", e_pos, e_pos) + radius**2 * np.einsum("tip,tiq->pq", e_rot, e_rot)
    mg = metric @ rigid
    return np.eye(len(rigid)) - rigid @ np.linalg.pinv(rigid.T @ mg) @ mg.T


def position_metric(
    geometry: Geometry,
    mask: ArrayLike | None = None,
    rigid: ArrayLike | None = None,
    n_random: int = 200,
    seed: int = 0,
) -> NDArray[np.float64]:
    """The matrix ``W`` (n, n) whose ``trace(Σθ W)`` is the square of the predicted position
    RMS (mm²) of :func:`predicted_pose_accuracy` for a parameter covariance ``Σθ``: a
    criterion of what a calibration will deliver, linear in the covariance (so planning can
    score many candidate covariances at once).

    >>> from hexcal.core import preset
    >>> machine, cov = preset("paper-hmt"), np.eye(42) * 1e-4
    >>> w = position_metric(machine)
    >>> bool(np.isclose(np.sqrt(np.trace(cov @ w)), predicted_pose_accuracy(machine, cov)["position_rms_mm"]))
    True
    """
    tp = accuracy_test_poses(geometry, n_random, seed)
    e = pose_error_map(geometry, tp, mask)
    e_pos = e[:, :3]
    weight = np.einsum("tip,tiq->pq", e_pos, e_pos) / len(tp)
    if rigid is None or not np.size(rigid):
        return weight
    e_rot = np.einsum("tij,tjk->tik", rotation_vector_map(geometry, tp), e[:, 3:])
    proj = rigid_projection(e_pos, e_rot, np.asarray(rigid, dtype=float), geometry)
    return proj.T @ weight @ proj


def accuracy_geometry(geometry: Geometry, poses: ArrayLike | None) -> tuple[Geometry, str]:
    """The geometry whose workspace box the predicted accuracy covers, and the words for it.

    A geometry without a ``workspace:`` box (optional in a geometry file) gets the range of
    ``poses`` (the calibration's own poses) as its box, said as such.

    >>> from hexcal.core import preset
    >>> g, where = accuracy_geometry(preset("paper-hmt").replace(workspace=None), np.eye(6))
    >>> g.workspace[0].tolist(), where
    ([0.0, 1.0], "the calibration poses' range (the geometry has no workspace box)")
    """
    if geometry.workspace is not None or poses is None or not len(poses):
        return geometry, "the workspace"
    arr = np.asarray(poses, dtype=float)
    box = np.stack([arr.min(axis=0), arr.max(axis=0)], axis=1)
    return geometry.replace(workspace=box), "the calibration poses' range (the geometry has no workspace box)"


def accuracy_test_poses(geometry: Geometry, n_random: int = 200, seed: int = 0) -> NDArray[np.float64]:
    """The test poses of the predicted accuracy: the workspace corners and ``n_random`` uniform
    poses (seeded)."""
    return np.concatenate([workspace_corners(geometry), random_poses(geometry, n_random, seed)])


def predicted_instrument_accuracy(
    geometry: Geometry,
    instrument: Any,
    setup: ArrayLike,
    covariance: ArrayLike,
    mask: ArrayLike,
    setup_mask: ArrayLike,
    n_random: int = 200,
    seed: int = 0,
) -> dict[str, float]:
    """RMS and worst predicted error of what the instrument will read after calibration, in its
    own terms: the values it predicts from the leg readings at the test poses
    (:func:`accuracy_test_poses`) against the true ones.

    To first order the prediction misses by ``δy = H_P E δθ + H_s δs`` (``E`` the map of
    :func:`pose_error_map` for the machine parameters of ``mask``, ``H_P`` and ``H_s`` the
    instrument's Jacobians with respect to the pose and to its own parameters of
    ``setup_mask``), whose covariance follows from the parameters' ``covariance`` (machine then
    instrument parameters, parameter units). It does not depend on the gauge convention: a
    gauge changes no prediction. Per noise group of the instrument (``targets``: distance of a
    target, mm; ``position``, mm; ``orientation``, rad): ``{label}_rms_{unit}`` and
    ``{label}_max_{unit}``, and ``poses``.
    """
    poses = accuracy_test_poses(geometry, n_random, seed)
    setup = np.asarray(setup, dtype=float)
    e = pose_error_map(geometry, poses, mask)  # (t, 6, n)
    h_pose = instrument.pose_jacobian(setup, poses, geometry.euler)  # (t, k, 6)
    h_setup = instrument.setup_jacobian(setup, poses, geometry.euler)[:, :, np.asarray(setup_mask, bool)]
    jac = np.concatenate([h_pose @ e, h_setup], axis=2)
    var = np.einsum("tip,pq,tiq->ti", jac, np.asarray(covariance, dtype=float), jac)  # (t, k)
    out: dict[str, float] = {}
    labels = instrument.group_labels()
    for name in instrument.noise_groups():
        probe = {"position": 0.0, "orientation": 0.0} | {name: 1.0}
        values = np.diag(instrument.covariance(NoiseModel(0.0, **probe, distribution="normal"))) != 0
        points = max(int(values.sum()) // 3, 1)  # a position error is a 3D distance per point
        err = np.sqrt(np.clip(var[:, values].sum(axis=1) / points, 0, None))
        label, unit = labels.get(name, name), "rad" if name == "orientation" else "mm"
        out[f"{label}_rms_{unit}"] = float(np.sqrt(np.mean(err**2)))
        out[f"{label}_max_{unit}"] = float(err.max())
    out["poses"] = len(poses)
    return out


def poses_stroke_excess(
    geometry: Geometry,
    poses: ArrayLike,
    margin: float = STROKE_MARGIN,
    ids: Sequence[Any] | None = None,
) -> StrokeExcess | None:
    """How far ``poses (m, 6)`` take legs beyond the calibrated stroke (the readings of the
    geometry's own inverse kinematics, :func:`hexcal.core.stroke_legs.stroke_excess`), or
    ``None`` when the leg model has no stroke. Where they do, every prediction at them is
    made with the model's held curve.

    >>> from hexcal.core import preset
    >>> from hexcal.core.stroke_legs import StrokeLegs, with_leg_model
    >>> narrow = with_leg_model(preset("paper-hmt"), StrokeLegs(3, [150.0] * 6, [300.0] * 6))
    >>> beyond = poses_stroke_excess(narrow, workspace_corners(narrow))
    >>> beyond.rows, beyond.beyond_share, round(float(beyond.share.max()), 2)
    (64, 0.96875, 1.26)
    """
    flat = as_poses(poses).reshape(-1, 6)
    if geometry.leg_model.stroke_range() is None:
        return None
    readings = leg_readings(geometry, inverse_kinematics(geometry, flat))
    return stroke_excess(geometry, readings, margin, ids)


def workspace_stroke_excess(
    geometry: Geometry, n_random: int = 200, seed: int = 0, margin: float = STROKE_MARGIN
) -> StrokeExcess | None:
    """How far the poses of the geometry's workspace box (its corners and ``n_random`` uniform
    poses, seeded: :func:`accuracy_test_poses`) take legs beyond the calibrated stroke;
    ``None`` when the leg model has no stroke or the geometry no workspace box."""
    if geometry.workspace is None or geometry.leg_model.stroke_range() is None:
        return None
    return poses_stroke_excess(geometry, accuracy_test_poses(geometry, n_random, seed), margin)


def predicted_pose_accuracy(
    geometry: Geometry,
    covariance: ArrayLike,
    mask: ArrayLike | None = None,
    n_random: int = 200,
    seed: int = 0,
    rigid: ArrayLike | None = None,
) -> dict[str, Any]:
    """RMS and worst predicted pose error over the workspace after calibration.

    The workspace corners and ``n_random`` uniform poses (seeded) are the test poses of
    :func:`predicted_pose_errors`: ``position_rms_mm``, ``position_max_mm`` (mm),
    ``orientation_rms_rad``, ``orientation_max_rad`` (rad, rotation angle), ``poses``, and for
    a leg model with a stroke ``beyond_stroke`` (:func:`poses_stroke_excess`: how much of the
    prediction the model makes beyond the calibrated stroke, with its held curve).

    >>> from hexcal.core import preset
    >>> acc = predicted_pose_accuracy(preset("paper-hmt"), np.eye(42) * 1e-4)
    >>> acc["poses"], acc["position_rms_mm"] > 0
    (264, True)
    """
    poses = accuracy_test_poses(geometry, n_random, seed)
    position, orientation = predicted_pose_errors(geometry, poses, covariance, mask, rigid)
    out: dict[str, Any] = {
        "position_rms_mm": float(np.sqrt(np.mean(position**2))),
        "position_max_mm": float(position.max()),
        "orientation_rms_rad": float(np.sqrt(np.mean(orientation**2))),
        "orientation_max_rad": float(orientation.max()),
        "poses": len(poses),
    }
    beyond = poses_stroke_excess(geometry, poses)
    if beyond is not None:
        out["beyond_stroke"] = beyond.to_dict()
    return out


def expected_validation(
    geometry: Geometry,
    covariance: ArrayLike,
    sessions: Sequence[tuple[Any, NDArray[np.float64], Any]],
    mask: ArrayLike | None = None,
    rigid: ArrayLike | None = None,
    folds: int = 5,
) -> dict[str, Any]:
    """What ``validate`` should measure on a new session measured like these: the same
    quantities (pose error of the forward kinematics of the readings against the pose the
    instrument gives, leg residuals at that pose), the noise included.

    Parameters
    ----------
    geometry : Geometry
        The calibrated machine.
    covariance : array_like, shape (n, n)
        Covariance of its identified machine parameters (those of ``mask``).
    sessions : sequence of (instrument, poses, noise)
        Each session's calibrated instrument, its poses ``(m, 6)`` (the new session is taken
        to be measured at such poses) and its noise model.
    mask, rigid
        As for :func:`predicted_pose_errors`; the rigid motions are removed as the
        re-registration of the frames removes them.
    folds : int
        The folds of validation's re-registration of instruments with free quantities.

    Returns
    -------
    dict
        ``position_rms_mm``, ``orientation_rms_rad``, ``leg_rms_mm`` (NaN where the instrument
        gives no pose), ``poses``, ``folds`` and ``from_parameters``: the same three figures
        of the parameters' uncertainty alone (no noise).

    Notes
    -----
    At a pose with pose Jacobian ``J`` (leg lengths per pose), error map ``E``
    (:func:`pose_error_map`), leg Jacobian ``A`` and the covariance ``Σp`` of the pose the
    instrument's values give (:meth:`~hexcal.instruments.MeasurementModel.platform_covariance`),
    the pose error ``FK(readings) - pose`` has the covariance
    ``E Σθ Eᵀ + (1 + h) (σ_leg² J⁻¹ J⁻ᵀ + Σp)`` and the leg residual
    ``A Σθ Aᵀ + (1 + h) (σ_leg² I + J Σp Jᵀ)``. ``h = q / (k m (F - 1) / F)`` is the average
    leverage of a cross-validated registration of ``q`` free quantities from ``k`` values per
    pose on ``m (F - 1) / F`` poses (0 when the instrument's quantities are fixed).
    """
    cov = np.asarray(covariance, dtype=float)
    pos2, rot2, leg2, ppos2, prot2, pleg2 = ([] for _ in range(6))
    for instrument, poses, noise in sessions:
        poses = as_poses(poses).reshape(-1, 6)
        e = pose_error_map(geometry, poses, mask)
        w = rotation_vector_map(geometry, poses)
        a = machine_jacobian(geometry, poses, mask)
        e_pos, e_rot = e[:, :3], np.einsum("tij,tjk->tik", w, e[:, 3:])
        own = cov
        if rigid is not None and np.size(rigid):
            own = without_rigid_motions(cov, e_pos, e_rot, np.asarray(rigid, dtype=float), geometry)
        jac = pose_jacobian(geometry, poses)
        jac_inv = np.linalg.inv(jac)
        setup = instrument.parameters().values
        measured = instrument.platform_covariance(setup, poses, noise, geometry.euler)
        free = int(np.sum(instrument.parameters().vary)) if setup.size else 0
        h = free / (instrument.size * len(poses) * (folds - 1) / folds) if free else 0.0
        leg_var = noise.sigmas[0] ** 2
        noise_pose = leg_var * jac_inv @ np.swapaxes(jac_inv, -1, -2) + measured
        noise_leg = leg_var * np.eye(6) + jac @ measured @ np.swapaxes(jac, -1, -2)
        par_pos = np.einsum("tip,pq,tiq->t", e_pos, own, e_pos)
        par_rot = np.einsum("tip,pq,tiq->t", e_rot, own, e_rot)
        par_leg = np.einsum("tip,pq,tiq->t", a, own, a) / 6
        ppos2.append(par_pos)
        prot2.append(par_rot)
        pleg2.append(par_leg)
        pos2.append(par_pos + (1 + h) * np.trace(noise_pose[:, :3, :3], axis1=1, axis2=2))
        rot_noise = w @ noise_pose[:, 3:, 3:] @ np.swapaxes(w, -1, -2)
        rot2.append(par_rot + (1 + h) * np.trace(rot_noise, axis1=1, axis2=2))
        leg2.append(par_leg + (1 + h) * np.trace(noise_leg, axis1=1, axis2=2) / 6)

    def rms(parts: list[NDArray[np.float64]]) -> float:
        return float(np.sqrt(np.mean(np.concatenate(parts))))

    return {
        "position_rms_mm": rms(pos2),
        "orientation_rms_rad": rms(rot2),
        "leg_rms_mm": rms(leg2),
        "poses": int(sum(len(p) for p in pos2)),
        "folds": folds,
        "from_parameters": {
            "position_rms_mm": rms(ppos2),
            "orientation_rms_rad": rms(prot2),
            "leg_rms_mm": rms(pleg2),
        },
    }
