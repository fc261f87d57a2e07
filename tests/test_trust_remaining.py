"""Issue 22, the items the first pass left open, each through the command line.

Formula injection and control characters: an id starting with ``=``, ``+``, ``-`` or ``@``
(unless it is a plain number such as ``-1``) or holding a control, format or line-separator
character is refused by the one table reader, so that no output hexcal writes (CSV, HAL,
INI, G-code, HTML) can carry it; text that reaches a file only as a comment or a title (a
geometry's name, a file name) is written with such characters escaped. Line breaks are CR,
LF and CRLF only: a U+2028 or U+0085 inside a field stays in that field.
"""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from hexcal.cli import main
from hexcal.core.presets import preset
from hexcal.io import save_geometry


def run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hexcal: error: ") and "Traceback" not in err, err
    return lines[0]


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> Path:
    """A geometry, 20 poses and their measurements, made by hexcal itself."""
    d = tmp_path_factory.mktemp("remaining")
    assert main(["preset", "paper-hmt", "--out", str(d / "g.yaml")]) == 0
    assert main(["candidates", "--geometry", str(d / "g.yaml"), "--candidates", "random:20",
                 "--out", str(d / "p.csv")]) == 0  # fmt: skip
    argv = ["synthesize", "--nominal", d / "g.yaml", "--true", "paper-hmt-true", "--poses", d / "p.csv"]
    assert main([str(a) for a in [*argv, "--out", d / "m.csv"]]) == 0
    return d


def _with_id(src: Path, dst: Path, row: int, value: str) -> Path:
    """``src`` with the id of data row ``row`` replaced by ``value`` (written by the csv module)."""
    rows = [r for r in csv.reader(src.read_text(encoding="utf-8").splitlines()) if not r[0].startswith("#")]
    rows[row][0] = value
    with open(dst, "w", newline="", encoding="utf-8") as fh:
        csv.writer(fh, lineterminator="\n").writerows(rows)
    return dst


# -- formula injection and control characters in ids ---------------------------------------
FORMULAS = ['=HYPERLINK("http://x")', "=cmd|' /C calc'!A0", "+1+cmd", "-2+3", "@SUM(A1)"]
CONTROLS = ["a\tb", "a\u2028b", "a\u0085b", "a\u2029b", "a\x00b", "a\x1bb", "a\u202eb"]


@pytest.mark.parametrize("value", FORMULAS)
@pytest.mark.parametrize("kind", ["poses", "measurements"])
def test_an_id_a_spreadsheet_runs_as_a_formula_is_refused(capsys, files, tmp_path, kind, value):
    if kind == "poses":
        path = _with_id(files / "p.csv", tmp_path / "x.csv", 3, value)
        argv = ["ik", "--geometry", files / "g.yaml", "--poses", path, "--out", tmp_path / "l.csv"]
    else:
        path = _with_id(files / "m.csv", tmp_path / "x.csv", 3, value)
        argv = ["validate", "--geometry", files / "g.yaml", "--data", path, "--out", tmp_path / "v.csv"]
    status, _, err = run(capsys, *argv)
    line = one_line(err)
    assert status == 1 and "line 4, column 'id'" in line and "formula" in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.csv"]


@pytest.mark.parametrize("value", CONTROLS, ids=[repr(c) for c in CONTROLS])
def test_an_id_with_a_control_or_line_separator_is_refused_on_its_line(capsys, files, tmp_path, value):
    """U+2028 and U+0085 are not line breaks of a CSV file: the row keeps its fields, and the
    id is refused on its own line (not "1 fields, but the header has 7" on a split row)."""
    path = _with_id(files / "p.csv", tmp_path / "x.csv", 5, value)
    status, _, err = run(
        capsys, "ik", "--geometry", files / "g.yaml", "--poses", path, "--out", tmp_path / "l.csv"
    )
    line = one_line(err)
    assert status == 1 and "line 6, column 'id'" in line and "control or line-separator" in line, line
    assert not (tmp_path / "l.csv").exists()


@pytest.mark.parametrize("value", ["-1", "+2", "-3.5", "r-1", "a=b", "x@y"])
def test_numbers_and_inner_marks_are_still_ids(capsys, files, tmp_path, value):
    path = _with_id(files / "p.csv", tmp_path / "x.csv", 2, value)
    status, _, err = run(
        capsys, "ik", "--geometry", files / "g.yaml", "--poses", path, "--out", tmp_path / "l.csv"
    )
    assert status == 0, err
    rows = list(csv.reader((tmp_path / "l.csv").read_text(encoding="utf-8").splitlines()))
    assert rows[2][0] == value


