"""The Geometry value object, its YAML mapping, parameter vector and the paper presets."""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from numpy.testing import assert_allclose, assert_array_equal

from hexcal.core.geometry import Geometry
from hexcal.core.parameters import (
    N_ALL_PARAMETERS,
    N_BASE_PARAMETERS,
    PARAMETER_GROUPS,
    PARAMETER_LEG,
    PARAMETER_NAMES,
    select_parameters,
)
from hexcal.core.presets import PRESETS, preset
from hexcal.errors import GeometryError

ARRAY_FIELDS = (
    "base_joints",
    "platform_joints",
    "initial_leg_lengths",
    "leg_gains",
    "leg_length_limits",
    "home_pose",
    "workspace",
)
HYPOTHESIS = settings(max_examples=40, deadline=None, derandomize=True)


def assert_same_geometry(a: Geometry, b: Geometry) -> None:
    for name in ARRAY_FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            assert_array_equal(x, y, err_msg=name)
    assert (a.euler, a.name, a.calibration) == (b.euler, b.name, b.calibration)


# -- dict / YAML round trip -------------------------------------------------------


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_dict_round_trip_of_presets_is_exact(name):
    geometry = preset(name)
    data = geometry.to_dict()
    assert_same_geometry(Geometry.from_dict(data), geometry)
    # through YAML text as well (docs/formats.md "Geometry file")
    assert_same_geometry(Geometry.from_dict(yaml.safe_load(yaml.safe_dump(data))), geometry)


def test_to_dict_follows_formats_md(nominal):
    data = nominal.to_dict()
    assert data["units"] == "mm"
    assert data["name"] == "paper-hmt"
    assert data["euler"] == "XYZ"
    assert data["base_joints"][0] == [305.4001, 111.1565, 0.0]
    assert data["platform_joints"][0] == [92.1597, 84.4488, 0.0]
    assert data["initial_leg_lengths"] == [604.8652] * 6
    assert data["leg_gains"] == [1.0] * 6
    assert data["leg_length_limits"] == [604.8652, 1100.0]
    # angles are written in degrees, with the _deg suffix
    assert data["home_pose"] == {"x": 0.0, "y": 0.0, "z": 800.0, "a_deg": 0.0, "b_deg": 0.0, "c_deg": 0.0}
    assert data["workspace"] == {
        "x": [-250.0, 250.0],
        "y": [-250.0, 250.0],
        "z": [700.0, 900.0],
        "a_deg": [-10.0, 10.0],
        "b_deg": [-10.0, 10.0],
        "c_deg": [-10.0, 10.0],
    }


joints = arrays(float, (6, 3), elements=st.floats(-1e3, 1e3, allow_nan=False))
lengths = arrays(float, (6,), elements=st.floats(100, 2000, allow_nan=False))
gains = arrays(float, (6,), elements=st.floats(0.5, 1.5, allow_nan=False))
# angles that a user wrote in degrees (up to 6 decimals)
degrees = st.integers(-180_000_000, 180_000_000).map(lambda k: k / 1e6)


@HYPOTHESIS
@given(
    joints, joints, lengths, gains, st.lists(degrees, min_size=3, max_size=3), st.sampled_from(["XYZ", "zyx"])
)
def test_dict_round_trip_is_exact(base, platform, l0, g, home_deg, euler):
    geometry = Geometry(
        base_joints=base,
        platform_joints=platform,
        initial_leg_lengths=l0,
        leg_gains=g,
        leg_length_limits=[100.0, 2500.5],
        home_pose=[1.5, -2.25, 800.125, *np.deg2rad(home_deg)],
        workspace=np.column_stack(
            [[-1, -2, 3, *np.deg2rad([-5.5, -1, -2])], [1, 2, 4, *np.deg2rad([5.5, 1, 2])]]
        ),
        euler=euler,
        name="random",
        calibration={"method": "paper", "poses": 15},
    )
    data = geometry.to_dict()
    assert_same_geometry(Geometry.from_dict(copy.deepcopy(data)), geometry)
    assert_same_geometry(Geometry.from_dict(yaml.safe_load(yaml.safe_dump(data))), geometry)


def test_angles_in_radians_round_trip_to_rounding(nominal):
    # to_dict writes degrees (rounded to 1e-12 deg), so radians survive only to ~1e-14 rad
    geometry = nominal.replace(home_pose=[0, 0, 800, 0.1, -0.2, 0.3])
    back = Geometry.from_dict(geometry.to_dict())
    assert_allclose(back.home_pose, geometry.home_pose, rtol=0, atol=1e-14)


