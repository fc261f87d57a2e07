"""File I/O of hexcal (docs/formats.md): geometry YAML, pose/measurement/leg CSV, atomic writes.

Every reader error must be an :class:`hexcal.io.InputError` whose one-line message names the
file and, where it applies, the line and the column.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose, assert_array_equal
from scipy.spatial.transform import Rotation

from hexcal.core.geometry import Geometry
from hexcal.core.presets import PRESETS, preset
from hexcal.errors import InputError, InputWarning
from hexcal.io import (
    QUATERNION_NORM_TOLERANCE,
    atomic_write,
    load_geometry,
    read_legs,
    read_measurements,
    read_poses,
    read_table,
    save_geometry,
    write_legs,
    write_poses,
    write_table,
)

GEOMETRY_ARRAYS = (
    "base_joints",
    "platform_joints",
    "initial_leg_lengths",
    "leg_gains",
    "leg_length_limits",
    "home_pose",
    "workspace",
)
READINGS = ("dl1", "dl2", "dl3", "dl4", "dl5", "dl6")
POSE_HEADER = "x,y,z,a,b,c"


# -- helpers --------------------------------------------------------------------


def write_text(path: Path, text: str) -> Path:
    path.write_bytes(text.encode("utf-8"))
    return path


def csv_text(columns, rows, ids=None, comments=(), sep=",") -> str:
    """A CSV file written by hand, numbers in full precision (repr)."""
    lines = [f"# {c}" for c in comments]
    lines.append(sep.join((["id"] if ids is not None else []) + list(columns)))
    for k, row in enumerate(rows):
        cells = [repr(float(v)) for v in row]
        lines.append(sep.join(([str(ids[k])] if ids is not None else []) + cells))
    return "\n".join(lines) + "\n"


def input_error(func, *args) -> str:
    """The message of the InputError raised by ``func(*args)``."""
    with pytest.raises(InputError) as info:
        func(*args)
    message = str(info.value)
    assert "\n" not in message, "the message must be one line"
    return message


def geometry_dict() -> dict:
    return preset("paper-hmt").to_dict()


def write_yaml(path: Path, data) -> Path:
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def physical_poses(n: int = 9, seed: int = 7) -> np.ndarray:
    """Poses inside the paper machine's workspace (angles within ±10°), mm and rad."""
    rng = np.random.default_rng(seed)
    low = np.array([-250, -250, 700, *np.deg2rad([-10, -10, -10])])
    high = np.array([250, 250, 900, *np.deg2rad([10, 10, 10])])
    return rng.uniform(low, high, size=(n, 6))


def assert_same_geometry(a: Geometry, b: Geometry) -> None:
    for field in GEOMETRY_ARRAYS:
        assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)
    assert a.name == b.name
    assert a.euler == b.euler


# -- geometry YAML ----------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_save_load_round_trip_of_presets_is_exact(tmp_path, name):
    geometry = preset(name)
    path = tmp_path / "g.yaml"
    save_geometry(geometry, path)
    loaded = load_geometry(path)
    assert_same_geometry(loaded, geometry)
    assert loaded.calibration is None
    text = path.read_text(encoding="utf-8")
    assert "units: mm" in text
    assert "a_deg" in text  # angles are written in degrees (docs/formats.md "Geometry file")


def test_save_load_round_trip_of_a_general_geometry(tmp_path):
    rng = np.random.default_rng(3)
    base = preset("paper-hmt")
    geometry = base.replace(
        base_joints=base.base_joints + rng.normal(0, 3, (6, 3)),
        platform_joints=base.platform_joints + rng.normal(0, 3, (6, 3)),
        initial_leg_lengths=base.initial_leg_lengths + rng.normal(0, 3, 6),
        leg_gains=1 + rng.normal(0, 1e-3, 6),
        leg_length_limits=[600.123456789, 1099.987654321],
        home_pose=[1.25, -2.5, 801.125, np.deg2rad(2.0), np.deg2rad(-3.0), np.deg2rad(0.5)],
        euler="zyx",
        name="machine 7",
        calibration={"method": "paper", "poses": 15, "stderr": {"u1.x": 0.0123}},
    )
    path = tmp_path / "calibrated.yaml"
    save_geometry(geometry, path)
    loaded = load_geometry(path)
    assert_same_geometry(loaded, geometry)
    assert loaded.calibration == geometry.calibration