def test_an_id_with_surrounding_blanks_is_the_id_without_them(capsys, files, tmp_path):
    """Blanks around a cell are not part of it (as for the numbers): ``' r01 '`` is ``r01``,
    and ``' r02 '`` repeats the id ``r02`` of the next row."""
    path = _with_id(files / "p.csv", tmp_path / "x.csv", 2, " r01 ")
    status, _, err = run(
        capsys, "ik", "--geometry", files / "g.yaml", "--poses", path, "--out", tmp_path / "l.csv"
    )
    assert status == 0, err
    assert (tmp_path / "l.csv").read_text(encoding="utf-8").splitlines()[2].startswith("r01,")
    path = _with_id(files / "p.csv", tmp_path / "y.csv", 2, " r02 ")
    status, _, err = run(
        capsys, "ik", "--geometry", files / "g.yaml", "--poses", path, "--out", tmp_path / "k.csv"
    )
    assert status == 1 and "id 'r02' repeats line 3" in one_line(err)


def test_a_line_separator_in_a_number_field_names_the_field(capsys, files, tmp_path):
    text = (files / "p.csv").read_text(encoding="utf-8").splitlines()
    cells = text[3].split(",")
    cells[2] = cells[2][:3] + "\u2028" + cells[2][3:]
    (tmp_path / "x.csv").write_text(
        "\n".join([*text[:3], ",".join(cells), *text[4:]]) + "\n", encoding="utf-8"
    )
    status, _, err = run(
        capsys,
        "ik",
        "--geometry",
        files / "g.yaml",
        "--poses",
        tmp_path / "x.csv",
        "--out",
        tmp_path / "l.csv",
    )
    line = one_line(err)
    assert status == 1 and "line 4" in line and "'y'" in line and "fields" not in line, line


NAMES = ["rig\nloadusr -w touch /tmp/x", "rig\u2028=cmd", "rig\r\n# x", "rig\x1b[2Jcls"]


@pytest.mark.parametrize("name", NAMES, ids=range(len(NAMES)))
def test_a_hostile_name_is_one_escaped_comment_line_of_every_csv(capsys, files, tmp_path, name):
    """The geometry's name reaches a CSV only inside the ``#`` comment: one line, escaped."""
    save_geometry(preset("paper-hmt").replace(name=name), tmp_path / "g.yaml")
    argv = [
        "synthesize",
        "--nominal",
        tmp_path / "g.yaml",
        "--true",
        "paper-hmt-true",
        "--poses",
        files / "p.csv",
    ]
    status, _, err = run(capsys, *argv, "--out", tmp_path / "m.csv")
    assert status == 0, err
    raw = (tmp_path / "m.csv").read_bytes().decode("utf-8")
    lines = raw.split("\n")
    assert lines[0].startswith("# ") and lines[1].startswith("id,"), lines[:3]
    assert lines[0].isprintable() and "\r" not in raw
    status, _, err = run(capsys, "validate", "--geometry", files / "g.yaml", "--data", tmp_path / "m.csv",
                         "--html", tmp_path / "v.html", "--out", tmp_path / "v.csv")  # fmt: skip
    assert status == 0, err


# -- identify without a workspace box --------------------------------------------------------
@pytest.mark.parametrize("instrument", ["pose", "targets"])
def test_identify_without_a_workspace_box_predicts_over_the_poses_range(capsys, files, tmp_path, instrument):
    """The ``workspace:`` box is optional in a geometry file: identify then predicts its
    accuracy over the calibration poses' range, says so, and writes no box of its own."""
    save_geometry(preset("paper-hmt").replace(workspace=None), tmp_path / "g.yaml")
    data, extra = files / "m.csv", []
    if instrument == "targets":
        (tmp_path / "s.yaml").write_text(
            "units: mm\ninstrument_frame: {x: 1000, y: 200, z: -300, a_deg: 10, b_deg: 5, c_deg: 30}\n"
            "targets:\n  t1: [0, 0, 60]\n  t2: [150, 20, 55]\n  t3: [-40, 160, 70]\n",
            encoding="utf-8",
        )
        argv = [
            "synthesize",
            "--nominal",
            "paper-hmt",
            "--true",
            "paper-hmt-true",
            "--poses",
            files / "p.csv",
        ]
        assert run(capsys, *argv, "--setup", tmp_path / "s.yaml", "--out", tmp_path / "t.csv")[0] == 0
        data, extra = tmp_path / "t.csv", ["--setup", tmp_path / "s.yaml"]
    argv = [
        "identify",
        "--geometry",
        tmp_path / "g.yaml",
        "--data",
        data,
        *extra,
        "--out",
        tmp_path / "r.yaml",
    ]
    status, out, err = run(capsys, *argv, "--force")
    assert status == 0, err
    assert "over the calibration poses' range (the geometry has no workspace box)" in out
    assert "workspace" not in (tmp_path / "r.yaml").read_text(encoding="utf-8")