def test_from_dict_reads_radians_and_degrees(nominal):
    data = nominal.to_dict()
    data["home_pose"] = {"x": 1, "y": 2, "z": 750, "a": 0.1, "b_deg": 5, "c": -0.2}
    data["workspace"] = {
        "x": [-1, 1],
        "y": [-2, 2],
        "z": [700, 800],
        "a": [-0.1, 0.1],
        "b_deg": [-5, 5],
        "c": [0, 0],
    }
    geometry = Geometry.from_dict(data)
    assert_array_equal(geometry.home_pose, [1, 2, 750, 0.1, np.deg2rad(5), -0.2])
    assert_array_equal(geometry.workspace[4], np.deg2rad([-5, 5]))
    assert_array_equal(geometry.workspace[3], [-0.1, 0.1])


def test_from_dict_defaults(nominal):
    data = {
        k: nominal.to_dict()[k] for k in ("units", "base_joints", "platform_joints", "initial_leg_lengths")
    }
    geometry = Geometry.from_dict(data)
    assert geometry.euler == "XYZ"
    assert geometry.name == ""
    assert_array_equal(geometry.leg_gains, np.ones(6))
    assert geometry.leg_length_limits is None
    assert geometry.home_pose is None
    assert geometry.workspace is None
    assert "name" not in geometry.to_dict()


# -- from_dict errors ---------------------------------------------------------------


def _error_message(data) -> str:
    with pytest.raises(GeometryError) as info:
        Geometry.from_dict(data)
    return str(info.value)


@pytest.mark.parametrize("key", ["units", "base_joints", "platform_joints", "initial_leg_lengths"])
def test_from_dict_missing_key(nominal, key):
    data = nominal.to_dict()
    del data[key]
    assert key in _error_message(data)
    assert "missing" in _error_message(data)


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("base_joints", [[0.0, 0.0, 0.0]] * 5),
        ("platform_joints", [[0.0, 0.0]] * 6),
        ("initial_leg_lengths", [600.0] * 7),
        ("leg_gains", [1.0] * 5),
        ("leg_length_limits", [600.0, 900.0, 1100.0]),
    ],
)
def test_from_dict_wrong_shape(nominal, key, value):
    data = nominal.to_dict()
    data[key] = value
    message = _error_message(data)
    assert key in message
    assert "shape" in message


def test_from_dict_rejects_other_units(nominal):
    data = nominal.to_dict()
    data["units"] = "cm"
    message = _error_message(data)
    assert "units" in message
    assert "cm" in message


@pytest.mark.parametrize("where", ["home_pose", "workspace"])
def test_from_dict_rejects_an_angle_in_both_units(nominal, where):
    data = nominal.to_dict()
    data[where]["a"] = data[where]["a_deg"]
    message = _error_message(data)
    assert where in message
    assert "'a'" in message
    assert "'a_deg'" in message


def test_from_dict_rejects_unknown_keys(nominal):
    data = nominal.to_dict()
    data["base_joint"] = data["base_joints"]  # a typo must not pass silently
    assert "base_joint" in _error_message(data)
    data = nominal.to_dict()
    data["home_pose"]["w"] = 0
    message = _error_message(data)
    assert "home_pose" in message
    assert "w" in message


@pytest.mark.parametrize(
    ("key", "value", "words"),
    [
        ("euler", "XYx", ["Euler"]),
        ("leg_length_limits", [1100.0, 600.0], ["leg_length_limits"]),
        ("initial_leg_lengths", [600.0] * 5 + [float("nan")], ["initial_leg_lengths", "NaN"]),
        ("base_joints", "abc", ["base_joints"]),
        (
            "workspace",
            {"x": [1, -1], "y": [0, 0], "z": [0, 0], "a": [0, 0], "b": [0, 0], "c": [0, 0]},
            ["low"],
        ),
    ],
)
def test_from_dict_rejects_bad_values(nominal, key, value, words):
    data = nominal.to_dict()
    data[key] = value
    message = _error_message(data)
    for word in words:
        assert word in message


def test_geometry_error_is_a_value_error():
    assert issubclass(GeometryError, ValueError)
    with pytest.raises(ValueError):
        Geometry.from_dict(["not", "a", "mapping"])


# -- immutability --------------------------------------------------------------------


@pytest.mark.parametrize("name", ARRAY_FIELDS)
def test_arrays_are_read_only(nominal, name):
    arr = getattr(nominal, name)
    assert not arr.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        arr[0] = 1.0


def test_geometry_is_frozen_and_copies_its_inputs(nominal):
    with pytest.raises(dataclasses.FrozenInstanceError):
        nominal.name = "other"
    joints = np.array(nominal.base_joints)
    geometry = nominal.replace(base_joints=joints)
    joints[0, 0] = 1e6
    assert geometry.base_joints[0, 0] == 305.4001
    assert nominal.replace(name="other").name == "other"
    assert nominal.name == "paper-hmt"


