"""Inverse and forward kinematics, the pose Jacobian and the workspace of paper-hmt."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal
from scipy.spatial.transform import Rotation

from hexcal.core.conventions import orientation_error
from hexcal.core.kinematics import (
    forward_kinematics,
    inverse_kinematics,
    leg_lengths,
    leg_readings,
    leg_vectors,
    pose_jacobian,
)
from hexcal.core.presets import preset
from hexcal.core.workspace import is_feasible, random_poses, workspace_corners

PAPER = preset("paper-hmt")
BATCH_SHAPES = [(), (4,), (2, 3)]
HYPOTHESIS = settings(max_examples=60, deadline=None, derandomize=True)


@st.composite
def workspace_poses(draw, geometry=PAPER):
    """A pose inside the geometry's workspace box."""
    box = geometry.workspace
    return np.array([draw(st.floats(lo, hi, allow_nan=False)) for lo, hi in box])


def _poses(batch, seed=0):
    return random_poses(PAPER, math.prod(batch), seed).reshape(batch + (6,))


# -- inverse kinematics ---------------------------------------------------------------


def test_leg_lengths_at_home_by_hand(nominal):
    # paper-hmt.md, Table 1 row 1: s_1 = (92.1597, 84.4488, 0), u_1 = (305.4001, 111.1565, 0);
    # home pose (0, 0, 800, 0, 0, 0), so leg 1 is s_1 + (0, 0, 800) - u_1
    leg1 = math.sqrt((92.1597 - 305.4001) ** 2 + (84.4488 - 111.1565) ** 2 + 800**2)
    lengths = inverse_kinematics(nominal, nominal.home_pose)
    assert lengths.shape == (6,)
    assert lengths[0] == pytest.approx(leg1, abs=1e-10)
    assert leg1 == pytest.approx(828.3627, abs=1e-4)
    # the joints are symmetric (every leg spans 22.5 deg), so all legs agree to the table's rounding
    assert_allclose(lengths, leg1, atol=1e-4)


@pytest.mark.parametrize("batch", BATCH_SHAPES, ids=str)
def test_inverse_kinematics_shapes_and_leg_vectors(nominal, batch):
    poses = _poses(batch)
    lengths = inverse_kinematics(nominal, poses)
    assert lengths.shape == batch + (6,)
    legs = leg_vectors(nominal, poses)
    assert legs.shape == batch + (6, 3)
    assert_allclose(lengths, np.linalg.norm(legs, axis=-1), rtol=0, atol=1e-10)


def test_inverse_kinematics_agrees_with_plain_norm_in_every_convention(nominal):
    # the docstring promises a rounding error of the squared form below 1e-12 mm
    poses = random_poses(nominal, 2000, 1)
    for euler in ("XYZ", "xyz", "ZYX", "zxz"):
        geometry = nominal.replace(euler=euler)
        legs = poses[:, None, :3] + np.einsum(
            "nij,kj->nki", _rotations(poses[:, 3:], euler), geometry.platform_joints
        )
        expected = np.linalg.norm(legs - geometry.base_joints, axis=-1)
        assert_allclose(inverse_kinematics(geometry, poses), expected, rtol=0, atol=1e-12)


def _rotations(angles, euler):
    return Rotation.from_euler(euler, angles).as_matrix()


def test_leg_readings_and_lengths_invert(nominal):
    geometry = nominal.replace(leg_gains=[1.01, 0.99, 1, 1, 1.02, 0.98])
    lengths = inverse_kinematics(geometry, _poses((3,)))
    readings = leg_readings(geometry, lengths)
    assert_allclose(readings, (lengths - 604.8652) / geometry.leg_gains)
    assert_allclose(leg_lengths(geometry, readings), lengths, rtol=0, atol=1e-12)