# -- simulate and paper declare their folder files like every command ------------------------
@pytest.mark.parametrize(
    ("argv", "inside"),
    [
        (["simulate", "--trials", "2", "--poses", "15"], "study.csv"),
        (["paper", "--trials", "2"], "fig11_validation_errors.png"),
    ],
)
@pytest.mark.parametrize("clash", ["fifo", "html"])
def test_simulate_and_paper_check_their_folder_files_before_any_work(capsys, tmp_path, argv, inside, clash):
    """The files written into ``--out DIR`` are declared outputs (``folder_files``): a FIFO
    there, or ``--html`` naming one of them, is refused at once, by the one output set."""
    import os

    from hexcal.cli import safety

    assert not hasattr(safety, "FOLDER_FILES")  # no list of exceptions beside the commands
    (tmp_path / "out").mkdir()
    extra = []
    if clash == "fifo":
        os.mkfifo(tmp_path / "out" / inside)
    else:
        extra = ["--html", tmp_path / "out" / inside]
    status, out, err = run(capsys, *argv, "--out", tmp_path / "out", *extra)
    line = one_line(err)
    assert status == 1 and inside in line and ("FIFO" in line or "another output" in line), line
    assert "Simulating" not in err + out
    assert [p.name for p in (tmp_path / "out").iterdir()] == ([inside] if clash == "fifo" else [])


# -- options that do nothing: each acts or is refused in one line naming it -------------------
SETUP_YAML = (
    "units: mm\ninstrument_frame: {x: 1000, y: 200, z: -300, a_deg: 10, b_deg: 5, c_deg: 30}\n"
    "targets:\n  t1: [0, 0, 60]\n  t2: [150, 20, 55]\n  t3: [-40, 160, 70]\n"
)


IDENTIFY = ["identify", "--geometry", "{g}", "--data", "{m}", "--out", "{o}/r.yaml"]
SYNTHESIZE = ["synthesize", "--nominal", "{g}", "--true", "paper-hmt-true", "--poses", "{p}"]


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        ([*IDENTIFY, "--setup-out", "{o}/s.yaml"], "--setup-out"),
        ([*IDENTIFY, "--delimiter", ";"], "--delimiter"),
        ([*SYNTHESIZE, "--setup", "{s}", "--orientation", "quat", "--out", "{o}/t"], "--orientation quat"),
        (["simulate", "--setup", "{s}", "--methods", "paper", "--trials", "2", "--poses", "15"],
         "method paper"),
        (["observability", "--geometry", "{g}", "--poses", "{p}", "--setup", "{s}", "--method", "length"],
         "method 'length'"),
    ],
    ids=["setup-out", "delimiter", "quat-targets", "simulate-paper-targets", "observability-length-targets"],
)  # fmt: skip
def test_an_option_that_cannot_act_is_refused_naming_it(capsys, files, tmp_path, argv, words):
    (tmp_path / "s.yaml").write_text(SETUP_YAML, encoding="utf-8")
    names = {"g": files / "g.yaml", "m": files / "m.csv", "p": files / "p.csv", "s": tmp_path / "s.yaml"}
    status, _, err = run(capsys, *[a.format(o=tmp_path, **names) for a in argv])
    note = "hexcal: no --true"  # simulate's announcement of random machines, before the check
    line = one_line("\n".join(x for x in err.splitlines() if not x.startswith(note)))
    assert status == 1 and words in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.yaml"]


@pytest.mark.parametrize("noise", ["leg=0.01", "pos=0.02,ang=0.0005"])
def test_a_partial_noise_says_what_fills_the_rest(capsys, files, tmp_path, noise):
    argv = [
        "identify",
        "--geometry",
        files / "g.yaml",
        "--data",
        files / "m.csv",
        "--out",
        tmp_path / "r.yaml",
    ]
    status, _, err = run(capsys, *argv, "--noise", noise, "--force")
    assert status == 0, err
    given = [item.split("=")[0] for item in noise.split(",")]
    said = [line for line in err.splitlines() if line.startswith("hexcal: warning: --noise gives only")]
    assert len(said) == 1 and "the seed paper's values" in said[0], err
    for key in {"leg", "pos", "ang"} - set(given):
        assert f"{key}=" in said[0]
    status, _, err = run(capsys, *argv, "--noise", "leg=0.01,pos=0.025,ang=0.001", "--force")
    assert status == 0 and "--noise gives only" not in err


# -- setups: one reader policy with the geometry's ------------------------------------------
def _tracker_data(capsys, files: Path, tmp_path: Path) -> Path:
    (tmp_path / "true.yaml").write_text(SETUP_YAML, encoding="utf-8")
    argv = ["synthesize", "--nominal", "paper-hmt", "--true", "paper-hmt-true", "--poses", files / "p.csv"]
    assert run(capsys, *argv, "--setup", tmp_path / "true.yaml", "--out", tmp_path / "t.csv")[0] == 0
    return tmp_path / "t.csv"