def test_arbitrary_radian_angles_survive_the_degree_round_trip_to_1e_13(tmp_path):
    # angles are stored in degrees rounded to 12 decimals: exact only for round degrees
    geometry = preset("paper-hmt").replace(home_pose=[0, 0, 800, 0.1, -0.0523, 0.17])
    path = tmp_path / "g.yaml"
    save_geometry(geometry, path)
    loaded = load_geometry(path)
    assert_array_equal(loaded.home_pose[:3], geometry.home_pose[:3])
    assert_allclose(loaded.home_pose[3:], geometry.home_pose[3:], rtol=0, atol=1e-13)


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_presets_load_by_name(name):
    loaded = load_geometry(name)
    assert_same_geometry(loaded, preset(name))
    assert loaded.name == name


def test_the_two_paper_presets_differ():
    assert not np.array_equal(
        load_geometry("paper-hmt").base_joints, load_geometry("paper-hmt-true").base_joints
    )


def test_degree_keys_in_yaml_become_radians(tmp_path):
    data = geometry_dict()
    data["home_pose"] = {"x": 1, "y": 2, "z": 800, "a_deg": 5, "b": 0.1, "c_deg": -30}
    data["workspace"] = {
        "x": [-100, 100],
        "y": [-50, 50],
        "z": [700, 900],
        "a_deg": [-5, 5],
        "b": [-0.2, 0.2],
        "c_deg": [-90, 90],
    }
    geometry = load_geometry(write_yaml(tmp_path / "deg.yaml", data))
    assert_allclose(geometry.home_pose, [1, 2, 800, np.deg2rad(5), 0.1, np.deg2rad(-30)], rtol=0, atol=1e-15)
    assert_allclose(geometry.workspace[3], np.deg2rad([-5, 5]), rtol=0, atol=1e-15)
    assert_allclose(geometry.workspace[4], [-0.2, 0.2], rtol=0, atol=0)
    assert_allclose(geometry.workspace[5], [-np.pi / 2, np.pi / 2], rtol=0, atol=1e-15)


def test_yaml_defaults_and_euler_key(tmp_path):
    data = geometry_dict()
    for key in ("leg_gains", "leg_length_limits", "home_pose", "workspace", "name"):
        del data[key]
    data["euler"] = "zyx"
    geometry = load_geometry(write_yaml(tmp_path / "min.yaml", data))
    assert_array_equal(geometry.leg_gains, np.ones(6))
    assert geometry.home_pose is None and geometry.workspace is None and geometry.leg_length_limits is None
    assert geometry.euler == "zyx"


def _mutate(data: dict, case: str) -> dict:
    if case == "missing_key":
        del data["platform_joints"]
    elif case == "wrong_shape":
        data["base_joints"] = data["base_joints"][:5]
    elif case == "units_cm":
        data["units"] = "cm"
    elif case == "unknown_key":
        data["legs"] = 6
    elif case == "not_numeric":
        data["initial_leg_lengths"] = ["a"] * 6
    elif case == "bad_euler":
        data["euler"] = "XXY"
    return data


@pytest.mark.parametrize(
    ("case", "expected"),
    [
        ("missing_key", ["missing required key 'platform_joints'"]),
        ("wrong_shape", ["base_joints", "(6, 3)", "(5, 3)"]),
        ("units_cm", ["units", "'mm'", "'cm'"]),
        ("unknown_key", ["unknown key", "legs"]),
        ("not_numeric", ["initial_leg_lengths", "numeric"]),
        ("bad_euler", ["XXY"]),
    ],
)
def test_load_geometry_errors_name_file_and_problem(tmp_path, case, expected):
    path = write_yaml(tmp_path / f"{case}.yaml", _mutate(geometry_dict(), case))
    message = input_error(load_geometry, path)
    assert message.startswith(str(path))
    for text in expected:
        assert text in message


def test_load_geometry_missing_file(tmp_path):
    path = tmp_path / "nowhere.yaml"
    message = input_error(load_geometry, path)
    assert str(path) in message
    assert "no such geometry file" in message
    assert "paper-hmt" in message  # lists the presets the name was not
    message = input_error(load_geometry, "paper-hmt-typo")
    assert "paper-hmt-typo" in message


def test_load_geometry_invalid_yaml_names_line(tmp_path):
    path = write_text(tmp_path / "bad.yaml", "units: mm\nbase_joints: [[1, 2, 3]\nplatform_joints: x: y\n")
    message = input_error(load_geometry, path)
    assert message.startswith(str(path))
    assert "not valid YAML" in message
    assert "line " in message