def test_wrong_pose_shape_raises(nominal):
    with pytest.raises(ValueError, match=r"\(\.\.\., 6\).*\(5,\)"):
        inverse_kinematics(nominal, np.zeros(5))
    with pytest.raises(ValueError, match=r"\(\.\.\., 6\)"):
        pose_jacobian(nominal, np.zeros((3, 7)))
    with pytest.raises(ValueError, match=r"\(\.\.\., 6\)"):
        forward_kinematics(nominal, np.zeros(5))


# -- pose Jacobian ----------------------------------------------------------------------


@pytest.mark.parametrize("batch", BATCH_SHAPES, ids=str)
def test_pose_jacobian_shapes(nominal, batch):
    poses = _poses(batch, 2)
    jac = pose_jacobian(nominal, poses)
    assert jac.shape == batch + (6, 6)
    flat = poses.reshape(-1, 6)
    expected = np.stack([pose_jacobian(nominal, p) for p in flat]).reshape(batch + (6, 6))
    assert_allclose(jac, expected, rtol=0, atol=1e-12)


def _numeric_pose_jacobian(geometry, pose):
    steps = np.array([1e-3, 1e-3, 1e-3, 1e-6, 1e-6, 1e-6])  # mm and rad
    cols = []
    for k in range(6):
        dp = np.zeros(6)
        dp[k] = steps[k]
        diff = inverse_kinematics(geometry, pose + dp) - inverse_kinematics(geometry, pose - dp)
        cols.append(diff / (2 * steps[k]))
    return np.stack(cols, axis=-1)


@HYPOTHESIS
@given(workspace_poses(), st.sampled_from(["XYZ", "xyz", "ZYZ"]))
def test_pose_jacobian_equals_central_differences(pose, euler):
    geometry = PAPER.replace(euler=euler)
    analytic = pose_jacobian(geometry, pose)
    numeric = _numeric_pose_jacobian(geometry, pose)
    # relative to the size of each column (mm/mm columns ~1, mm/rad columns ~100)
    scale = np.max(np.abs(analytic), axis=0)
    assert np.all(np.abs(numeric - analytic) <= 1e-6 * scale)


def test_pose_jacobian_translation_columns_are_unit_legs(nominal):
    poses = _poses((5,), 3)
    legs = leg_vectors(nominal, poses)
    jac = pose_jacobian(nominal, poses)
    assert_allclose(jac[..., :3], legs / np.linalg.norm(legs, axis=-1, keepdims=True), atol=1e-15)


# -- forward kinematics -----------------------------------------------------------------


@pytest.mark.parametrize("batch", BATCH_SHAPES, ids=str)
def test_forward_kinematics_shapes(nominal, batch):
    poses = _poses(batch, 4)
    result = forward_kinematics(nominal, inverse_kinematics(nominal, poses))
    assert result.poses.shape == batch + (6,)
    for name in ("converged", "iterations", "residual"):
        assert getattr(result, name).shape == batch, name
    assert result.all_converged
    assert np.all(result.residual <= 1e-9)
    assert np.all(result.iterations >= 1)
    assert_allclose(result.poses, poses, rtol=0, atol=1e-7)


def test_forward_kinematics_broadcasts_guess_against_lengths(nominal):
    poses = _poses((2, 3), 5)
    lengths = inverse_kinematics(nominal, poses)
    result = forward_kinematics(nominal, lengths, guess=poses[:, :1] * 0 + nominal.home_pose)
    assert result.poses.shape == (2, 3, 6)
    assert_allclose(result.poses, poses, atol=1e-7)


def _assert_round_trip(geometry, pose):
    result = forward_kinematics(geometry, inverse_kinematics(geometry, pose))
    assert result.converged
    assert result.residual <= 1e-9
    assert_allclose(result.poses[:3], pose[:3], rtol=0, atol=1e-7)
    assert_allclose(result.poses[3:], pose[3:], rtol=0, atol=1e-9)
    assert orientation_error(result.poses[3:], pose[3:], geometry.euler) <= 1e-8