def test_calibration_metadata_is_not_shared(nominal):
    given_metadata = {"method": "paper", "poses": 15}
    data = nominal.to_dict()
    data["calibration"] = given_metadata
    geometry = Geometry.from_dict(data)
    given_metadata["method"] = "changed after loading"
    geometry.to_dict()["calibration"]["poses"] = -1
    assert geometry.calibration == {"method": "paper", "poses": 15}


# -- parameter vector ---------------------------------------------------------------


def test_parameter_names_follow_formats_md():
    # docs/formats.md "Conventions": "u1.x u1.y u1.z ... u6.z s1.x ... s6.z l0_1 ... l0_6 g1 ... g6"
    expected = []
    for joint in ("u", "s"):
        for leg in range(1, 7):
            expected += [f"{joint}{leg}.x", f"{joint}{leg}.y", f"{joint}{leg}.z"]
    expected += [f"l0_{leg}" for leg in range(1, 7)]
    expected += [f"g{leg}" for leg in range(1, 7)]
    assert list(PARAMETER_NAMES) == expected
    assert PARAMETER_NAMES[:4] == ("u1.x", "u1.y", "u1.z", "u2.x")
    assert PARAMETER_NAMES[17:19] == ("u6.z", "s1.x")
    assert PARAMETER_NAMES[35:37] == ("s6.z", "l0_1")
    assert PARAMETER_NAMES[41:43] == ("l0_6", "g1")
    assert (N_BASE_PARAMETERS, N_ALL_PARAMETERS, len(PARAMETER_NAMES)) == (42, 48, 48)
    assert [PARAMETER_LEG[PARAMETER_NAMES.index(n)] for n in ("u3.y", "s5.z", "l0_2", "g4")] == [2, 4, 1, 3]


def test_to_vector_layout(true_machine):
    v42, v48 = true_machine.to_vector(), true_machine.to_vector(gains=True)
    assert v42.shape == (42,)
    assert v48.shape == (48,)
    assert_array_equal(v48[:42], v42)
    index = PARAMETER_NAMES.index
    assert v42[index("u3.y")] == true_machine.base_joints[2, 1] == 208.0087
    assert v42[index("s5.z")] == true_machine.platform_joints[4, 2] == -4.8473
    assert v42[index("l0_2")] == true_machine.initial_leg_lengths[1] == 607.2473
    assert v48[index("g4")] == true_machine.leg_gains[3] == 1.0
    params = true_machine.parameters(gains=True)
    assert list(params) == list(PARAMETER_NAMES)
    assert params["u6.x"] == 302.4266
    assert len(true_machine.parameters()) == 42


def test_with_vector_42_keeps_gains_and_48_sets_them(nominal):
    with_gains = nominal.replace(leg_gains=[1.001, 0.999, 1, 1, 1, 1.002])
    delta = np.arange(48) * 0.01
    v42 = with_gains.to_vector() + delta[:42]
    changed = with_gains.with_vector(v42)
    assert_array_equal(changed.to_vector(), v42)
    assert_array_equal(changed.leg_gains, with_gains.leg_gains)
    v48 = with_gains.to_vector(gains=True) + delta
    changed = with_gains.with_vector(v48)
    assert_array_equal(changed.to_vector(gains=True), v48)
    # everything else is kept
    assert_array_equal(changed.workspace, nominal.workspace)
    assert changed.name == nominal.name
    for bad in (np.zeros(41), np.zeros(43), np.zeros((6, 7))):
        with pytest.raises(ValueError, match=r"\(42,\) or \(48,\)"):
            nominal.with_vector(bad)


# -- select_parameters -----------------------------------------------------------------


def test_select_parameters_groups():
    names = np.array(PARAMETER_NAMES)
    assert select_parameters().sum() == 42
    assert_array_equal(select_parameters(), np.arange(48) < 42)
    assert list(names[select_parameters("gains")]) == [f"g{i}" for i in range(1, 7)]
    assert list(names[select_parameters("l0")]) == [f"l0_{i}" for i in range(1, 7)]
    assert list(names[select_parameters("base")]) == list(names[:18])
    assert list(names[select_parameters("platform")]) == list(names[18:36])
    assert_array_equal(select_parameters("joints, l0,gains"), np.ones(48, dtype=bool))
    assert_array_equal(select_parameters(["base", "platform"]), select_parameters("joints"))
    for group, members in PARAMETER_GROUPS.items():
        assert set(names[select_parameters(group)]) == set(members)