@pytest.mark.parametrize("text", ["", "- 1\n- 2\n", "just a string\n"])
def test_load_geometry_not_a_mapping(tmp_path, text):
    path = write_text(tmp_path / "g.yaml", text)
    message = input_error(load_geometry, path)
    assert message.startswith(str(path))
    assert "mapping" in message


def test_input_error_is_a_value_error():
    assert issubclass(InputError, ValueError)
    assert issubclass(InputWarning, UserWarning)


# -- CSV tables: reading -------------------------------------------------------------


def test_read_table_comments_whitespace_and_lines(tmp_path):
    text = "# exported by the tracker\n#units: mm\n\n id , x , y \n a1 , 1.5 ,  2\n\n a2,3,4e1\n"
    table = read_table(write_text(tmp_path / "t.csv", text))
    assert table.columns == ("id", "x", "y")
    assert table.rows == (("a1", "1.5", "2"), ("a2", "3", "4e1"))
    assert table.lines == (5, 7)  # physical line numbers, blank lines counted
    assert_array_equal(table.numbers(["y", "x"]), [[2, 1.5], [40, 3]])
    assert table.ids() == ("a1", "a2")


def test_read_table_bom_and_crlf(tmp_path):
    path = tmp_path / "excel.csv"
    path.write_bytes(b"\xef\xbb\xbfx,y\r\n1,2\r\n3,4\r\n")
    table = read_table(path)
    assert table.columns == ("x", "y")
    assert_array_equal(table.numbers(["x", "y"]), [[1, 2], [3, 4]])


def test_read_poses_comments_spaces_ids_and_extra_columns(tmp_path):
    poses = physical_poses(3)
    lines = ["# target poses", "# second comment line", "id, note, x, y, z, a, b, c, temperature"]
    for k, pose in enumerate(poses):
        cells = ", ".join(repr(float(v)) for v in pose)
        lines.append(f"P{k}, anything, {cells}, 21.5")
    path = write_text(tmp_path / "poses.csv", "\n".join(lines) + "\n")
    read, ids = read_poses(path, "XYZ")
    assert_array_equal(read, poses)
    assert ids == ("P0", "P1", "P2")


def test_row_numbers_are_the_ids_without_id_column(tmp_path):
    poses = physical_poses(4)
    read, ids = read_poses(write_text(tmp_path / "p.csv", csv_text(POSE_HEADER.split(","), poses)), "XYZ")
    assert_array_equal(read, poses)
    assert ids == ("1", "2", "3", "4")


def test_read_measurements(tmp_path):
    poses = physical_poses(5)
    readings = np.random.default_rng(1).uniform(0, 300, (5, 6))
    columns = [*READINGS, *POSE_HEADER.split(",")]
    text = csv_text(columns, np.hstack([readings, poses]), ids=[f"m{k}" for k in range(5)], comments=["m"])
    m = read_measurements(write_text(tmp_path / "m.csv", text), "XYZ")
    assert_array_equal(m.poses, poses)
    assert_array_equal(m.readings, readings)
    assert m.ids == ("m0", "m1", "m2", "m3", "m4")
    assert len(m) == 5


def test_read_legs_groups(tmp_path):
    lengths = np.random.default_rng(2).uniform(700, 900, (3, 6))
    l_cols = [f"l{i}" for i in range(1, 7)]
    only_l = read_legs(write_text(tmp_path / "l.csv", csv_text(l_cols, lengths)))
    assert_array_equal(only_l.lengths, lengths)
    assert only_l.readings is None
    assert only_l.ids == ("1", "2", "3")
    only_dl = read_legs(write_text(tmp_path / "dl.csv", csv_text(READINGS, lengths - 600)))
    assert only_dl.lengths is None
    assert_array_equal(only_dl.readings, lengths - 600)
    path = tmp_path / "both.csv"
    write_legs(path, lengths, lengths - 600, ids=["a", "b", "c"])
    both = read_legs(path)
    assert_allclose(both.lengths, lengths, rtol=1e-14)
    assert_allclose(both.readings, lengths - 600, rtol=1e-14)
    assert both.ids == ("a", "b", "c")


def test_read_legs_without_leg_columns(tmp_path):
    path = write_text(tmp_path / "p.csv", csv_text(POSE_HEADER.split(","), physical_poses(2)))
    message = input_error(read_legs, path)
    assert message.startswith(str(path))
    assert "l1..l6" in message and "dl1..dl6" in message


