"""One reader policy for every table (issue 22) and column maps (issue 19, item 4), library level.

Every reader function (measurement, pose, leg files whole and in blocks, target and tool
exports, the generic tables) detects the delimiter and the decimal mark and honours
``delimiter=``/``decimal=``; unit rows, thousands separators, oversized fields and the row
limit are refused with one line naming file, line and column; ``columns=`` maps hexcal's
names to the file's, and the messages keep the file's names. Nothing read is changed.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hexcal.errors import HexcalError, InputError, InputWarning, UsageError
from hexcal.instruments.setup import Setup
from hexcal.io import (
    COLUMN_NAMES,
    MAX_FIELD_CHARS,
    check_column_map,
    iter_legs,
    iter_poses,
    iter_tables,
    parse_column_map,
    read_legs,
    read_measurements,
    read_poses,
    read_table,
    read_target_measurements,
    read_tool_measurements,
)

SETUP = Setup(None, {"t1": [0.0, 0.0, 60.0]})
READINGS = [f"dl{i}" for i in range(1, 7)]
MEASURED = ["id", *READINGS, "x", "y", "z", "a_deg", "b_deg", "c_deg"]
ROWS = [
    ["p1", "0.5", "-1.25", "2", "0", "0", "0.125", "12.5", "-80.25", "800", "1.5", "0", "-2.75"],
    ["p2", "1", "1", "1", "1", "1", "1", "2.75", "-7.5", "810.125", "0", "0.5", "0"],
]
JUGGLEBOT = Path(__file__).resolve().parent / "data" / "jugglebot" / "session1_108_poses.csv"
JUGGLEBOT_MAP = (
    ",".join(f"dl{i}=leg_length_{i}" for i in range(1, 7))
    + ",x=position_x,y=position_y,z=position_z"
    + ",qx=orientation_x,qy=orientation_y,qz=orientation_z,qw=orientation_w"
)


def _write(path: Path, header, rows, sep=",", decimal=".", units=None) -> Path:
    lines = [sep.join(header)] + ([sep.join(units)] if units else [])
    lines += [sep.join(c.replace(".", decimal) for c in row) for row in rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _one_line(info) -> str:
    message = str(info.value)
    assert message and "\n" not in message and len(message) < 400, message
    return message


def _readers(kind: str):
    """Every reader of a file kind, as functions of (path, **table options)."""
    return {
        "measurements": [
            lambda p, **o: read_measurements(p, "XYZ", **o),
            lambda p, **o: read_table(p, **o),
            lambda p, **o: list(iter_tables(p, 1, **o)),
        ],
        "poses": [
            lambda p, **o: read_poses(p, "XYZ", **o),
            lambda p, **o: list(iter_poses(p, "XYZ", 1, **o)),
        ],
        "legs": [lambda p, **o: read_legs(p, **o), lambda p, **o: list(iter_legs(p, 1, **o))],
        "targets": [lambda p, **o: read_target_measurements(p, SETUP, **o)],
        "tool": [lambda p, **o: read_tool_measurements(p, "XYZ", **o)],
    }[kind]


def _case(tmp_path: Path, kind: str, sep: str, decimal: str, units=None) -> Path:
    """A small file of each kind in a given dialect."""
    if kind in ("measurements", "tool"):
        return _write(tmp_path / f"{kind}.csv", MEASURED, ROWS, sep, decimal, units)
    if kind == "poses":
        return _write(
            tmp_path / "p.csv", MEASURED[:1] + MEASURED[7:], [r[:1] + r[7:] for r in ROWS], sep, decimal
        )
    if kind == "legs":
        return _write(tmp_path / "l.csv", MEASURED[:7], [r[:7] for r in ROWS], sep, decimal)
    header = [*MEASURED[:7], "t1.x", "t1.y", "t1.z"]
    return _write(tmp_path / "t.csv", header, [r[:7] + r[7:10] for r in ROWS], sep, decimal, units)


def _values(result) -> list[np.ndarray]:
    if isinstance(result, list):
        return [v for r in result for v in _values(r)]
    if isinstance(result, tuple):  # poses and ids
        return [np.asarray(result[0])]
    if hasattr(result, "targets"):
        return [result.readings, np.nan_to_num(result.targets)]
    if hasattr(result, "poses"):
        return [result.poses, result.readings]
    if hasattr(result, "readings"):
        return [result.readings]
    return [result.numbers([c for c in result.columns if c != "id"])]


KINDS = ["measurements", "poses", "legs", "targets", "tool"]


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize(("sep", "decimal"), [(";", ","), ("\t", ","), (";", "."), ("\t", ".")])
def test_every_reader_detects_the_dialect(tmp_path, kind, sep, decimal):
    for reader in _readers(kind):
        plain = _values(reader(_case(tmp_path, kind, ",", ".")))
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            got = _values(reader(_case(tmp_path, kind, sep, decimal)))
        for a, b in zip(got, plain, strict=True):
            np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("kind", KINDS)
def test_every_reader_honours_the_given_delimiter_and_decimal_mark(tmp_path, kind):
    path = _case(tmp_path, kind, ";", ",")
    for reader in _readers(kind):
        assert _values(reader(path, delimiter=";", decimal=","))  # as detected: read, no warning
        with pytest.warns(InputWarning, match="look like decimal commas"):
            with pytest.raises(InputError, match="has a decimal comma") as info:
                _values(reader(path, decimal="."))  # honoured: read with points, so refused
        assert str(path) in _one_line(info)
        with pytest.raises(InputError, match=r"tab was given .* holds none; the file looks semicolon"):
            _values(reader(path, delimiter="\t"))  # one line naming the option, no warning


def test_a_comma_cannot_be_both_and_odd_options_are_refused(tmp_path):
    path = _case(tmp_path, "poses", ",", ".")
    with pytest.raises(InputError, match="both the delimiter and the decimal mark"):
        read_poses(path, "XYZ", decimal=",")
    with pytest.raises(InputError, match="delimiter must be"):
        read_poses(path, "XYZ", delimiter="|")
    with pytest.raises(InputError, match="decimal mark must be"):
        read_poses(path, "XYZ", decimal="'")


@pytest.mark.parametrize("kind", ["measurements", "targets", "tool"])
@pytest.mark.parametrize(
    ("column", "unit", "expected"),
    [
        ("x", "[deg]", "only mm"),
        ("dl2", "rad", "only mm"),
        ("x", "m", "only mm"),
        ("a_deg", "rad", "only deg"),
    ],
)
def test_unit_rows_are_checked_per_column(tmp_path, kind, column, unit, expected):
    header = MEASURED if kind != "targets" else [*MEASURED[:7], "t1.x", "t1.y", "t1.z"]
    column = column if kind != "targets" or column in READINGS else "t1.x"
    if kind == "targets" and expected == "only deg":
        return
    units = ["[mm]" if c in READINGS or c in "xyz" or c.startswith("t1") else "deg" for c in header]
    units[0] = ""
    path = _case(tmp_path, kind, ";", ",", units)
    reader = _readers(kind)[0]
    assert _values(reader(path))  # a right unit row is skipped
    units[header.index(column)] = unit
    path = _case(tmp_path, kind, ";", ",", units)
    with pytest.raises(
        InputError, match=re.escape(f"line 2, column '{column}': unit '{unit}'; {expected}")
    ) as info:
        reader(path)
    assert _one_line(info).startswith(str(path))


def test_radian_columns_with_a_degree_unit_and_short_unit_rows_are_refused(tmp_path):
    path = tmp_path / "p.csv"
    path.write_text("x;y;z;a;b;c\nmm;mm;mm;deg;deg;deg\n1;2;800;0;0;0\n")
    with pytest.raises(InputError, match=r"column 'a': unit 'deg'; only rad here \(name the columns a_deg"):
        read_poses(path, "XYZ")
    path.write_text("x;y;z;a;b;c\nmm;mm;mm\n1;2;800;0;0;0\n")
    with pytest.raises(InputError, match="line 2: the unit row has 3 fields, but the header has 6") as info:
        read_poses(path, "XYZ")
    _one_line(info)
    path.write_text("x;y;z;a;b;c\nmm;mm;mm;rad;rad;rad;mm\n1;2;800;0;0;0\n")
    with pytest.raises(InputError, match="the unit row has 7 fields"):
        read_poses(path, "XYZ")
    path.write_text("id;x;y;z;a;b;c\n-;mm;mm;mm;rad;rad;rad\np1;1;2;800;0;0;0\n")
    assert read_poses(path, "XYZ")[1] == ("p1",)


@pytest.mark.parametrize(
    ("sep", "cell", "expected"),
    [
        (";", "1.234,5", "'1.234,5' has a thousands separator"),
        (";", "1,234.5", "'1,234.5' has a thousands separator"),
        ("\t", "-12.345.678,5", "thousands separator"),
        (";", "1.234", "'1.234' has a point, but the numbers of this file have decimal commas"),
        (",", "1,234.5", "8 fields, but the header has 7 (decimal commas in a comma-separated file"),
    ],
)
def test_thousands_separators_are_refused_not_misread(tmp_path, sep, cell, expected):
    mark = "0,5" if sep != "," else "0.5"
    rows = [["p1", mark, mark, "800", mark, "0", "0"], ["p2", cell, "2", "800", "0", "0", "0"]]
    path = tmp_path / "p.csv"
    path.write_text("\n".join(sep.join(r) for r in [MEASURED[:1] + MEASURED[7:], *rows]) + "\n")
    for reader in _readers("poses"):
        with pytest.raises(InputError, match=expected.replace("(", r"\(").replace(".", r"\.")) as info:
            _values(reader(path))
        assert "line 3" in _one_line(info)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.floats(-1e7, 1e7, allow_nan=False).map(lambda v: round(v, 3)), min_size=1, max_size=6))
def test_european_numbers_are_read_exactly_or_refused(tmp_path, values):
    """1.234.567,125 style cells: refused with one line, or (no separator needed) read exactly."""
    cells = [f"{v:,.3f}".replace(",", "_").replace(".", ",").replace("_", ".") for v in values]
    path = tmp_path / "eu.csv"
    path.write_text("id;x;y;z;a;b;c\n" + "".join(f"p{k};{c};0;800;0;0;0\n" for k, c in enumerate(cells)))
    try:
        poses, _ = read_poses(path, "XYZ")
    except InputError as exc:
        assert "\n" not in str(exc) and "line" in str(exc)
        assert any(abs(v) >= 1000 for v in values)  # only a thousands separator is refused
    else:
        np.testing.assert_array_equal(poses[:, 0], values)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("quoted", [False, True])
def test_a_field_of_200000_characters_is_one_line(tmp_path, kind, quoted):
    path = _case(tmp_path, kind, ",", ".")
    lines = path.read_text().splitlines()
    long = "1" * 200_000
    cells = lines[2].split(",")
    cells[1] = f'"{long}"' if quoted else long
    lines[2] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    for reader in _readers(kind):
        with pytest.raises(InputError) as info:
            _values(reader(path))
        message = _one_line(info)
        assert "line 3" in message and f"{MAX_FIELD_CHARS:,}" in message and long[:100] not in message


def test_a_long_header_or_an_endless_line_is_one_line(tmp_path):
    path = tmp_path / "h.csv"
    path.write_text("x" * 200_000 + ",y\n1,2\n")
    with pytest.raises(InputError, match="line 1: a header of 200,002 characters") as info:
        read_table(path)
    _one_line(info)


def test_target_exports_honour_the_row_limit_while_reading(tmp_path):
    path = tmp_path / "big.csv"  # 150,000 rows, 14 MB: the limit is met in the fourth 4 MB chunk
    header = ";".join([*MEASURED[:7], "t1.x", "t1.y", "t1.z"])
    with path.open("w") as fh:
        fh.write(header + "\n" + "".join(f"p{k:032d};0;0;0;0;0;0;1,5;2;3\n" for k in range(150_000)))
        fh.write("p;\n")  # never reached: refused by the limit first, not by this line
    with pytest.raises(
        InputError, match="more than 100,000 data rows, the limit; raise it with --max-rows"
    ) as info:
        read_target_measurements(path, SETUP)
    _one_line(info)
    with pytest.raises(InputError, match="more than 10 data rows"):
        read_tool_measurements(path, "XYZ", max_rows=10)


def test_parse_column_map():
    assert parse_column_map(" x = position_x ,y=Position Y") == {"x": "position_x", "y": "Position Y"}
    assert parse_column_map(JUGGLEBOT_MAP)["qw"] == "orientation_w"
    assert parse_column_map("t12.z=T12 Z") == {"t12.z": "T12 Z"}
    for spec, expected in [
        ("X=position_x", "unknown hexcal column 'X'"),
        ("x=position_x,y=position_x", "file column 'position_x' is mapped twice"),
        ("x=a,x=b", "x is given twice"),
        ("x", "'x' is not hexcal_name=file_column"),
        ("x=", "'x=' is not hexcal_name=file_column"),
        ("x=a=b", "is not hexcal_name=file_column"),
        (" , ", "empty"),
    ]:
        with pytest.raises(UsageError, match=expected) as info:
            parse_column_map(spec)
        assert str(info.value).startswith("column map: ") and "\n" not in str(info.value)
    assert issubclass(UsageError, ValueError) and set(COLUMN_NAMES) >= {"id", "dl6", "qw", "c_deg", "l1"}
    with pytest.raises(UsageError, match="unknown hexcal column 'speed'"):
        check_column_map({"speed": "v"})


def _mocap(tmp_path: Path, rows: int = 3, bad: str | None = None) -> Path:
    header = [f"leg_length_{i}" for i in range(1, 7)] + ["position_x", "position_y", "position_z"]
    header += ["orientation_x", "orientation_y", "orientation_z", "orientation_w"]
    lines = [",".join(header)]
    for k in range(rows):
        lines.append(",".join([f"{1.5 + k / 10}"] * 6 + ["5.6", "-2.3", f"{751 + k}", "0", "0", "0", "1"]))
    if bad:
        lines[2] = lines[2].replace("-2.3", bad)
    path = tmp_path / "mocap.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_column_map_reads_real_files_as_they_come(tmp_path):
    path, columns = _mocap(tmp_path), parse_column_map(JUGGLEBOT_MAP)
    data = read_measurements(path, "XYZ", columns=columns)
    np.testing.assert_array_equal(data.readings[:, 0], [1.5, 1.6, 1.7])
    np.testing.assert_array_equal(data.poses[:, :3], [[5.6, -2.3, 751], [5.6, -2.3, 752], [5.6, -2.3, 753]])
    assert data.ids == ("1", "2", "3")
    poses = [p for p, _ in iter_poses(path, "XYZ", 2, columns=columns)]
    np.testing.assert_array_equal(np.concatenate(poses), data.poses)
    legs = {f"dl{i}": f"leg_length_{i}" for i in range(1, 7)}
    np.testing.assert_array_equal(read_legs(path, columns=legs).readings, data.readings)
    assert [len(b.ids) for b in iter_legs(path, 2, columns=legs)] == [2, 1]
    np.testing.assert_array_equal(read_tool_measurements(path, "XYZ", columns=columns).poses, data.poses)
    with pytest.raises(InputError, match="missing leg columns"):
        read_legs(path)  # without the map the file's names mean nothing to hexcal


def test_column_map_messages_name_the_files_columns(tmp_path):
    columns = parse_column_map(JUGGLEBOT_MAP)
    with pytest.raises(InputError, match=r"line 3, column 'position_y': not a number: 'oops'") as info:
        read_measurements(_mocap(tmp_path, bad="oops"), "XYZ", columns=columns)
    _one_line(info)
    with pytest.raises(InputError, match=r"line 1: no column 'leg_length_9' \(the column map's dl1\)"):
        read_measurements(_mocap(tmp_path), "XYZ", columns={**columns, "dl1": "leg_length_9"})
    path = tmp_path / "both.csv"
    path.write_text("x,position_x,y,z,a,b,c\n1,2,3,800,0,0,0\n")
    with pytest.raises(InputError, match="columns 'x' and 'position_x' would both be x"):
        read_poses(path, "XYZ", columns={"x": "position_x"})
    path.write_text("X,Y,Z,QX,QY,QZ,QW\n0,0,800,0,0,0,1.1\n")
    quat = {"x": "X", "y": "Y", "z": "Z", "qx": "QX", "qy": "QY", "qz": "QZ", "qw": "QW"}
    with pytest.raises(InputError, match=r"columns 'QX, QY, QZ, QW': quaternion norm 1\.1"):
        read_poses(path, "XYZ", columns=quat)
    path.write_text("X,Y,Z,QX,QY,QZ\n0,0,800,0,0,0\n")
    with pytest.raises(InputError, match=r"no column 'QW' \(the column map's qw\)"):
        read_poses(path, "XYZ", columns=quat)


def test_a_column_map_for_target_exports(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text(
        "Pose;" + ";".join(f"L{i}" for i in range(1, 7)) + ";T1 X;T1 Y;T1 Z\nA;0;0;0;0;0;0;1,5;;3\n"
    )
    columns = {
        "id": "Pose",
        **{f"dl{i}": f"L{i}" for i in range(1, 7)},
        "t1.x": "T1 X",
        "t1.y": "T1 Y",
        "t1.z": "T1 Z",
    }
    with pytest.raises(InputError, match="line 2, column 'T1 Y': empty, but target t1 has other coordinates"):
        read_target_measurements(path, SETUP, columns=columns)
    path.write_text(path.read_text().replace("1,5;;3", "1,5;2;3"))
    data = read_target_measurements(path, SETUP, columns=columns)
    np.testing.assert_array_equal(data.targets[0, 0], [1.5, 2, 3])
    assert data.ids == ("A",)


def test_the_real_motion_capture_session_is_read_with_its_own_columns():
    before = JUGGLEBOT.read_bytes()
    data = read_measurements(JUGGLEBOT, "XYZ", columns=parse_column_map(JUGGLEBOT_MAP))
    assert len(data) == 108 and np.all(np.isfinite(data.poses)) and np.all(np.isfinite(data.readings))
    assert 700 < data.poses[:, 2].mean() < 800  # mm
    assert JUGGLEBOT.read_bytes() == before


def test_readers_leave_every_file_unchanged_and_raise_only_hexcal_errors(tmp_path):
    files = [_case(tmp_path, k, ";", ",") for k in KINDS] + [_mocap(tmp_path, bad="1.234,5")]
    before = {p: p.read_bytes() for p in files}
    for path in files:
        for kind in KINDS:
            for reader in _readers(kind):
                try:
                    reader(path)
                except HexcalError:
                    pass
    assert {p: p.read_bytes() for p in files} == before


@pytest.mark.parametrize("ending", ["\r\n", "\n"])
def test_large_files_read_the_same_in_blocks_and_whole(tmp_path, ending):
    """Thousands of rows: the chunk-as-a-block path, with CRLF or LF line ends, and ids with points."""
    rng = np.random.default_rng(5)
    poses = np.round(rng.uniform(-200, 200, (5000, 6)) / [1, 1, 1, 1000, 1000, 1000], 6)
    text = "id;x;y;z;a;b;c" + ending
    text += "".join(
        f"p.{k};" + ";".join(repr(float(v)).replace(".", ",") for v in p) + ending
        for k, p in enumerate(poses)
    )
    path = tmp_path / "big.csv"
    path.write_bytes(text.encode())
    whole, ids = read_poses(path, "XYZ")
    np.testing.assert_array_equal(whole, poses)
    assert ids[:2] == ("p.0", "p.1") and len(set(ids)) == 5000
    blocks = list(iter_poses(path, "XYZ", 777))
    np.testing.assert_array_equal(np.concatenate([b[0] for b in blocks]), poses)
    assert sum((b[1] for b in blocks), ()) == ids
    bad = text.replace(f"p.4321;{repr(float(poses[4321, 0])).replace('.', ',')}", "p.4321;1.234,5")
    path.write_bytes(bad.encode())
    with pytest.raises(InputError, match=r"line 4323, column 'x': '1\.234,5' has a thousands separator"):
        list(iter_poses(path, "XYZ", 1000))