def test_select_parameters_fix():
    mask = select_parameters(("joints", "l0"), fix=("u1.x", "l0_6"))
    assert mask.sum() == 40
    assert not mask[PARAMETER_NAMES.index("u1.x")]
    assert not mask[PARAMETER_NAMES.index("l0_6")]
    assert mask[PARAMETER_NAMES.index("u1.y")]


@pytest.mark.parametrize(
    ("fit", "fix", "match"),
    [
        ("joints,offsets", (), "offsets"),
        (("joints",), ("u7.x",), "u7.x"),
        ("l0", tuple(f"l0_{i}" for i in range(1, 7)), "no parameter"),
    ],
)
def test_select_parameters_errors(fit, fix, match):
    with pytest.raises(ValueError, match=match):
        select_parameters(fit, fix)


# -- presets: the seed paper's machine (shared/reference/paper-hmt.md) ---------------------------


def test_nominal_preset_matches_table_1(nominal):
    # rows of Table 1: s_i (x, y, z), u_i (x, y, z), l0_i
    assert_array_equal(nominal.platform_joints[0], [92.1597, 84.4488, 0])
    assert_array_equal(nominal.base_joints[0], [305.4001, 111.1565, 0])
    assert_array_equal(nominal.platform_joints[2], [-119.2146, 37.5882, 0])
    assert_array_equal(nominal.base_joints[4], [-56.4357, -320.0625, 0])
    assert_array_equal(nominal.initial_leg_lengths, [604.8652] * 6)
    assert_array_equal(nominal.leg_gains, np.ones(6))
    # "platform joints on a 125 mm radius at +-42.5, +-77.5, +-162.5 deg; base joints on a 325 mm
    # radius at +-20, +-100, +-140 deg" (to the 4 decimals of the table)
    s, u = nominal.platform_joints, nominal.base_joints
    assert_allclose(np.hypot(s[:, 0], s[:, 1]), 125.0, atol=1e-4)
    assert_allclose(np.hypot(u[:, 0], u[:, 1]), 325.0, atol=1e-4)
    assert_allclose(
        np.degrees(np.arctan2(s[:, 1], s[:, 0])), [42.5, 77.5, 162.5, -162.5, -77.5, -42.5], atol=1e-4
    )
    assert_allclose(np.degrees(np.arctan2(u[:, 1], u[:, 0])), [20, 100, 140, -140, -100, -20], atol=1e-4)


def test_true_preset_matches_table_2(true_machine):
    assert_array_equal(true_machine.platform_joints[0], [96.6610, 81.7602, 1.0684])
    assert_array_equal(true_machine.base_joints[0], [305.2599, 115.0695, 2.6210])
    assert_array_equal(true_machine.platform_joints[3], [-120.6859, -34.4565, -4.9014])
    assert_array_equal(true_machine.base_joints[5], [302.4266, -109.4351, 3.3812])
    assert_array_equal(
        true_machine.initial_leg_lengths, [604.4299, 607.2473, 600.4441, 605.9031, 604.5251, 600.0616]
    )


@pytest.mark.parametrize("name", ["paper-hmt", "paper-hmt-true"])
def test_presets_carry_limits_home_and_workspace(name):
    # paper-hmt.md: limits 604.8652..1100 mm, home (0, 0, 800, 0, 0, 0), box x, y in [-250, 250],
    # z in [700, 900], angles in [-10, 10] deg
    geometry = preset(name)
    assert geometry.name == name
    assert geometry.euler == "XYZ"
    assert_array_equal(geometry.leg_length_limits, [604.8652, 1100.0])
    assert_array_equal(geometry.home_pose, [0, 0, 800, 0, 0, 0])
    ten = np.deg2rad(10)
    assert_array_equal(
        geometry.workspace, [[-250, 250], [-250, 250], [700, 900], [-ten, ten], [-ten, ten], [-ten, ten]]
    )


def test_mean_absolute_difference_of_the_tables(nominal, true_machine):
    # paper-hmt.md: 2.66507 mm over the 42 parameters; the seed paper's Table I "before
    # calibration" prints 2.6652 mm
    diff = np.abs(nominal.to_vector() - true_machine.to_vector())
    assert diff.shape == (42,)
    assert diff.mean() == pytest.approx(2.66507, abs=5e-6)
    assert diff.mean() == pytest.approx(2.6652, abs=2e-4)


def test_presets_are_fresh_objects_and_unknown_names_fail():
    assert preset("paper-hmt") is not preset("paper-hmt")
    with pytest.raises(ValueError, match="paper-hmt"):
        preset("no-such-machine")