def test_write_poses_and_tables_read_back(tmp_path):
    poses = physical_poses(6)
    path = tmp_path / "p.csv"
    write_poses(path, poses, ids=[f"q{k}" for k in range(6)], comment="two\nlines")
    assert path.read_text(encoding="utf-8").startswith("# two\n# lines\nid,x,y,z,a,b,c\n")
    read, ids = read_poses(path, "XYZ")
    assert_allclose(read, poses, rtol=1e-14, atol=1e-14)
    assert ids == tuple(f"q{k}" for k in range(6))


# -- orientation variants ------------------------------------------------------------


def _orientation_files(tmp_path: Path, poses: np.ndarray, euler: str, with_readings: bool) -> dict[str, Path]:
    """The same physical poses as rad, deg and quaternion files."""
    angles = poses[:, 3:]
    quat = Rotation.from_euler(euler, angles).as_quat()  # scalar last
    groups = {
        "rad": (("a", "b", "c"), angles),
        "deg": (("a_deg", "b_deg", "c_deg"), np.rad2deg(angles)),
        "quat": (("qx", "qy", "qz", "qw"), quat),
    }
    readings = np.arange(poses.shape[0] * 6, dtype=float).reshape(-1, 6) / 7
    files = {}
    for group, (columns, values) in groups.items():
        data = np.hstack([poses[:, :3], values])
        cols = ["x", "y", "z", *columns]
        if with_readings:
            data, cols = np.hstack([readings, data]), [*READINGS, *cols]
        files[group] = write_text(tmp_path / f"{group}.csv", csv_text(cols, data))
    return files


@pytest.mark.parametrize("euler", ["XYZ", "zyx", "ZYX", "xyz"])
def test_three_orientation_groups_give_the_same_poses(tmp_path, euler):
    poses = physical_poses(12, seed=11)
    files = _orientation_files(tmp_path, poses, euler, with_readings=False)
    for group, path in files.items():
        read, ids = read_poses(path, euler)
        assert_allclose(read[:, :3], poses[:, :3], rtol=0, atol=0, err_msg=group)
        assert_allclose(read[:, 3:], poses[:, 3:], rtol=0, atol=1e-12, err_msg=group)
        assert len(ids) == 12


def test_quaternions_are_read_in_the_requested_sequence(tmp_path):
    poses = physical_poses(5, seed=2)
    path = _orientation_files(tmp_path, poses, "zyx", with_readings=False)["quat"]
    as_xyz, _ = read_poses(path, "XYZ")
    as_zyx, _ = read_poses(path, "zyx")
    assert_allclose(as_zyx[:, 3:], poses[:, 3:], atol=1e-12)
    assert np.max(np.abs(as_xyz[:, 3:] - poses[:, 3:])) > 1e-4  # a different sequence, other angles
    # yet the same physical rotation
    r_xyz = Rotation.from_euler("XYZ", as_xyz[:, 3:]).as_matrix()
    r_zyx = Rotation.from_euler("zyx", as_zyx[:, 3:]).as_matrix()
    assert_allclose(r_xyz, r_zyx, atol=1e-12)


@pytest.mark.parametrize("euler", ["XYZ", "zyx"])
def test_three_orientation_groups_in_measurement_files(tmp_path, euler):
    poses = physical_poses(7, seed=5)
    files = _orientation_files(tmp_path, poses, euler, with_readings=True)
    results = {g: read_measurements(p, euler) for g, p in files.items()}
    for group, m in results.items():
        assert_allclose(m.poses, poses, rtol=0, atol=1e-12, err_msg=group)
        assert_array_equal(m.readings, results["rad"].readings)


def test_quaternion_within_tolerance_is_normalised(tmp_path):
    quat = Rotation.from_euler("XYZ", [0.1, -0.05, 0.02]).as_quat() * (1 + 0.5 * QUATERNION_NORM_TOLERANCE)
    text = csv_text(["x", "y", "z", "qx", "qy", "qz", "qw"], [[0, 0, 800, *quat]])
    poses, _ = read_poses(write_text(tmp_path / "q.csv", text), "XYZ")
    assert_allclose(poses[0, 3:], [0.1, -0.05, 0.02], atol=1e-12)