@HYPOTHESIS
@given(workspace_poses())
def test_forward_of_inverse_is_identity_default_euler(pose):
    _assert_round_trip(PAPER, pose)


@HYPOTHESIS
@given(workspace_poses(), st.sampled_from(["xyz", "zyx", "YZX"]))
def test_forward_of_inverse_is_identity_other_euler(pose, euler):
    # Tait-Bryan sequences only: a proper Euler sequence (zxz) has no unique angles at the
    # box centre (middle angle 0), so only its rotation, not its angles, comes back
    _assert_round_trip(PAPER.replace(euler=euler), pose)


@HYPOTHESIS
@given(workspace_poses())
def test_forward_of_inverse_proper_euler_gives_the_rotation(pose):
    geometry = PAPER.replace(euler="zxz")
    result = forward_kinematics(geometry, inverse_kinematics(geometry, pose))
    assert result.converged
    assert_allclose(result.poses[:3], pose[:3], rtol=0, atol=1e-7)
    assert orientation_error(result.poses[3:], pose[3:], "zxz") <= 1e-8


@HYPOTHESIS
@given(workspace_poses())
def test_forward_of_inverse_on_the_true_machine(pose):
    _assert_round_trip(preset("paper-hmt-true"), pose)


def test_forward_kinematics_at_every_corner(nominal):
    corners = workspace_corners(nominal)
    result = forward_kinematics(nominal, inverse_kinematics(nominal, corners))
    assert result.all_converged
    assert np.max(result.residual) <= 1e-9
    assert_allclose(result.poses, corners, rtol=0, atol=1e-7)


@pytest.mark.parametrize(
    "lengths",
    [
        # no pose has every leg 1 mm long: the platform hexagon (125 mm radius) cannot cover
        # the base hexagon (325 mm radius)
        np.full(6, 1.0),
        # platform joints are at most 250 mm apart and base joints at most 650 mm, so
        # |l_i - l_j| <= 900 mm for any reachable pose
        np.array([5000.0, 700, 700, 700, 700, 700]),
        np.array([700.0, 700, 700, 2000, 2000, 2000]),
    ],
    ids=["all-1mm", "one-5000mm", "three-2000mm"],
)
def test_forward_kinematics_reports_unreachable_lengths(nominal, lengths):
    result = forward_kinematics(nominal, lengths)
    assert not result.converged
    assert not result.all_converged
    assert np.all(np.isnan(result.poses))
    assert result.residual > 1e-3


def test_forward_kinematics_marks_only_the_unreachable_poses(nominal):
    poses = _poses((3,), 6)
    lengths = inverse_kinematics(nominal, poses)
    lengths[1] = 1.0
    result = forward_kinematics(nominal, lengths)
    assert_array_equal(result.converged, [True, False, True])
    assert np.all(np.isnan(result.poses[1]))
    assert_allclose(result.poses[[0, 2]], poses[[0, 2]], atol=1e-7)


def test_forward_kinematics_all_legs_5000mm_is_a_real_pose(nominal):
    # all legs 5000 mm is geometrically reachable (the platform 4995 mm up, far beyond the leg
    # limits, which forward kinematics does not apply): it must then be a correct pose
    lengths = np.full(6, 5000.0)
    result = forward_kinematics(nominal, lengths)
    if result.converged:
        assert_allclose(inverse_kinematics(nominal, result.poses), lengths, rtol=0, atol=1e-9)
        assert not is_feasible(nominal, result.poses)
    else:
        assert np.all(np.isnan(result.poses))


def test_forward_kinematics_tolerance_and_iteration_limit(nominal):
    pose = workspace_corners(nominal)[37]
    lengths = inverse_kinematics(nominal, pose)
    tight = forward_kinematics(nominal, lengths)
    assert tight.residual <= 1e-9
    assert np.max(np.abs(inverse_kinematics(nominal, tight.poses) - lengths)) <= 1e-9
    # one Newton step from home cannot reach a corner: not converged, and no pose returned
    short = forward_kinematics(nominal, lengths, max_iter=1)
    assert not short.converged
    assert np.all(np.isnan(short.poses))
    assert short.iterations == 1


