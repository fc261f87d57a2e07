"""Rotation conventions: hexcal's fast rotation matrices against scipy, Euler axes, orientation error."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from hexcal.core.conventions import (
    DEFAULT_EULER,
    POSE_NAMES,
    as_poses,
    check_euler,
    euler_axes,
    orientation_error,
    rotation_matrices,
)

# The 12 valid sequences of scipy (Tait-Bryan and proper Euler), lower case extrinsic, upper intrinsic.
_SEQUENCES = ["".join(p) for p in itertools.product("xyz", repeat=3) if p[0] != p[1] and p[1] != p[2]]
assert len(_SEQUENCES) == 12
ALL_SEQUENCES = _SEQUENCES + [s.upper() for s in _SEQUENCES]
BATCH_SHAPES = [(), (5,), (2, 3)]

HYPOTHESIS = settings(max_examples=60, deadline=None, derandomize=True)
angle = st.floats(-np.pi, np.pi, allow_nan=False)


def test_default_convention_is_intrinsic_xyz():
    # docs/formats.md "Conventions": R = Rx(a) @ Ry(b) @ Rz(c), scipy's "XYZ"
    assert DEFAULT_EULER == "XYZ"
    assert POSE_NAMES == ("x", "y", "z", "a", "b", "c")
    a, b, c = 0.3, -0.2, 0.7
    rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rz = np.array([[np.cos(c), -np.sin(c), 0], [np.sin(c), np.cos(c), 0], [0, 0, 1]])
    assert_allclose(rotation_matrices([a, b, c]), rx @ ry @ rz, atol=1e-15)


@pytest.mark.parametrize("euler", ALL_SEQUENCES)
@pytest.mark.parametrize("batch", BATCH_SHAPES, ids=str)
def test_rotation_matrices_equal_scipy(euler, batch):
    angles = np.random.default_rng(1).uniform(-np.pi, np.pi, batch + (3,))
    got = rotation_matrices(angles, euler)
    assert got.shape == batch + (3, 3)
    expected = Rotation.from_euler(euler, angles.reshape(-1, 3)).as_matrix().reshape(batch + (3, 3))
    assert_allclose(got, expected, rtol=0, atol=1e-14)


def test_rotation_matrices_reject_wrong_shape():
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\)"):
        rotation_matrices(np.zeros(4))
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\)"):
        rotation_matrices(0.5)


def _numeric_rotation_derivatives(angles, euler, h=1e-6):
    out = []
    for k in range(3):
        step = np.zeros(3)
        step[k] = h
        out.append(
            (rotation_matrices(angles + step, euler) - rotation_matrices(angles - step, euler)) / (2 * h)
        )
    return out


def _skew(w):
    return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


@pytest.mark.parametrize("euler", ALL_SEQUENCES)
def test_euler_axes_give_rotation_derivative(euler):
    """dR/dθ_k = [w_k]× R, checked by central differences."""
    rng = np.random.default_rng(2)
    for angles in rng.uniform(-1.2, 1.2, (4, 3)):
        axes = euler_axes(angles, euler)
        assert axes.shape == (3, 3)
        assert_allclose(np.linalg.norm(axes, axis=-1), 1.0, atol=1e-14)
        rot = rotation_matrices(angles, euler)
        for k, numeric in enumerate(_numeric_rotation_derivatives(angles, euler)):
            assert_allclose(_skew(axes[k]) @ rot, numeric, atol=1e-9)


@pytest.mark.parametrize("batch", BATCH_SHAPES, ids=str)
def test_euler_axes_batch_shapes(batch):
    angles = np.random.default_rng(3).uniform(-1, 1, batch + (3,))
    axes = euler_axes(angles, "XYZ")
    assert axes.shape == batch + (3, 3)
    flat = angles.reshape(-1, 3)
    expected = np.stack([euler_axes(a, "XYZ") for a in flat]).reshape(batch + (3, 3))
    assert_allclose(axes, expected, atol=0)


def test_euler_axes_of_intrinsic_xyz_by_hand():
    # R = Rx(a) Ry(b) Rz(c): w1 = e_x, w2 = Rx(a) e_y, w3 = Rx(a) Ry(b) e_z
    a, b, c = 0.4, -0.3, 1.1
    axes = euler_axes([a, b, c], "XYZ")
    assert_allclose(axes[0], [1, 0, 0], atol=1e-15)
    assert_allclose(axes[1], [0, np.cos(a), np.sin(a)], atol=1e-15)
    rxy = Rotation.from_euler("XY", [a, b]).as_matrix()
    assert_allclose(axes[2], rxy[:, 2], atol=1e-15)


@HYPOTHESIS
@given(st.tuples(angle, angle, angle), st.sampled_from(ALL_SEQUENCES))
def test_orientation_error_of_identical_orientations_is_zero(angles, euler):
    assert orientation_error(angles, angles, euler) == pytest.approx(0.0, abs=1e-7)


@HYPOTHESIS
@given(st.tuples(angle, angle, angle), st.tuples(angle, angle, angle), st.sampled_from(ALL_SEQUENCES))
def test_orientation_error_symmetric_and_is_rotation_angle(a, b, euler):
    err = orientation_error(a, b, euler)
    assert err == pytest.approx(orientation_error(b, a, euler), abs=1e-9)
    assert 0.0 <= err <= np.pi + 1e-12
    ra, rb = Rotation.from_euler(euler, a), Rotation.from_euler(euler, b)
    assert err == pytest.approx((ra.inv() * rb).magnitude(), abs=1e-9)


def test_orientation_error_known_angle_and_batch_shapes():
    # a rotation by 0.3 rad about z, whatever the starting orientation, is an error of 0.3 rad
    base = Rotation.from_euler("XYZ", [[0.1, -0.2, 0.3], [0.5, 0.4, -0.6]])
    turned = Rotation.from_euler("z", 0.3) * base
    err = orientation_error(base.as_euler("XYZ"), turned.as_euler("XYZ"))
    assert err.shape == (2,)
    assert_allclose(err, 0.3, atol=1e-12)
    assert orientation_error(np.zeros((2, 3, 3)), np.full((2, 3, 3), 0.01)).shape == (2, 3)
    assert orientation_error(np.zeros(3), np.zeros(3)).shape == ()
    assert orientation_error(np.zeros((0, 3)), np.zeros((0, 3))).shape == (0,)


@pytest.mark.parametrize("euler", ALL_SEQUENCES)
def test_check_euler_accepts_every_scipy_sequence(euler):
    assert check_euler(euler) == euler


@pytest.mark.parametrize("bad", ["XY", "XYZX", "", "XYz", "xYz", "XXY", "xyy", "abc", "XYW", 123, None])
def test_check_euler_rejects_bad_sequences(bad):
    with pytest.raises(ValueError, match="Euler sequence"):
        check_euler(bad)


@pytest.mark.parametrize("bad", ["XYx", "XXY", "XYZW", "xy"])
def test_rotation_functions_reject_invalid_sequences(bad):
    angles = [0.1, 0.2, 0.3]
    with pytest.raises(ValueError):
        Rotation.from_euler(bad, angles)
    with pytest.raises(ValueError, match="Euler sequence"):
        rotation_matrices(angles, bad)
    with pytest.raises(ValueError, match="Euler sequence"):
        euler_axes(angles, bad)


def test_as_poses_checks_the_last_axis():
    assert as_poses([1, 2, 3, 4, 5, 6]).dtype == float
    assert as_poses(np.zeros((2, 3, 6))).shape == (2, 3, 6)
    with pytest.raises(ValueError, match=r"\(\.\.\., 6\).*\(5,\)"):
        as_poses(np.zeros(5))
    with pytest.raises(ValueError, match=r"\(\.\.\., 6\)"):
        as_poses(3.0)


@pytest.mark.parametrize("euler", ["XYZ", "zyx", "ZXZ", "xzx"])
def test_rotation_and_axes_in_one_pass_equal_each_alone(euler):
    """``rotation_and_axes`` (the pose instruments' inner loop) gives exactly
    ``rotation_matrices`` and ``euler_axes`` of the same angles, for any batch shape."""
    from hexcal.core.conventions import euler_axes, rotation_and_axes, rotation_matrices

    angles = np.random.default_rng(2).uniform(-3, 3, (4, 5, 3))
    rot, axes = rotation_and_axes(angles, euler)
    np.testing.assert_array_equal(rot, rotation_matrices(angles, euler))
    np.testing.assert_array_equal(axes, euler_axes(angles, euler))