def test_radian_columns_holding_degrees_warn(tmp_path):
    rows = [[0, 0, 800, 0.01, 0.02, 0.03], [0, 0, 800, 2, -1.8, 1], [0, 0, 800, 0, 0, 0]]
    path = write_text(tmp_path / "oops.csv", csv_text(POSE_HEADER.split(","), rows))
    with pytest.warns(InputWarning) as record:
        poses, _ = read_poses(path, "XYZ")
    message = str(record[0].message)
    assert str(path) in message and "line 3" in message and "a_deg" in message
    assert_array_equal(poses[1, 3:], [2, -1.8, 1])  # within ±π: still read as given
    rows[1][3:] = [10, -5, 2]  # beyond ±π (issue 22): no pose has such angles, refused
    path = write_text(tmp_path / "oops.csv", csv_text(POSE_HEADER.split(","), rows))
    with pytest.raises(InputError, match=r"line 3, column 'a': 10 is beyond ±180° .*a_deg"):
        read_poses(path, "XYZ")


def test_plausible_angles_do_not_warn(tmp_path):
    poses = physical_poses(6)
    files = _orientation_files(tmp_path, poses, "XYZ", with_readings=False)
    deg_path = write_text(tmp_path / "deg90.csv", "x,y,z,a_deg,b_deg,c_deg\n0,0,800,10,-45,89\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for path in [*files.values(), deg_path]:
            read_poses(path, "XYZ")


# -- CSV tables: errors ----------------------------------------------------------------

GOOD_ROW = "1,2,800,0.1,0.2,0.3"


@pytest.mark.parametrize(
    ("name", "text", "expected"),
    [
        ("nan", f"{POSE_HEADER}\n{GOOD_ROW}\n1,2,nan,0,0,0\n", ["line 3", "column 'z'", "finite"]),
        ("inf", f"# c\n{POSE_HEADER}\n{GOOD_ROW}\n1,2,3,0,-inf,0\n", ["line 4", "column 'b'", "finite"]),
        ("word", f"{POSE_HEADER}\n1,2,3,0,0,zero\n", ["line 2", "column 'c'", "not a number", "'zero'"]),
        ("empty_cell", f"{POSE_HEADER}\n1,,3,0,0,0\n", ["line 2", "column 'y'", "not a number"]),
        ("missing_z", "x,y,a,b,c\n1,2,0,0,0\n", ["missing column 'z'"]),
        ("partial_deg", "x,y,z,a_deg,b_deg\n1,2,3,0,0\n", ["missing column 'c_deg'"]),
        ("no_orientation", "x,y,z\n1,2,3\n", ["missing orientation columns"]),
        ("dup_column", f"# c\n# c\n{POSE_HEADER},x\n{GOOD_ROW},1\n", ["line 3", "'x'", "twice"]),
        ("unnamed_column", "x,y,,z,a,b,c\n1,2,3,4,0,0,0\n", ["line 1", "column 3", "no name"]),
        (
            "two_groups",
            "x,y,z,a,b,c,qx,qy,qz,qw\n1,2,3,0,0,0,0,0,0,1\n",
            ["two orientation groups", "qx, qy, qz, qw"],
        ),
        ("rad_and_deg", "x,y,z,a,b,c,a_deg\n1,2,3,0,0,0,0\n", ["two orientation groups"]),
        ("too_many", f"{POSE_HEADER}\n{GOOD_ROW}\n{GOOD_ROW},7\n", ["line 3", "7 fields", "header has 6"]),
        ("too_few", f"#\n{POSE_HEADER}\n1,2,3,4,5\n", ["line 3", "5 fields", "header has 6"]),
        ("empty", "", ["empty file"]),
        ("blank_lines", "\n  \n\n", ["empty file"]),
        ("comments_only", "# nothing\n# here\n", ["empty file"]),
        ("header_only", f"# c\n{POSE_HEADER}\n\n", ["no data rows"]),
        (
            "quat_norm",
            "x,y,z,qx,qy,qz,qw\n0,0,800,0,0,0,1\n0,0,800,0,0,0,1.1\n",
            ["line 3", "qx, qy, qz, qw", "norm 1.1", "not 1"],
        ),
        (
            "quat_just_outside",
            f"x,y,z,qx,qy,qz,qw\n0,0,800,0,0,0,{1 + 2 * QUATERNION_NORM_TOLERANCE!r}\n",
            ["line 2", "quaternion norm"],
        ),
        (
            "dup_id",
            f"id,{POSE_HEADER}\np1,{GOOD_ROW}\np2,{GOOD_ROW}\np1,{GOOD_ROW}\n",
            ["line 4", "'p1'", "line 2"],
        ),
        (
            "empty_id",
            f"id,{POSE_HEADER}\np1,{GOOD_ROW}\n ,{GOOD_ROW}\n",
            ["line 3", "column 'id'", "empty id"],
        ),
    ],
)
def test_pose_file_errors_name_file_line_and_column(tmp_path, name, text, expected):
    path = write_text(tmp_path / f"{name}.csv", text)
    message = input_error(read_poses, path, "XYZ")
    assert message.startswith(str(path))
    for part in expected:
        assert part in message, (part, message)


@pytest.mark.parametrize("missing", ["dl3", "dl6"])
def test_measurement_file_missing_reading_column(tmp_path, missing):
    poses = physical_poses(2)
    columns = [c for c in READINGS if c != missing] + POSE_HEADER.split(",")
    path = write_text(tmp_path / "m.csv", csv_text(columns, np.hstack([np.zeros((2, 5)), poses])))
    message = input_error(read_measurements, path, "XYZ")
    assert message.startswith(str(path))
    assert f"missing column '{missing}'" in message


def test_measurement_file_nan_reading(tmp_path):
    text = f"{','.join(READINGS)},{POSE_HEADER}\n0,0,0,0,0,0,{GOOD_ROW}\n0,0,NaN,0,0,0,{GOOD_ROW}\n"
    path = write_text(tmp_path / "m.csv", text)
    message = input_error(read_measurements, path, "XYZ")
    assert "line 3" in message and "column 'dl3'" in message


def test_leg_file_errors(tmp_path):
    l_cols = ",".join(f"l{i}" for i in range(1, 7))
    path = write_text(tmp_path / "l.csv", f"{l_cols}\n700,700,700,700,700,700\n700,700,700,inf,700,700\n")
    message = input_error(read_legs, path)
    assert message.startswith(str(path)) and "line 3" in message and "column 'l4'" in message
    path = write_text(tmp_path / "l5.csv", "l1,l2,l3,l4,l5\n700,700,700,700,700\n")
    assert "missing column 'l6'" in input_error(read_legs, path)


@pytest.mark.parametrize("reader", ["table", "poses", "measurements", "legs"])
def test_missing_file_and_folder(tmp_path, reader):
    funcs = {
        "table": read_table,
        "poses": lambda p: read_poses(p, "XYZ"),
        "measurements": lambda p: read_measurements(p, "XYZ"),
        "legs": read_legs,
    }
    path = tmp_path / "absent.csv"
    message = input_error(funcs[reader], path)
    assert message.startswith(str(path)) and "no such file" in message
    message = input_error(funcs[reader], tmp_path)
    assert message.startswith(str(tmp_path)) and "folder" in message


def test_undecodable_file(tmp_path):
    path = tmp_path / "latin1.csv"
    path.write_bytes("x,y,z,a,b,c\n1,2,3,0,0,0 \xb0\n".encode("latin-1"))
    message = input_error(read_table, path)
    assert message.startswith(str(path)) and "cannot read" in message


def test_comment_with_an_unbalanced_quote_is_still_a_comment(tmp_path):
    text = f'# operator: J. Doe,"tracker warmed up 30 min\n{POSE_HEADER}\n{GOOD_ROW}\n'
    poses, _ = read_poses(write_text(tmp_path / "p.csv", text), "XYZ")
    assert_array_equal(poses, [[1, 2, 800, 0.1, 0.2, 0.3]])


def test_python_digit_separators_are_not_numbers(tmp_path):
    path = write_text(tmp_path / "p.csv", f"{POSE_HEADER}\n1_0,2,800,0,0,0\n")
    message = input_error(read_poses, path, "XYZ")
    assert "line 2" in message and "column 'x'" in message


# -- atomic writes and untouched inputs ---------------------------------------------------


def test_write_table_into_missing_folder_leaves_nothing(tmp_path):
    target = tmp_path / "missing" / "t.csv"
    message = input_error(write_table, target, ["x"], np.zeros((1, 1)))
    assert str(target) in message and "does not exist" in message
    assert list(tmp_path.iterdir()) == []


def test_save_geometry_into_missing_folder(tmp_path):
    target = tmp_path / "nope" / "g.yaml"
    with pytest.raises(InputError):
        save_geometry(preset("paper-hmt"), target)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("exc_type", [RuntimeError, KeyboardInterrupt])
def test_exception_inside_atomic_write_leaves_no_file(tmp_path, exc_type):
    target = tmp_path / "out.csv"
    with pytest.raises(exc_type):
        with atomic_write(target) as fh:
            fh.write("half a table\n")
            fh.flush()
            assert len(list(tmp_path.iterdir())) == 1  # the temporary file, beside the target
            raise exc_type("stop")
    assert list(tmp_path.iterdir()) == []


def test_exception_inside_atomic_write_keeps_the_old_file(tmp_path):
    target = tmp_path / "out.csv"
    target.write_bytes(b"old,content\n1,2\n")
    with pytest.raises(RuntimeError):
        with atomic_write(target) as fh:
            fh.write("new")
            raise RuntimeError("stop")
    assert target.read_bytes() == b"old,content\n1,2\n"
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]