def test_forward_kinematics_needs_a_guess_without_home_pose(nominal):
    geometry = nominal.replace(home_pose=None)
    lengths = inverse_kinematics(nominal, nominal.home_pose)
    with pytest.raises(ValueError, match="guess"):
        forward_kinematics(geometry, lengths)
    result = forward_kinematics(geometry, lengths, guess=[0, 0, 750, 0, 0, 0])
    assert_allclose(result.poses, nominal.home_pose, atol=1e-7)


# -- workspace ---------------------------------------------------------------------------


def test_workspace_corners(nominal):
    corners = workspace_corners(nominal)
    box = nominal.workspace
    assert corners.shape == (64, 6)
    assert len({tuple(c) for c in corners}) == 64
    on_low, on_high = corners == box[:, 0], corners == box[:, 1]
    assert np.all(on_low | on_high)
    # documented order: x is the most significant bit
    assert_array_equal(corners[0], box[:, 0])
    assert_array_equal(corners[63], box[:, 1])
    assert_array_equal(on_high[32], [True, False, False, False, False, False])
    assert_array_equal(on_high[1], [False, False, False, False, False, True])
    # paper-hmt.md: "All 64 corners of this box keep every leg inside the leg length limits"
    assert np.all(is_feasible(nominal, corners))
    lengths = inverse_kinematics(nominal, corners)
    assert lengths.min() >= 604.8652
    assert lengths.max() <= 1100.0


def test_workspace_needs_a_box(nominal):
    geometry = nominal.replace(workspace=None)
    with pytest.raises(ValueError, match="workspace"):
        workspace_corners(geometry)
    with pytest.raises(ValueError, match="workspace"):
        random_poses(geometry, 3, 0)


def test_random_poses_deterministic_and_inside_the_box(nominal):
    a = random_poses(nominal, 500, 42)
    assert a.shape == (500, 6)
    assert_array_equal(a, random_poses(nominal, 500, 42))
    assert_array_equal(a, random_poses(nominal, 500, np.random.default_rng(42)))
    assert not np.array_equal(a, random_poses(nominal, 500, 43))
    box = nominal.workspace
    assert np.all((a >= box[:, 0]) & (a <= box[:, 1]))
    # they fill the box, not a corner of it
    assert np.all(a.min(axis=0) < box[:, 0] + 0.05 * (box[:, 1] - box[:, 0]))
    assert np.all(a.max(axis=0) > box[:, 1] - 0.05 * (box[:, 1] - box[:, 0]))
    assert random_poses(nominal, 0, 1).shape == (0, 6)


def test_is_feasible(nominal):
    home = nominal.home_pose
    high = home + [0, 0, 400, 0, 0, 0]  # z = 1200 mm: every leg longer than the 1100 mm limit
    assert inverse_kinematics(nominal, high).min() > 1100
    assert is_feasible(nominal, home)
    assert not is_feasible(nominal, high)
    low = home - [0, 0, 400, 0, 0, 0]  # z = 400 mm: legs shorter than l0
    assert not is_feasible(nominal, low)
    assert_array_equal(
        is_feasible(nominal, np.stack([[home, high], [low, home]])), [[True, False], [False, True]]
    )
    # margin: a pose whose longest leg is 0.5 mm too long
    lengths = inverse_kinematics(nominal, high)
    assert is_feasible(nominal, high, margin=lengths.max() - 1100 + 1e-9)
    assert not is_feasible(nominal, high, margin=lengths.max() - 1100 - 1e-6)
    # no limits: everything is feasible
    assert is_feasible(nominal.replace(leg_length_limits=None), high)
