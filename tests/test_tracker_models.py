"""Target and tool models: predictions, Jacobians against finite differences, setup values."""

from __future__ import annotations

import numpy as np
import pytest

from hexcal.errors import InputError, UsageError
from hexcal.instruments.pose import ToolModel
from hexcal.instruments.registry import model_by_name
from hexcal.instruments.setup import Setup
from hexcal.instruments.targets import TargetMeasurements, TargetModel
from tracker_cases import TARGETS3, general_machines

FRAME = np.array([2500.0, -800.0, 300.0, 0.3, -1.1, 2.5])


def _fd(fun, x, h):
    cols = []
    for k in range(len(x)):
        d = np.zeros_like(x)
        d[k] = h[k]
        cols.append((fun(x + d) - fun(x - d)) / (2 * h[k]))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("euler", ["XYZ", "zyx"])
@pytest.mark.parametrize("kind", ["targets", "tool"])
def test_jacobians_match_finite_differences(kind, euler):
    rng = np.random.default_rng(1)
    if kind == "targets":
        model = TargetModel(Setup(FRAME, TARGETS3))
    else:
        model = ToolModel(Setup(FRAME, tool=[10, -20, 60, 0.2, -0.1, 0.4]))
    setup = model.setup.vector()
    poses = np.concatenate([rng.uniform(-200, 200, (4, 3)), rng.uniform(-0.3, 0.3, (4, 3))], axis=1)
    h_pose = np.array([1e-4] * 3 + [1e-7] * 3)
    h_setup = np.concatenate([h_pose, np.full(len(setup) - 6, 1e-4) if kind == "targets" else h_pose])
    pj = model.pose_jacobian(setup, poses, euler)
    sj = model.setup_jacobian(setup, poses, euler)
    for j in range(len(poses)):
        num = _fd(lambda p, j=j: model.predict(setup, p[None], euler)[0], poses[j], h_pose)
        np.testing.assert_allclose(pj[j], num, atol=1e-5 * max(1, np.abs(num).max()))
    num = _fd(lambda s: model.predict(s, poses, euler), setup, h_setup)
    np.testing.assert_allclose(sj, num, atol=1e-5 * np.abs(num).max())


def test_tool_residual_is_well_defined_where_euler_angles_wrap():
    model = ToolModel(Setup(np.zeros(6), tool=np.zeros(6)))
    # orientation c = 179.99 deg measured as -179.99 deg: the Euler difference is ~2π, the residual tiny
    pose = np.array([[0, 0, 700, 0, 0, np.deg2rad(179.99)]])
    obs = np.array([[0, 0, 700, 0, 0, np.deg2rad(-179.99)]])
    res = model.residual(model.setup.vector(), pose, "XYZ", obs)
    assert abs(res[0, 5] + np.deg2rad(0.02)) < 1e-9  # 179.99° is 0.02° short of -179.99°
    assert np.allclose(res[0, :5], 0)


def test_registry_and_parameters():
    assert model_by_name("targets").size == 3 and model_by_name("tool").size == 6
    params = Setup(FRAME, TARGETS3, fixed=("targets",)).parameters()
    assert params.names[:6] == ("frame.x", "frame.y", "frame.z", "frame.a", "frame.b", "frame.c")
    assert params.groups["targets"][:3] == ("t1.x", "t1.y", "t1.z")
    assert params.vary[:6].all() and not params.vary[6:].any()
    assert Setup(FRAME, tool=np.zeros(6)).parameters().groups["tool"][-1] == "tool.c"


def test_setup_round_trip():
    setup = Setup(FRAME, TARGETS3, fixed=("instrument_frame",))
    again = Setup.from_dict(setup.to_dict())
    np.testing.assert_allclose(again.vector(), setup.vector(), atol=1e-12)
    assert again.fixed == ("instrument_frame",)
    assert Setup.from_dict(
        {"units": "mm", "instrument_frame": "auto", "tool": {"x": 0, "y": 0, "z": 1, "a": 0, "b": 0, "c": 0}}
    ).auto


def test_missing_targets_masked_and_empty_pose_refused():
    targets = np.zeros((3, 2, 3))
    targets[1, 0] = np.nan
    data = TargetMeasurements(np.zeros((3, 6)), targets, ("t1", "t2"))
    model = TargetModel(Setup(None, {"t1": [0, 0, 0], "t2": [1, 0, 0]}))
    _, present = model.observed(data)
    assert present.shape == (3, 6) and present.sum() == 15 and not present[1, :3].any()
    targets[2] = np.nan
    with pytest.raises(UsageError, match=r"pose 3 \(row 3\): no target seen"):
        TargetMeasurements(np.zeros((3, 6)), targets, ("t1", "t2"))