def test_atomic_write_success_replaces_and_leaves_no_temp(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with atomic_write(target) as fh:
        fh.write("new\n")
        assert target.read_text() == "old"  # not visible before the end
    assert target.read_text() == "new\n"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_write_table_over_existing_folder_fails_cleanly(tmp_path):
    (tmp_path / "taken").mkdir()
    with pytest.raises(OSError):
        write_table(tmp_path / "taken", ["x"], np.zeros((1, 1)))
    assert [p.name for p in tmp_path.iterdir()] == ["taken"]
    assert list((tmp_path / "taken").iterdir()) == []


def test_written_files_get_the_usual_permissions(tmp_path):
    old = os.umask(0o022)
    try:
        write_table(tmp_path / "t.csv", ["x"], np.zeros((1, 1)))
        save_geometry(preset("paper-hmt"), tmp_path / "g.yaml")
    finally:
        os.umask(old)
    assert (tmp_path / "t.csv").stat().st_mode & 0o777 == 0o644
    assert (tmp_path / "g.yaml").stat().st_mode & 0o777 == 0o644


def test_reading_leaves_input_files_unchanged(tmp_path):
    poses = physical_poses(4)
    files = _orientation_files(tmp_path, poses, "XYZ", with_readings=True)
    leg_path = tmp_path / "legs.csv"
    write_legs(leg_path, np.full((2, 6), 800.0), np.full((2, 6), 195.1348))
    yaml_path = tmp_path / "g.yaml"
    save_geometry(preset("paper-hmt"), yaml_path)
    paths = [*files.values(), leg_path, yaml_path]
    before = {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in paths}
    for path in files.values():
        read_measurements(path, "XYZ")
        read_poses(path, "zyx")
        read_table(path)
    read_legs(leg_path)
    load_geometry(yaml_path)
    after = {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in paths}
    assert after == before
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in paths)


