"""The one table reader through the command line (issue 22): what works through it today.

``hexcal ik``/``fk``/``compensate`` read pose and leg files in any dialect; ``hexcal identify
--data`` reads a full-pose measurement file with ``;`` and decimal commas; target exports
honour ``--max-rows``; unit rows, thousands separators and 200,000-character fields end in one
line ``hexcal: error: ...`` with exit status 1 and nothing written.
"""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from hexcal.cli import main


def run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("hexcal: error: ") and "Traceback" not in err
    return lines[0]


def european(source: Path, target: Path) -> Path:
    """The same table with ``;`` between fields and decimal commas (comments dropped)."""
    rows = [r for r in csv.reader(source.read_text().splitlines()) if r and not r[0].startswith("#")]
    target.write_text("".join(";".join(c.replace(".", ",") for c in row) + "\n" for row in rows))
    return target


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> Path:
    """Poses, legs and a measurement file of the paper's machine, made by hexcal itself."""
    folder = tmp_path_factory.mktemp("tables_cli")
    assert (
        main(
            [
                "candidates",
                "--geometry",
                "paper-hmt",
                "--candidates",
                "corners",
                "--out",
                str(folder / "p.csv"),
            ]
        )
        == 0
    )
    args = [
        "synthesize",
        "--nominal",
        "paper-hmt",
        "--true",
        "paper-hmt-true",
        "--poses",
        str(folder / "p.csv"),
    ]
    assert main([*args, "--out", str(folder / "m.csv"), "--orientation", "deg"]) == 0
    assert (
        main(
            [
                "ik",
                "--geometry",
                "paper-hmt",
                "--poses",
                str(folder / "p.csv"),
                "--out",
                str(folder / "l.csv"),
            ]
        )
        == 0
    )
    return folder


@pytest.mark.parametrize(
    ("command", "option", "name"),
    [("ik", "--poses", "p"), ("fk", "--legs", "l"), ("compensate", "--poses", "p")],
)
def test_commands_read_semicolons_and_decimal_commas(capsys, files, tmp_path, command, option, name):
    eu = european(files / f"{name}.csv", tmp_path / f"{name}_eu.csv")
    geometry = "paper-hmt-true" if command == "compensate" else "paper-hmt"
    for source, out in ((files / f"{name}.csv", tmp_path / "a.csv"), (eu, tmp_path / "b.csv")):
        status, _, err = run(capsys, command, "--geometry", geometry, option, source, "--out", out)
        assert status == 0, err
    assert (tmp_path / "a.csv").read_text() == (tmp_path / "b.csv").read_text()


def test_identify_reads_a_full_pose_file_with_semicolons_and_decimal_commas(capsys, files, tmp_path):
    eu = european(files / "m.csv", tmp_path / "m_eu.csv")
    base = ["identify", "--geometry", "paper-hmt"]
    status, _, err = run(capsys, *base, "--data", files / "m.csv", "--out", tmp_path / "a.yaml")
    assert status == 0, err
    status, _, err = run(capsys, *base, "--data", eu, "--out", tmp_path / "b.yaml")
    assert status == 0, err
    status, _, err = run(
        capsys, *base, "--data", eu, "--out", tmp_path / "c.yaml", "--delimiter", ";", "--decimal", ","
    )
    assert status == 0, err
    calibrated = [(tmp_path / f"{k}.yaml").read_text().split("calibration:")[0] for k in "abc"]
    assert calibrated[0] == calibrated[1] == calibrated[2]  # the same geometry from the same numbers


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (
            "id,x,y,z,a,b,c\n,[deg],mm,mm,rad,rad,rad\np1,1,2,800,0,0,0\n",
            "line 2, column 'x': unit '[deg]'; only mm here",
        ),
        ("x;y;z;a;b;c\n;mm\n1;2;800;0;0;0\n", "line 2: the unit row has 2 fields, but the header has 6"),
        ("x;y;z;a;b;c\n1.234,5;2;800;0;0;0\n", "line 2, column 'x': '1.234,5' has a thousands separator"),
        ("x;y;z;a;b;c\n0,5;0,5;800;0;0;0\n1.234;2;800;0;0;0\n", "line 3, column 'x': '1.234' has a point"),
        (
            "id,x,y,z,a,b,c\n" + "x" * 200_000 + ",1,2,800,0,0,0\n",
            "line 2, column 'id': a field of 200,000 characters",
        ),
        (
            "id,x,y,z,a,b,c\np1,0." + "1" * 200_000 + ",2,800,0,0,0\n",
            "line 2, column 'x': a field of 200,002 characters",
        ),
    ],
)
def test_ik_refuses_with_one_line(capsys, tmp_path, text, expected):
    poses = tmp_path / "poses.csv"
    poses.write_text(text)
    status, out, err = run(
        capsys, "ik", "--geometry", "paper-hmt", "--poses", poses, "--out", tmp_path / "legs.csv"
    )
    assert status == 1 and out == ""
    line = one_line(err)
    assert expected in line and str(poses) in line and len(line) < 300
    assert sorted(p.name for p in tmp_path.iterdir()) == ["poses.csv"]


SETUP = "units: mm\ninstrument_frame: auto\ntargets:\n  t1: [1, -1, 61]\n  t2: [149, 21, 54]\n"
SETUP += "  t3: [-41, 158, 71]\n"
EXPORT = "id;dl1;dl2;dl3;dl4;dl5;dl6;t1.x;t1.y;t1.z;t2.x;t2.y;t2.z;t3.x;t3.y;t3.z\n"


def _identify(capsys, tmp_path, export: str, *extra):
    (tmp_path / "setup.yaml").write_text(SETUP)
    (tmp_path / "export.csv").write_text(export)
    args = [
        "identify",
        "--geometry",
        "paper-hmt",
        "--setup",
        tmp_path / "setup.yaml",
        "--data",
        tmp_path / "export.csv",
    ]
    return run(capsys, *args, "--out", tmp_path / "cal.yaml", *extra)


def test_target_exports_honour_the_row_limit(capsys, tmp_path):
    rows = "".join(f"p{k};0;0;0;0;0;0;1,5;2;3;1;2;3;1;2;3\n" for k in range(150_000))
    status, _, err = _identify(capsys, tmp_path, EXPORT + rows)
    assert status == 1 and "more than 100,000 data rows, the limit; raise it with --max-rows" in one_line(err)
    status, _, err = _identify(capsys, tmp_path, EXPORT + rows[: 20 * 40], "--max-rows", "10")
    assert status == 1 and "more than 10 data rows" in one_line(err)
    assert not (tmp_path / "cal.yaml").exists()


@pytest.mark.parametrize("extra", [(), ("--delimiter", ";", "--decimal", ",")])
def test_a_long_field_in_a_target_export_is_one_line(capsys, tmp_path, extra):
    status, _, err = _identify(
        capsys, tmp_path, EXPORT + "p1;0;0;0;0;0;0;" + "1" * 200_000 + ";2;3;1;2;3;1;2;3\n", *extra
    )
    assert status == 1
    assert "line 2, column 't1.x': a field of 200,000 characters, over the limit of 131,072" in one_line(err)


def test_a_unit_row_in_degrees_on_a_target_column_is_refused(capsys, tmp_path):
    units = ";mm;mm;mm;mm;mm;mm;deg;mm;mm;mm;mm;mm;mm;mm;mm\n"
    status, _, err = _identify(capsys, tmp_path, EXPORT + units + "p1;0;0;0;0;0;0;1;2;3;1;2;3;1;2;3\n")
    assert status == 1 and "line 2, column 't1.x': unit 'deg'; only mm here" in one_line(err)