@pytest.mark.parametrize(
    ("targets", "words"),
    [
        (
            "  t1: [0, 0, 60]\n  t2: [0, 0, 60.0]\n  t3: [-40, 160, 70]\n",
            "targets t1 and t2 are at one point",
        ),
        (
            "".join(f"  t{k}: [{k}, {k % 7}, 60]\n" for k in range(1, 2001)),
            "2,000 targets, over the limit of 64",
        ),
    ],
    ids=["coincident", "2000-targets"],
)
def test_a_setup_no_instrument_can_have_is_refused_at_once(capsys, files, tmp_path, targets, words):
    data = _tracker_data(capsys, files, tmp_path)
    frame = SETUP_YAML.split("targets:")[0]
    (tmp_path / "s.yaml").write_text(frame + "targets:\n" + targets, encoding="utf-8")
    argv = ["identify", "--geometry", files / "g.yaml", "--data", data, "--setup", tmp_path / "s.yaml"]
    status, out, err = run(capsys, *argv, "--out", tmp_path / "r.yaml")
    line = one_line(err)
    assert status == 1 and out == "" and words in line, line
    assert not (tmp_path / "r.yaml").exists()


def test_a_message_naming_the_setups_targets_stays_one_short_line(capsys, files, tmp_path):
    data = _tracker_data(capsys, files, tmp_path)
    frame = SETUP_YAML.split("targets:")[0]
    targets = "".join(f"  t{k}: [{k}, {k % 7}, 60]\n" for k in range(1, 61))
    (tmp_path / "s.yaml").write_text(frame + "targets:\n" + targets, encoding="utf-8")
    argv = ["identify", "--geometry", files / "g.yaml", "--data", data, "--setup", tmp_path / "s.yaml"]
    status, _, err = run(capsys, *argv, "--out", tmp_path / "r.yaml")
    line = one_line(err)
    assert status == 1 and "missing column 't4.x'" in line and "and 52 more" in line and len(line) < 300, line


# -- angles beyond a half turn --------------------------------------------------------------
@pytest.mark.parametrize(("column", "value"), [("a_deg", "360"), ("b_deg", "-181"), ("a", "6.3")])
def test_a_measured_angle_beyond_180_degrees_is_refused_naming_it(capsys, files, tmp_path, column, value):
    """``a_deg = +360`` passed without a word (issue 22); the workspace refuses ±720° already,
    and every pose reader now refuses such an angle the same way, on its line."""
    lines = [x for x in (files / "m.csv").read_text(encoding="utf-8").splitlines() if not x.startswith("#")]
    header = lines[0].split(",")
    if column.endswith("_deg"):
        header = [f"{h}_deg" if h in "abc" else h for h in header]
    cells = lines[3].split(",")
    cells[header.index(column)] = value
    text = "\n".join([",".join(header), *lines[1:3], ",".join(cells), *lines[4:]]) + "\n"
    (tmp_path / "x.csv").write_text(text, encoding="utf-8")
    argv = [
        "identify",
        "--geometry",
        files / "g.yaml",
        "--data",
        tmp_path / "x.csv",
        "--out",
        tmp_path / "r.yaml",
    ]
    status, _, err = run(capsys, *argv)
    line = one_line(err)
    assert status == 1 and f"line 4, column '{column}'" in line and "beyond ±180°" in line, line


# -- one limit for every reader: target files too ------------------------------------------
@pytest.mark.parametrize("kind", ["pose", "targets"])
def test_a_huge_field_and_too_many_rows_are_one_line_for_every_file_kind(capsys, files, tmp_path, kind):
    """A field of 200,000 characters took 32 s and ended in a traceback (issue 22), in a target
    file at once; ``--max-rows`` was ignored by target files. Both are one line now, at once."""
    data, extra = files / "m.csv", []
    if kind == "targets":
        data, extra = _tracker_data(capsys, files, tmp_path), ["--setup", tmp_path / "true.yaml"]
    argv = ["identify", "--geometry", files / "g.yaml", *extra, "--out", tmp_path / "r.yaml"]
    status, _, err = run(capsys, *argv, "--data", data, "--max-rows", "5")
    assert status == 1 and "more than 5 data rows" in one_line(err)
    lines = [x for x in data.read_text(encoding="utf-8").splitlines() if not x.startswith("#")]
    cells = lines[2].split(",")
    cells[8] = "9" * 200_000
    (tmp_path / "big.csv").write_text("\n".join([*lines[:2], ",".join(cells), *lines[3:]]) + "\n")
    status, _, err = run(capsys, *argv, "--data", tmp_path / "big.csv")
    line = one_line(err)
    assert status == 1 and "line 3" in line and "200,000 characters, over the limit" in line, line
    assert not (tmp_path / "r.yaml").exists()