def test_table_text_is_what_the_csv_module_writes(tmp_path):
    """The block writer writes exactly what csv.writer with format(v, '.15g') wrote before."""
    import csv
    import io

    rng = np.random.default_rng(4)
    data = rng.normal(0, 1, (40, 3)) * 10.0 ** rng.integers(-20, 20, (40, 3))
    data[0] = [-0.0, 0.0, 1e300]
    data[1] = [0.1 + 0.2, 123456789012345678.0, -5e-324]
    ids = [f"p{k}" for k in range(40)]
    ids[2], ids[3], ids[4] = "with,comma", 'with "quote"', " spaced "
    expected = io.StringIO()
    expected.write("# a\n# b\n")
    writer = csv.writer(expected, lineterminator="\n")
    writer.writerow(["id", "u", "v,w", "x"])
    for k, row in enumerate(data):
        writer.writerow([ids[k]] + [format(float(v), ".15g") for v in row])
    write_table(tmp_path / "t.csv", ["u", "v,w", "x"], data, ids, comment="a\nb")
    assert (tmp_path / "t.csv").read_text(encoding="utf-8") == expected.getvalue()
    read = read_table(tmp_path / "t.csv")
    assert read.ids()[2:5] == ("with,comma", 'with "quote"', "spaced")


def test_measurement_files_have_a_lower_row_limit_than_other_tables():
    from hexcal.io import DEFAULT_MAX_ROWS, MEASUREMENT_MAX_ROWS

    assert MEASUREMENT_MAX_ROWS == 100_000 < DEFAULT_MAX_ROWS == 1_000_000
