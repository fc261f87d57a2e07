"""Setup files and instrument exports: validation, delimiters, decimal commas, unit rows."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from hexcal.errors import InputError, InputWarning
from hexcal.instruments.setup import Setup
from hexcal.instruments.targets import TargetMeasurements
from hexcal.io.setup_file import load_setup, save_setup
from hexcal.io.target_files import read_target_measurements, read_tool_measurements, write_target_measurements

SETUP = Setup(None, {"t1": [0.0, 0.0, 60.0], "t2": [120.0, 0.0, 60.0]})
HEADER = ["id", "dl1", "dl2", "dl3", "dl4", "dl5", "dl6", "t1.x", "t1.y", "t1.z", "t2.x", "t2.y", "t2.z"]
ROWS = [
    ["p1", "0.5", "-1.25", "2", "0", "0", "0.125", "2500.5", "-800.25", "300", "2620.5", "-800", "301.5"],
    ["p2", "1", "1", "1", "1", "1", "1", "2501.75", "-799.5", "310.125", "", "", ""],
    ["p3", "-1", "0", "0", "0", "0", "0", "", "", "", "2600", "-790.5", "305"],
]


def _write(path, rows, sep=",", decimal=".", units=None, comment=None):
    lines = [f"# {comment}"] if comment else []
    lines.append(sep.join(HEADER))
    if units:
        lines.append(sep.join(units))
    for row in rows:
        lines.append(sep.join(c.replace(".", decimal) for c in row))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_setup_file_round_trip(tmp_path):
    path = tmp_path / "setup.yaml"
    setup = Setup(
        np.array([2500, -800, 300, 0, 0, 0.6]),
        SETUP.targets,
        fixed=("targets",),
        calibration={"stderr": {"t1.x": 0.01}},
    )
    save_setup(setup, path)
    again = load_setup(path)
    np.testing.assert_allclose(again.vector(), setup.vector(), atol=1e-12)
    assert again.calibration == {"stderr": {"t1.x": 0.01}} and again.fixed == ("targets",)


@pytest.mark.parametrize(
    "text, message",
    [
        ("units: mm\ninstrument_frame: auto\n", "needs targets"),
        ("units: mm\ninstrument_frame: auto\ntargets: {t1: [0, 0]}\n", "targets.t1"),
        ("units: [mm\n", "not valid YAML"),
        ("instrument_frame: auto\ntargets: {t1: [0, 0, 0]}\n", "missing units"),
        ("units: mm\ninstrument_frame: auto\ntargets: {T1: [0, 0, 0]}\n", "target name 'T1'"),
    ],
)
def test_malformed_setup_files(tmp_path, text, message):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(InputError, match=message) as err:
        load_setup(path)
    assert str(err.value).startswith(str(path)) and "\n" not in str(err.value)


def test_missing_setup_file(tmp_path):
    with pytest.raises(InputError, match="no such setup file"):
        load_setup(tmp_path / "none.yaml")


@pytest.mark.parametrize("sep, decimal", [(";", ","), ("\t", ","), (";", "."), ("\t", ".")])
def test_exports_read_the_same_as_standard_csv(tmp_path, sep, decimal):
    ref = read_target_measurements(_write(tmp_path / "ref.csv", ROWS), SETUP)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = read_target_measurements(_write(tmp_path / "x.csv", ROWS, sep, decimal), SETUP)
    np.testing.assert_array_equal(got.readings, ref.readings)
    np.testing.assert_array_equal(got.targets, ref.targets)
    assert got.ids == ref.ids == ("p1", "p2", "p3")
    assert np.isnan(ref.targets[1, 1]).all() and np.isnan(ref.targets[2, 0]).all()


def test_unit_row_is_skipped_and_non_mm_refused(tmp_path):
    units = [""] + ["mm"] * 12
    got = read_target_measurements(_write(tmp_path / "u.csv", ROWS, ";", ",", units), SETUP)
    assert len(got) == 3
    bad = [""] + ["mm"] * 6 + ["m"] + ["mm"] * 5
    with pytest.raises(InputError, match=r"line 2, column 't1\.x': unit 'm'"):
        read_target_measurements(_write(tmp_path / "v.csv", ROWS, ";", ",", bad), SETUP)


def test_overrides_that_contradict_the_file_warn(tmp_path):
    path = _write(tmp_path / "x.csv", ROWS, ";", ",")
    with pytest.warns(InputWarning, match="look like decimal commas"):
        with pytest.raises(InputError):
            read_target_measurements(path, SETUP, decimal=".")
    with pytest.raises(InputError, match=r"comma was given .* holds none; the file looks semicolon"):
        read_target_measurements(path, SETUP, delimiter=",")
    got = read_target_measurements(path, SETUP, delimiter=";", decimal=",")
    assert got.targets[0, 0, 0] == 2500.5


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda r: r[0].__setitem__(8, ""), r"line 3, column 't1.y': empty, but target t1"),
        (lambda r: r[0].__setitem__(8, "abc"), r"line 3, column 't1.y': not a number"),
        (lambda r: r[1].__setitem__(1, "x"), r"line 4, column 'dl1': not a number"),
        (lambda r: r[2].__setitem__(slice(10, 13), ["", "", ""]), r"line 5: no target seen"),
        (
            lambda r: r.append(["p4", "0", "0", "0", "0", "0", "0", "", "", "", "", "", ""]),
            r"line 6: no target seen",
        ),
        (lambda r: r[0].pop(), r"line 3: 12 fields, but the header has 13"),
    ],
)
def test_malformed_exports(tmp_path, edit, message):
    rows = [list(r) for r in ROWS]
    edit(rows)
    path = _write(tmp_path / "bad.csv", rows, comment="tracker export")  # line 1; header line 2
    with pytest.raises(InputError, match=message):
        read_target_measurements(path, SETUP)


def test_missing_and_unknown_target_columns(tmp_path):
    path = _write(tmp_path / "x.csv", ROWS)
    one = Setup(None, {"t1": [0.0, 0.0, 60.0]})
    with pytest.raises(InputError, match="target t2 is not in the setup"):
        read_target_measurements(path, one)
    three = Setup(None, {**SETUP.targets, "t3": [0.0, 1.0, 0.0]})
    with pytest.raises(InputError, match=r"missing column 't3\.x'"):
        read_target_measurements(path, three)


def test_write_and_read_back(tmp_path):
    targets = np.array([[[1.5, 2, 3], [np.nan] * 3], [[4, 5, 6], [7, 8, 9.25]]])
    data = TargetMeasurements(np.arange(12.0).reshape(2, 6), targets, ("t1", "t2"), ("a", "b"))
    write_target_measurements(tmp_path / "w.csv", data, comment="simulated")
    again = read_target_measurements(tmp_path / "w.csv", SETUP)
    np.testing.assert_array_equal(again.targets, targets)
    assert again.ids == ("a", "b")


def test_tool_export_with_decimal_commas(tmp_path):
    path = tmp_path / "tool.csv"
    path.write_text("dl1;dl2;dl3;dl4;dl5;dl6;x;y;z;a_deg;b_deg;c_deg\n0;0;0;0;0;0;1,5;2;3;10;0;0\n")
    got = read_tool_measurements(path, "XYZ")
    np.testing.assert_allclose(got.poses[0], [1.5, 2, 3, np.deg2rad(10), 0, 0])


def test_decimal_commas_in_a_comma_separated_file_are_explained(tmp_path):
    path = tmp_path / "x.csv"
    path.write_text("dl1,dl2,dl3,dl4,dl5,dl6,t1.x,t1.y,t1.z\n0,0,0,0,0,0,1,5,2,3\n")
    with pytest.raises(InputError, match="decimal commas in a comma-separated file"):
        read_target_measurements(path, Setup(None, {"t1": [0.0, 0.0, 0.0]}))
