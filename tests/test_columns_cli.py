"""``--columns`` and a setup's ``columns:`` through the command line (issue 19, item 4).

Every command that reads a measurement, pose or leg table takes ``--columns``; a bad spec is a
usage error (exit 2) naming the option and the item; a mapped column missing from the file, an
unknown hexcal name and two names for one column are one line each; a setup's ``columns:`` is
merged with ``--columns``, the option winning (said in one warning line). ``identify`` and
``validate`` without ``--setup`` honour ``--delimiter`` and ``--decimal``. The files are the real
Jugglebot sessions of ``tests/data/jugglebot`` (legs in revolutions, gains in mm per revolution).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from hexcal.cli import main

DATA = Path(__file__).parent / "data" / "jugglebot"
SESSION, GEOMETRY, SETUP = DATA / "session2_60_poses.csv", DATA / "jugglebot.yaml", DATA / "mocap.yaml"
LEGS = ",".join(f"dl{i}=leg_length_{i}" for i in range(1, 7))
POSE = "x=position_x,y=position_y,z=position_z,qx=orientation_x,qy=orientation_y,qz=orientation_z"
POSE += ",qw=orientation_w"


def run(capsys, *argv) -> tuple[int, str, str]:
    try:
        status = main([str(a) for a in argv])
    except SystemExit as exc:  # a usage error, from the parser
        status = int(exc.code)
    out, err = capsys.readouterr()
    return status, out, err


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hexcal: error: ") and "Traceback" not in err, err
    return lines[0]


#: Each command that reads a table, with the options it needs besides --columns.
COMMANDS = {
    "identify": ["--geometry", GEOMETRY, "--data", SESSION, "--setup", SETUP, "--out", "x.yaml"],
    "validate": ["--geometry", GEOMETRY, "--data", SESSION, "--setup", SETUP],
    "ik": ["--geometry", GEOMETRY, "--poses", SESSION, "--out", "x.csv"],
    "fk": ["--geometry", GEOMETRY, "--legs", SESSION, "--out", "x.csv"],
    "compensate": ["--geometry", GEOMETRY, "--poses", SESSION, "--out", "x.csv"],
    "synthesize": ["--nominal", GEOMETRY, "--true", GEOMETRY, "--poses", SESSION, "--out", "x.csv"],
    "observability": ["--geometry", GEOMETRY, "--poses", SESSION],
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize(
    ("spec", "says"),
    [
        ("X=position_x", "unknown hexcal column 'X'"),
        ("x=position_x,y=position_x", "file column 'position_x' is mapped twice (x, y)"),
        ("x", "'x' is not hexcal_name=file_column"),
    ],
)
def test_a_bad_spec_is_a_usage_error_naming_the_option_and_the_item(capsys, tmp_path, command, spec, says):
    status, out, err = run(capsys, command, *COMMANDS[command], "--columns", spec)
    assert status == 2 and not out
    line = one_line(err)
    assert f"{command}: argument --columns: column map: {says}" in line
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("command", ["validate", "ik", "fk"])
def test_a_mapped_column_missing_from_the_file_is_one_line(capsys, command):
    options = [o for o in COMMANDS[command] if o not in ("--setup", SETUP)]  # the map alone
    status, _, err = run(capsys, command, *options, "--columns", "dl1=leg_length_9")
    assert status == 1
    assert one_line(err).endswith(f"{SESSION}: line 1: no column 'leg_length_9' (the column map's dl1)")


def test_ik_and_fk_read_the_session_as_it_comes(capsys, tmp_path):
    """Readings in revolutions through gains in mm per revolution, and back."""
    poses, legs = tmp_path / "poses.csv", tmp_path / "legs.csv"
    status, _, err = run(
        capsys, "fk", "--geometry", GEOMETRY, "--legs", SESSION, "--columns", LEGS, "--out", poses
    )
    assert status == 0, err
    status, _, err = run(capsys, "ik", "--geometry", GEOMETRY, "--poses", poses, "--out", legs)
    assert status == 0, err
    with open(SESSION, newline="") as fh:
        raw = np.array([[float(r[f"leg_length_{i}"]) for i in range(1, 7)] for r in csv.DictReader(fh)])
    with open(legs, newline="") as fh:
        rows = list(csv.DictReader(fh))
    readings = np.array([[float(r[f"dl{i}"]) for i in range(1, 7)] for r in rows])
    lengths = np.array([[float(r[f"l{i}"]) for i in range(1, 7)] for r in rows])
    np.testing.assert_allclose(readings, raw, atol=1e-9)  # fk's tolerance 1e-9 mm, over ~71 mm/rev
    gains, l0 = np.array([75.691976, 71.196674, 72.341626, 70.800926, 70.62112, 71.262834]), 640.196644
    np.testing.assert_allclose(lengths, l0 + gains * raw, atol=1e-6)  # mm = l0 + gain · revolutions
    # the mocap poses as ik's input, by their own names
    status, _, err = run(
        capsys, "ik", "--geometry", GEOMETRY, "--poses", SESSION, "--columns", POSE, "--out", legs
    )
    assert status == 0, err


def test_the_setup_columns_merge_with_the_option_which_wins(capsys, tmp_path):
    head = b"\r\n".join(SESSION.read_bytes().split(b"\r\n")[:21]) + b"\r\n"  # 20 poses: quick
    short, swapped = tmp_path / "short.csv", tmp_path / "swapped.csv"
    short.write_bytes(head)
    header, rest = head.split(b"\r\n", 1)  # position_x and position_y swapped in the header
    header = (
        header.replace(b"position_x", b"P").replace(b"position_y", b"position_x").replace(b"P", b"position_y")
    )
    swapped.write_bytes(header + b"\r\n" + rest)
    args = ["validate", "--geometry", GEOMETRY, "--setup", SETUP, "--data"]
    status, plain, err = run(capsys, *args, short)
    assert status == 0 and not err, err
    # qw agrees with the setup: not said; x and y replace the setup's, in one line
    status, out, err = run(capsys, *args, swapped, "--columns", "x=position_y,y=position_x,qw=orientation_w")
    assert status == 0 and out == plain.replace(short.name, swapped.name)
    assert err.strip() == (
        "hexcal: warning: --columns replaces the setup's columns: x=position_x by x=position_y, "
        "y=position_y by y=position_x"
    )
    status, _, err = run(capsys, *args, short, "--columns", "y=position_x")
    assert status == 1
    assert one_line(err.splitlines()[-1]).endswith(
        "--columns with the setup's columns: file column 'position_x' is mapped twice (x, y)"
    )


def test_a_bad_setup_columns_key_is_one_line(capsys, tmp_path):
    text = SETUP.read_text()
    for change, says in [
        (("  qw: orientation_w", "  QW: orientation_w"), "columns: unknown hexcal column 'QW'"),
        (("  y: position_y", "  y: position_x"), "columns: file column 'position_x' is mapped twice (x, y)"),
        (("  qw: orientation_w", "  qw: [1]"), "columns.qw: must name a file column (text), got [1]"),
    ]:
        bad = tmp_path / "bad.yaml"
        bad.write_text(text.replace(*change))
        status, _, err = run(capsys, "validate", *COMMANDS["validate"][:4], "--setup", bad)
        assert status == 1 and f"{bad}: {says}" in one_line(err)


def test_identify_and_validate_without_a_setup_honour_delimiter_and_decimal(capsys, tmp_path):
    """A full-pose file (the design machine's fk of session 2) with tabs and odd column names."""
    poses = tmp_path / "poses.csv"
    assert (
        main(
            [
                "fk",
                "--geometry",
                str(GEOMETRY),
                "--legs",
                str(SESSION),
                "--columns",
                LEGS,
                "--out",
                str(poses),
            ]
        )
        == 0
    )
    with open(poses, newline="") as fh:
        pose_rows = [r for r in csv.reader(fh) if r and not r[0].startswith("#")][1:]
    with open(SESSION, newline="") as fh:
        legs = [[r[f"leg_length_{i}"] for i in range(1, 7)] for r in csv.DictReader(fh)]
    names = ["id", "x;mm", "y;mm", "z;mm", "a;rad", "b;rad", "c;rad"] + [
        f"leg_length_{i}" for i in range(1, 7)
    ]
    data = tmp_path / "data.tsv"  # a ';' in the header: detection alone would split there
    data.write_text(
        "\n".join(["\t".join(names)] + ["\t".join(p + g) for p, g in zip(pose_rows, legs, strict=True)])
        + "\n"
    )
    columns = LEGS + ",x=x;mm,y=y;mm,z=z;mm,a=a;rad,b=b;rad,c=c;rad"
    args = ["validate", "--geometry", GEOMETRY, "--data", data, "--columns", columns]
    status, _, err = run(capsys, *args)  # split at the ';' of the header: not the file's columns
    assert status == 1 and one_line(err).endswith("no column 'leg_length_1' (the column map's dl1)")
    status, out, err = run(capsys, *args, "--delimiter", "tab")
    assert status == 0 and "read tab-separated as asked" in err, err
    assert float(out.split("leg residual RMS (mm)")[1].split()[0]) < 1e-6  # fk's own poses
    status, _, err = run(capsys, *args, "--delimiter", "tab", "--decimal", ",")
    assert status == 1 and "has a point, but the numbers of this file have decimal commas" in err
    identify = [
        "identify",
        "--geometry",
        GEOMETRY,
        "--data",
        data,
        "--columns",
        columns,
        "--out",
        tmp_path / "c",
    ]
    status, _, err = run(capsys, *identify)
    assert status == 1 and one_line(err).endswith("no column 'leg_length_1' (the column map's dl1)")
    status, _, err = run(capsys, *identify, "--delimiter", "tab", "--decimal", ",")  # both reach the reader
    assert status == 1 and "column 'x;mm'" in err and "decimal commas" in err.splitlines()[-1]
    assert not (tmp_path / "c").exists()


@pytest.mark.parametrize("command", ["validate", "ik", "fk"])
def test_a_file_without_hexcal_names_and_no_map_says_to_map_them(capsys, command):
    options = [o for o in COMMANDS[command] if o not in ("--setup", SETUP)]
    status, _, err = run(capsys, command, *options)
    assert status == 1
    assert one_line(err).endswith(
        "none of the file's columns (leg_length_1, leg_length_2, leg_length_3 ...) is a hexcal name: "
        "map them (--columns, or columns: in the setup)"
    )