@pytest.mark.parametrize(
    "data, message",
    [
        ({"instrument_frame": "auto", "targets": {"t1": [0, 0, 0]}}, "missing units"),
        ({"units": "m", "instrument_frame": "auto", "targets": {"t1": [0, 0, 0]}}, "only mm"),
        (
            {"units": "mm", "instrument_frame": "auto", "targets": {"t1": [0, 0, 0]}, "colour": 1},
            "unknown key 'colour'",
        ),
        ({"units": "mm", "instrument_frame": "auto", "targets": {"p1": [0, 0, 0]}}, "target name 'p1'"),
        (
            {"units": "mm", "instrument_frame": "auto", "targets": {"t1": [0, 0]}},
            r"targets.t1: must be a list",
        ),
        ({"units": "mm", "instrument_frame": "auto", "targets": {"t1": [0, "a", 0]}}, "not a finite number"),
        (
            {
                "units": "mm",
                "instrument_frame": "auto",
                "targets": {"t1": [0, 0, 0]},
                "tool": {"x": 0, "y": 0, "z": 0, "a": 0, "b": 0, "c": 0},
            },
            "not both",
        ),
        ({"units": "mm", "instrument_frame": "auto"}, "needs targets"),
        (
            {"units": "mm", "instrument_frame": "somewhere", "targets": {"t1": [0, 0, 0]}},
            "instrument_frame must be",
        ),
        ({"units": "mm", "instrument_frame": {"x": 0, "y": 0}, "targets": {"t1": [0, 0, 0]}}, "missing z"),
        (
            {
                "units": "mm",
                "instrument_frame": {"x": 0, "y": 0, "z": 0, "a": 0, "b_deg": 0, "c": 0, "d": 1},
                "targets": {"t1": [0, 0, 0]},
            },
            "unknown key 'd'",
        ),
        ({"units": "mm", "targets": {"t1": [0, 0, 0]}}, "missing instrument_frame"),
        (
            {"units": "mm", "instrument_frame": "auto", "targets": {"t1": [0, 0, 0]}, "fixed": ["legs"]},
            "fixed: unknown",
        ),
        (
            {"units": "mm", "instrument_frame": "auto", "targets": {"t1": [0, 0, 0]}, "fixed": ["tool"]},
            "has no tool",
        ),
        ({"units": "mm", "instrument_frame": "auto", "targets": {"t1": [0, 0, 0]}, "euler": "XXY"}, "euler"),
        ([1, 2], "must be a mapping"),
    ],
)
def test_malformed_setups_one_clear_error(data, message):
    with pytest.raises(InputError, match=message):
        Setup.from_dict(data)


def test_general_machine_is_not_symmetric():
    nominal, true = general_machines()
    assert np.abs(true.to_vector() - nominal.to_vector()).max() > 0.5


def test_setup_angles_convert_to_the_geometry_sequence():
    from scipy.spatial.transform import Rotation

    setup = Setup(FRAME, TARGETS3, euler="ZYX")
    moved = setup.in_euler("XYZ")
    assert moved.euler == "XYZ" and setup.in_euler("ZYX") is setup
    a = Rotation.from_euler("ZYX", FRAME[3:]).as_matrix()
    b = Rotation.from_euler("XYZ", moved.frame[3:]).as_matrix()
    np.testing.assert_allclose(a, b, atol=1e-12)
    np.testing.assert_array_equal(moved.frame[:3], FRAME[:3])


@pytest.mark.parametrize("kind", ["targets", "tool", "pose", "ballbar"])
def test_residual_and_pose_jacobian_at_once_are_the_two_alone(kind):
    """The likelihood's pose solve asks an instrument for its residual and whitened pose
    Jacobian at once (:meth:`MeasurementModel.residual_and_pose_jacobian`; a model shares the
    work of the two): exactly what the two methods give alone."""
    from hexcal.instruments.ballbar import BallbarModel
    from hexcal.instruments.ballbar_setup import BallbarSetup
    from hexcal.instruments.pose import FullPoseModel

    rng = np.random.default_rng(3)
    model = {
        "targets": TargetModel(Setup(FRAME, TARGETS3)),
        "tool": ToolModel(Setup(FRAME, tool=[10, -20, 60, 0.2, -0.1, 0.4])),
        "pose": FullPoseModel(),
        "ballbar": BallbarModel(BallbarSetup([0, 0, 750], [0, 0, -50], 150.0)),
    }[kind]
    setup = model.parameters().values
    poses = np.concatenate([rng.uniform(-200, 200, (5, 3)), rng.uniform(-0.3, 0.3, (5, 3))], axis=1)
    observed = model.predict(setup, poses, "XYZ") + rng.normal(0, 0.1, (5, model.size))
    whitener = np.diag(rng.uniform(1, 2, model.size))
    both = model.residual_and_pose_jacobian(setup, poses, "XYZ", observed, whitener)
    np.testing.assert_array_equal(both[0], model.residual(setup, poses, "XYZ", observed))
    np.testing.assert_array_equal(both[1], model.whitened_pose_jacobian(setup, poses, "XYZ", whitener))
