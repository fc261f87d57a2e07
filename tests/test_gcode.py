"""G-code program filtering for closed controllers (issue 20, item 3): ``hexcal compensate
--gcode``, :mod:`hexcal.io.gcode` and :mod:`hexcal.core.path_compensation`.

The simulated real machine is ``paper-hmt-true``, the controller keeps ``paper-hmt``: a
filtered program, run on the controller (its inverse kinematics -> leg readings -> the real
machine's forward kinematics), must follow the intended path within the tolerance at every
commanded point and densely along every output segment, where the unfiltered program misses
by tens of millimetres.
"""

from __future__ import annotations

import hashlib
import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from hexcal.cli.main import main
from hexcal.core import compensate, preset
from hexcal.core.path_compensation import (
    Moves,
    PathError,
    correct_path,
    correct_poses,
    orientation_deviation,
    path_points,
    reached_poses,
)
from hexcal.io import read_poses
from hexcal.io.gcode import gcode_comment, read_program

TRUE = preset("paper-hmt-true")
NOMINAL = preset("paper-hmt")
HOME = np.array([0.0, 0.0, 800.0, 0.0, 0.0, 0.0])

# lines, an arc in each plane (centre and radius form, a full helical circle, P turns),
# incremental moves and an inch section, each move tagged (mN) to find its output lines
PROGRAM = """\
%
(hexcal test program)
G21 G90 G17 G94
N1 G0 X-150 Y-120 Z760 A2 B-3 C5 (m1)
N2 G1 X180 Y-90 Z820 F800 (m2)
N3 Y140 A-4 (m3)
N4 G2 X100 Y60 I-80 J0 (m4)
N5 G3 X100 Y60 I0 J40 Z800 (m5)
N6 G18 G2 X40 Z860 R70 (m6)
N7 G19 G3 Y0 Z800 J-60 K0 C-5 (m7)
N8 G17 G91 G1 X-50 Y-50 (m8)
N9 X-30 Z-20 B4 (m9)
N10 G90 G20 X-1 Y2 (m10)
N11 G21 G0 X0 Y0 Z800 A0 B0 C0 (m11) M2
%
"""


def run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def program_args(source: Path, out: Path, *extra, geometry: object = "paper-hmt-true") -> list:
    """``compensate --gcode`` of the simulated real machine for the paper's nominal controller."""
    machines = ["--geometry", geometry, "--nominal", "paper-hmt"]
    return ["compensate", *machines, "--gcode", source, "--out", out, *extra]


def filter_program(capsys, tmp_path: Path, text: str, *extra) -> tuple[Path, str, str]:
    source, out = tmp_path / "in.ngc", tmp_path / "out.ngc"
    source.write_text(text)
    status, stdout, err = run(capsys, *program_args(source, out, *extra))
    assert status == 0, err
    return out, stdout, err


def moves_of(path: Path, start: np.ndarray = HOME) -> tuple[Moves, list[str]]:
    """All moves of a program (one block) and the source line of each."""
    blocks = list(read_program(path, start))
    assert len(blocks) == 1
    block = blocks[0]
    return block.moves, [block.lines[i] for i in block.move_lines]


def one_error(capsys, *argv) -> str:
    status, _, err = run(capsys, *argv)
    assert status == 1 and "Traceback" not in err, err
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("hexcal: error:"), err
    return lines[0]


# -- reading: modal state, comments, arcs, incremental mode (by hand) --------------------------
def test_modal_words_comments_and_blank_lines(tmp_path):
    text = "G21 G90\n\nG1 X10 F100 (first; with a semicolon)\nY5 ; modal G1, X kept\nG0 Z900\nA90\nM5\n"
    (tmp_path / "p.ngc").write_text(text)
    moves, lines = moves_of(tmp_path / "p.ngc")
    expected = [[10, 0, 800, 0, 0, 0], [10, 5, 800, 0, 0, 0], [10, 5, 900, 0, 0, 0], [10, 5, 900, 0, 0, 0]]
    expected[3][3] = math.pi / 2
    assert_allclose(moves.end, expected)
    assert lines[1].startswith("Y5") and not moves.arc.any()


def test_blanks_inside_numbers_case_and_units(tmp_path):
    (tmp_path / "p.ngc").write_text("g0x +0. 12 34Y 7\nG20 G1 X1 Y-0.5 F10\nG91 X.5\n")
    moves, _ = moves_of(tmp_path / "p.ngc")
    assert_allclose(moves.end[:, :2], [[0.1234, 7], [25.4, -12.7], [38.1, -12.7]])


def test_incremental_moves_accumulate(tmp_path):
    (tmp_path / "p.ngc").write_text("G91 G1 X1 Y1 F10\nX1 Y1 C10\nG90 X0\n")
    moves, _ = moves_of(tmp_path / "p.ngc")
    c = math.radians(10)
    assert_allclose(moves.end[:, [0, 1, 2, 5]], [[1, 1, 800, 0], [2, 2, 800, c], [0, 2, 800, c]])


@pytest.mark.parametrize(
    ("program", "mid"),
    [
        # G17: a quarter counterclockwise from (10, 0) about the origin, seen from +Z
        ("G0 X10 Y0 Z800\nG3 X0 Y10 I-10 J0 F10\n", {0: 10 / math.sqrt(2), 1: 10 / math.sqrt(2)}),
        # clockwise the same way round is three quarters, through (-7.07, -7.07)
        ("G0 X10 Y0 Z800\nG2 X0 Y10 I-10 J0 F10\n", {0: -10 / math.sqrt(2), 1: -10 / math.sqrt(2)}),
        # G18 is the ZX plane: counterclockwise seen from +Y turns from +Z towards +X
        ("G18 G0 X0 Y0 Z810\nG3 X10 Z800 I0 K-10 F10\n", {0: 10 / math.sqrt(2), 2: 800 + 10 / math.sqrt(2)}),
        ("G18 G0 X0 Y0 Z810\nG2 X10 Z800 I0 K-10 F10\n", {0: -10 / math.sqrt(2), 2: 800 - 10 / math.sqrt(2)}),
        # G19 is the YZ plane: counterclockwise seen from +X turns from +Y towards +Z
        ("G19 G0 X0 Y10 Z800\nG3 Y0 Z810 J-10 K0 F10\n", {1: 10 / math.sqrt(2), 2: 800 + 10 / math.sqrt(2)}),
        # R form: R > 0 the short way (centre (5, -8.66)), R < 0 the long way (centre (5, 8.66))
        ("G0 X0 Y0 Z800\nG2 X10 Y0 R10 F10\n", {0: 5, 1: 10 - 10 * math.sqrt(0.75)}),
        ("G0 X0 Y0 Z800\nG2 X10 Y0 R-10 F10\n", {0: 5, 1: 10 + 10 * math.sqrt(0.75)}),
        # absolute arc centre (G90.1) and a helix: Z halfway at the middle
        ("G90.1 G0 X10 Y0 Z800\nG3 X-10 Y0 Z820 I0 J0 F10\n", {0: 0, 1: 10, 2: 810}),
    ],
)
def test_arcs_in_each_plane_by_hand(tmp_path, program, mid):
    (tmp_path / "p.ngc").write_text(program)
    moves, _ = moves_of(tmp_path / "p.ngc")
    point = path_points(moves, np.array([1]), np.array([0.5]))[0]
    for axis, value in mid.items():
        assert point[axis] == pytest.approx(value, abs=1e-9), (axis, point)
    end = path_points(moves, np.array([1]), np.array([1.0]))[0]
    assert_allclose(end, moves.end[1], atol=1e-9)  # the parametrisation ends at the end point


def test_full_circles_and_turns(tmp_path):
    (tmp_path / "p.ngc").write_text("G0 X10 Y0 Z800\nG2 I-10 F10\nG3 X10 Y0 I-10 J0 P3\n")
    moves, _ = moves_of(tmp_path / "p.ngc")
    assert moves.arc[1:].all()
    assert_allclose(moves.sweep[1:], [-2 * math.pi, 6 * math.pi])
    assert_allclose(moves.end[1], moves.end[0])  # no axis words: a full circle back to the start
    quarter = path_points(moves, np.array([1]), np.array([0.25]))[0]
    assert_allclose(quarter[:2], [0, -10], atol=1e-9)  # clockwise from +X goes to -Y first


def test_lines_after_the_program_end_are_not_read(tmp_path):
    (tmp_path / "p.ngc").write_text("G1 X1 F1\nM2\nthis is not G-code #1 [\n")
    moves, _ = moves_of(tmp_path / "p.ngc")
    assert len(moves) == 1


@pytest.mark.parametrize(
    ("line", "words"),
    [
        ("G1 X1 (unclosed", "'(' without ')'"),
        ("G1 X(nested (x)) 1", "cannot be nested"),
        ("G1 X#1", "parameters and expressions"),
        ("O100 sub", "O-words"),
        ("G1 X1 E5", "'E5' is not a word"),
        ("G1 X1 X2", "X appears twice"),
        ("G0 G1 X1", "two motion codes"),
        ("G92 X0", "coordinate frame"),
        ("G43 H1", "offset the path"),
        ("G81 X1 Z-1 R2", "not supported"),
        ("G93 G1 X1 F2", "G93"),
        ("G1 U3", "U axis"),
        ("G1 X1 I2", "without G2 or G3"),
        ("G2 X1 Y1", "I J K offsets or an R"),
        ("G17 G2 X1 Y1 K1", "K offset outside the arc plane G17"),
        ("G2 X10 Y0 R2", "smaller than half the distance"),
        ("G2 X10 Y0 I6", "radius to the end of the arc differs"),
        ("G80 X1", "without a motion mode"),
        ("/G1 X1", "block delete"),
        ("G1 X1 Y1 @2", "cannot read '@2'"),
    ],
)
def test_a_malformed_line_is_one_error_naming_its_line_and_nothing_is_written(capsys, tmp_path, line, words):
    source, out = tmp_path / "bad.ngc", tmp_path / "out.ngc"
    source.write_text(f"G21 G90\nG1 X0 Y0 Z800 F100\n{line}\nG1 X5\n")
    before = source.read_bytes()
    message = one_error(capsys, *program_args(source, out))
    assert f"{source}: line 3: " in message and words in message, message
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["bad.ngc"]
    assert source.read_bytes() == before


# -- the simulated real machine --------------------------------------------------------------
def _segments_by_move(path: Path, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The commanded points of an output program and the tagged input move of each."""
    moves, lines = moves_of(path, start)
    tags, current = [], None
    for line in lines:
        found = re.search(r"\(m(\d+)\)", line)
        current = int(found.group(1)) - 1 if found else current
        tags.append(current)
    return moves.end, np.array(tags)


def _distance_to_move(moves: Moves, m: int, reached: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position distance of ``reached`` to the intended path of move ``m`` (the nearest of 2001
    samples, refined by a golden-section search on the move's parameter), and the orientation
    error at that nearest point."""
    t = np.linspace(0.0, 1.0, 2001)
    samples = path_points(moves, np.full(t.size, m), t)
    near = np.concatenate([
        np.argmin(np.linalg.norm(reached[lo : lo + 500, None, :3] - samples[None, :, :3], axis=2), axis=1)
        for lo in range(0, len(reached), 500)
    ])  # fmt: skip
    lo, hi = np.maximum(t[near] - 1e-3, 0.0), np.minimum(t[near] + 1e-3, 1.0)
    index = np.full(len(reached), m)

    def gap(u: np.ndarray) -> np.ndarray:
        return np.linalg.norm(path_points(moves, index, u)[:, :3] - reached[:, :3], axis=1)

    golden = (math.sqrt(5) - 1) / 2
    for _ in range(60):
        a, b = hi - golden * (hi - lo), lo + golden * (hi - lo)
        left = gap(a) < gap(b)
        hi, lo = np.where(left, b, hi), np.where(left, lo, a)
    foot = path_points(moves, index, 0.5 * (lo + hi))
    distance = np.linalg.norm(foot[:, :3] - reached[:, :3], axis=1)
    return distance, orientation_deviation(reached, foot, TRUE.euler)


def test_filtered_program_follows_the_path_on_the_real_machine(capsys, tmp_path):
    out, stdout, _ = filter_program(capsys, tmp_path, PROGRAM)
    intended, _ = moves_of(tmp_path / "in.ngc")
    start_corrected = correct_poses(TRUE, NOMINAL, HOME[None], np.array([0]))[0]
    commanded, tags = _segments_by_move(out, start_corrected)
    assert tags[0] == 0 and (np.diff(tags) >= 0).all() and set(tags) == set(range(len(intended)))
    # every commanded point and 15 points inside every output segment, run on the controller
    s = np.linspace(0.0, 1.0, 17)
    q0 = np.concatenate([start_corrected[None], commanded[:-1]])
    dense = q0[:, None] + s[None, :, None] * (commanded - q0)[:, None]
    worst_position = worst_angle = 0.0
    for m in range(len(intended)):
        points = dense[tags == m].reshape(-1, 6)
        reached = reached_poses(TRUE, NOMINAL, points, points)
        assert np.isfinite(reached).all()
        distance, angle = _distance_to_move(intended, m, reached)
        worst_position, worst_angle = max(worst_position, distance.max()), max(worst_angle, angle.max())
    assert worst_position <= 1e-3 and worst_angle <= 1e-5, (worst_position, worst_angle)
    # the commanded points alone, at the moves' ends: on the targets within the FK's accuracy
    ends = np.flatnonzero(np.r_[tags[1:] != tags[:-1], True])
    reached_ends = reached_poses(TRUE, NOMINAL, commanded[ends], intended.end)
    assert np.abs(reached_ends[:, :3] - intended.end[:, :3]).max() <= 2e-5  # the written decimals
    # the unfiltered program, on the same controller, misses by tens of millimetres
    t = np.linspace(0.0, 1.0, 65)
    index = np.repeat(np.arange(len(intended)), t.size)
    along = path_points(intended, index, np.tile(t, len(intended)))
    raw = reached_poses(TRUE, NOMINAL, along, along)
    miss = np.linalg.norm(raw[:, :3] - along[:, :3], axis=1)
    assert miss.min() > 30.0 and miss.max() > 45.0, (miss.min(), miss.max())
    assert orientation_deviation(raw, along, TRUE.euler).max() > 0.05
    print(f"filtered: {worst_position * 1e3:.3f} um, {worst_angle:.2e} rad; unfiltered {miss.max():.1f} mm")
    assert "largest deviation" in stdout


def test_header_states_sequence_unit_tolerance_hashes_and_version(capsys, tmp_path):
    from importlib.metadata import version

    out, _, _ = filter_program(capsys, tmp_path, PROGRAM, "--euler", "xyz", "--tolerance", "0.002")
    lines = out.read_text().splitlines()
    assert lines[0] == "%"  # the header comes after the opening percent line
    header = [line for line in lines[1:10] if line.startswith("(hexcal") or ":" in line]
    text = "\n".join(header)
    assert f"hexcal {version('hexcal')}" in text
    assert "A B C: degrees, Euler sequence extrinsic xyz: R = Rz[C] Ry[B] Rx[A], LinuxCNC's" in text
    assert "0.002 mm in position, 1e-05 rad in orientation" in text
    preset_yaml = tmp_path / "true.yaml"
    status, _, err = run(capsys, "preset", "paper-hmt-true", "--out", preset_yaml)
    assert status == 0, err
    assert hashlib.sha256(preset_yaml.read_bytes()).hexdigest() in text  # the preset's YAML


def test_a_hostile_geometry_name_cannot_break_out_of_the_header(capsys, tmp_path):
    from hexcal.io import save_geometry

    evil = tmp_path / "evil.yaml"
    save_geometry(TRUE.replace(name="real)\nG0 X999 (\r\x00; M2 \u00e9"), evil)
    source, out = tmp_path / "in.ngc", tmp_path / "out.ngc"
    source.write_text("G1 X10 Y10 Z800 F100\n")
    status, _, err = run(capsys, *program_args(source, out, geometry=evil))
    assert status == 0, err
    lines = out.read_text().split("\n")
    header = lines[: next(i for i, line in enumerate(lines) if line.startswith("G1"))]
    assert header and all(line.startswith("(") and line.endswith(")") for line in header)
    assert all(line.count("(") == 1 and line.count(")") == 1 and ";" not in line for line in header)
    assert not any(line.startswith("G0") for line in lines)
    name_line = next(line for line in header if line.startswith("(calibrated geometry name"))
    assert name_line == '(calibrated geometry name: "real\\x29\\x0aG0 X999 \\x28\\x0d\\x00\\x3b M2 \\xe9")'
    assert hashlib.sha256(evil.read_bytes()).hexdigest() in "".join(header)
    written, _ = moves_of(out)  # the header reads as comments; the move ends at the corrected target
    target = compensate(TRUE, [[10, 10, 800, 0, 0, 0]], nominal=NOMINAL).corrected_poses[0]
    assert_allclose(written.end[-1, :3], target[:3], atol=1e-5)


def test_other_words_comments_line_numbers_and_stop_codes_are_kept(capsys, tmp_path):
    text = "%\r\nN5 G21 S1000 M3 (spindle)\r\n\r\nN10 G1 X200 Y100 Z850 F600 M8 (cut) M30 ; end\r\n%\r\n"
    out, _, _ = filter_program(capsys, tmp_path, text)
    written = out.read_bytes().decode()
    assert "\r\n" in written and "\n" not in written.replace("\r\n", "")  # the program's line endings
    lines = written.split("\r\n")
    assert lines[0] == "%" and lines[-2:] == ["%", ""]
    assert "N5 G21 S1000 M3 (spindle)" in lines and "" in lines  # untouched, blank line kept
    moves = [line for line in lines if "X" in line and not line.startswith("(")]
    assert len(moves) > 5  # a 250 mm move is cut into segments
    assert moves[0].startswith("N10 G1 X") and moves[0].endswith(" F600 M8 (cut) ; end")
    assert "M30" not in moves[0] and moves[-1].endswith(" M30")  # a stop code acts after the move
    assert all(line.startswith("G1 X") and line.count(" ") == 6 + line.endswith("M30") for line in moves[1:])


def test_incremental_and_inch_output_reproduces_the_corrected_points(capsys, tmp_path):
    text = "G20 G91 G1 X2 Y1 F20\nX-4\nG21 G90 G0 X0 Y0 Z800\n"
    out, _, _ = filter_program(capsys, tmp_path, text, "--tolerance", "0.01")
    written = out.read_text()
    assert "G91 G1 X" in written and "G20" in written
    intended, _ = moves_of(tmp_path / "in.ngc")
    start = correct_poses(TRUE, NOMINAL, HOME[None], np.array([0]))[0]
    path = correct_path(TRUE, NOMINAL, intended, start, 0.01, 1e-5)
    commanded, _ = moves_of(out, start)
    # read back (increments summed, inches converted) = the corrected points, to the decimals
    assert_allclose(commanded.end[:, :3], path.corrected[:, :3], rtol=0, atol=3e-6 * 25.4)
    assert_allclose(np.degrees(commanded.end[:, 3:]), np.degrees(path.corrected[:, 3:]), rtol=0, atol=1e-5)


def test_corrected_points_are_what_compensate_computes(tmp_path):
    ends = np.array([[-200, -100, 750, 0.05, -0.05, 0.1], [200, 150, 850, -0.1, 0.1, 0.0]])
    moves = Moves.lines(HOME, ends)
    start = correct_poses(TRUE, NOMINAL, HOME[None], np.array([0]))[0]
    path = correct_path(TRUE, NOMINAL, moves, start, 1e-3, 1e-5)
    last = np.flatnonzero(path.t == 1.0)
    assert_allclose(path.corrected[last], compensate(TRUE, ends, nominal=NOMINAL).corrected_poses, atol=1e-9)
    assert path.counts.min() > 5 and path.position <= 0.9e-3  # long moves: subdivided
    # a shorter tolerance needs more segments, about sqrt(10) times
    finer = correct_path(TRUE, NOMINAL, moves, start, 1e-4, 1e-6)
    assert 2.5 < finer.counts.sum() / path.counts.sum() < 4.5


def test_an_unreachable_target_names_its_line_and_nothing_is_written(capsys, tmp_path):
    source, out = tmp_path / "far.ngc", tmp_path / "out.ngc"
    source.write_text("G1 X0 Y0 Z800 F100\nG1 X0 Y0 Z1200\n")
    message = one_error(capsys, *program_args(source, out))
    assert f"{source}: line 2: " in message and "leg length limits" in message
    assert not out.exists()
    message = one_error(capsys, *program_args(source, out, "--skip-infeasible"))
    assert "--skip-infeasible does not apply to --gcode" in message


def test_progress_lines_and_quiet(capsys, tmp_path, monkeypatch):
    from hexcal.io import gcode

    monkeypatch.setattr(gcode, "BLOCK_LINES", 3)
    text = "(a block)\n(without)\n(moves)\n" + "".join(f"G1 X{k} Y0 Z800 F100\n" for k in range(27))
    _, _, err = filter_program(capsys, tmp_path, text)
    steps = re.findall(r"compensate: (\d+)% \((\d+) lines", err)
    percents = [int(p) for p, _ in steps]
    assert 8 <= len(steps) <= 11 and percents == sorted(percents) and steps[-1] == ("100", "30"), err
    _, _, err = filter_program(capsys, tmp_path, text, "--quiet")
    assert err == ""


def test_corrected_pose_files_keep_the_angle_unit_of_the_targets(capsys, tmp_path):
    poses = np.array([[10.0, -20, 790, 0.05, -0.02, 0.03], [-50, 40, 820, -0.04, 0.06, 0.0]])
    comp = compensate(TRUE, poses, nominal=NOMINAL)
    for columns, values in (
        ("a_deg,b_deg,c_deg", np.degrees(poses[:, 3:])),
        ("qx,qy,qz,qw", None),
        ("a,b,c", poses[:, 3:]),
    ):
        from scipy.spatial.transform import Rotation

        if values is None:
            values = Rotation.from_euler(TRUE.euler, poses[:, 3:]).as_quat()
        targets = tmp_path / "t.csv"
        rows = [",".join(repr(float(x)) for x in [*p[:3], *v]) for p, v in zip(poses, values, strict=True)]
        targets.write_text(f"x,y,z,{columns}\n" + "\n".join(rows) + "\n")
        corrected = tmp_path / "c.csv"
        argv = ["--geometry", "paper-hmt-true", "--nominal", "paper-hmt", "--poses", targets, "--out"]
        status, _, err = run(capsys, "compensate", *argv, tmp_path / "l.csv", "--corrected-poses", corrected)
        assert status == 0, err
        assert corrected.read_text().splitlines()[0] == f"id,x,y,z,{columns}"
        back, _ = read_poses(corrected, TRUE.euler)
        assert_allclose(back, comp.corrected_poses, atol=1e-9)
    assert np.abs(np.degrees(comp.corrected_poses[:, 3:])).max() > 1  # degrees, not radians


# -- properties ------------------------------------------------------------------------------
@settings(max_examples=60, deadline=None)
@given(st.text(max_size=60))
def test_comments_are_one_line_and_hold_no_parenthesis(text):
    line = gcode_comment(text)
    assert line.startswith("(") and line.endswith(")") and line.count("(") == line.count(")") == 1
    assert line.isascii() and line.isprintable() and ";" not in line
    if len(line) < 250:  # not cut: the escapes give the text back
        assert line[1:-1].encode().decode("unicode_escape") == text


def _moves(axes: str) -> st.SearchStrategy:
    words = st.dictionaries(st.sampled_from(axes), st.integers(-40, 40), max_size=len(axes))
    return st.tuples(st.sampled_from(["G0", "G1", ""]), words, st.booleans())


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(_moves("XYZABC"), min_size=1, max_size=12))
def test_the_reader_follows_modal_and_incremental_words_like_a_reference(tmp_path, program):
    """Random G0/G1 programs, G90/G91 switched: the reader's end poses are those of a plain
    reference interpreter."""
    lines, pose, incremental = ["G1 F100"], [0.0, 0.0, 800.0, 0.0, 0.0, 0.0], False
    expected = []
    for motion, words, switch in program:
        if switch:
            incremental = not incremental
        text = " ".join([("G91" if incremental else "G90") if switch else "", motion])
        text += " " + " ".join(f"{k}{v / 4:g}" for k, v in words.items())
        lines.append(text.strip() or "(nothing)")
        for axis, value in words.items():
            k = "XYZABC".index(axis)
            number = value / 4 if k < 3 else math.radians(value / 4)
            pose[k] = pose[k] + number if incremental else number
        if words:
            expected.append(list(pose))
    source = tmp_path / "random.ngc"
    source.write_text("\n".join(lines) + "\n")
    moves, _ = moves_of(source)
    assert_allclose(moves.end, np.array(expected).reshape(-1, 6), atol=1e-12)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(_moves("XYABC"), min_size=1, max_size=8))
def test_writing_with_the_exact_geometry_gives_the_program_back(tmp_path, program):
    """With the nominal geometry as the real one, the correction is the identity: the written
    program reads back to the same moves (any modal and incremental mix)."""
    from hexcal.io.gcode import ProgramWriter

    lines = ["G1 F100"]
    for motion, words, switch in program:
        text = f"{'G91' if switch else 'G90'} {motion} " + " ".join(f"{k}{v / 4:g}" for k, v in words.items())
        lines.append(text)
    source, out = tmp_path / "p.ngc", tmp_path / "o.ngc"
    source.write_text("\n".join(lines) + "\n")
    block = next(read_program(source, HOME))
    path = correct_path(NOMINAL, NOMINAL, block.moves, HOME, 1e-3, 1e-5)
    assert (path.counts == 1).all()  # nothing to subdivide
    with out.open("w") as fh:
        ProgramWriter(fh, [], (5, 7, 6), HOME).write(block, path)
    again, _ = moves_of(out)
    assert_allclose(again.end, block.moves.end, atol=1e-5)


def test_linuxcnc_angles_extrinsic_xyz(capsys, tmp_path):
    """With --euler xyz the program's A B C are LinuxCNC's: the filtered program, run with both
    machines in that sequence, still follows its moves' ends."""
    out, _, _ = filter_program(capsys, tmp_path, "G1 X50 Y-40 Z820 A6 B-4 C8 F100\n", "--euler", "xyz")
    true, nominal = TRUE.replace(euler="xyz"), NOMINAL.replace(euler="xyz")
    start = correct_poses(true, nominal, HOME[None], np.array([0]))[0]
    commanded, _ = moves_of(out, start)
    target = np.array([50, -40, 820, *np.radians([6, -4, 8])])
    reached = reached_poses(true, nominal, commanded.end[-1:], target[None])[0]
    assert np.linalg.norm(reached[:3] - target[:3]) < 2e-5
    assert orientation_deviation(reached, target, "xyz") < 1e-7
    wrong = reached_poses(TRUE, NOMINAL, commanded.end[-1:], target[None])[0]  # read as intrinsic XYZ
    assert orientation_deviation(wrong, target, "XYZ") > 1e-3


def test_the_output_cannot_be_the_program(capsys, tmp_path):
    source = tmp_path / "p.ngc"
    source.write_text("G1 X1 Y1 Z800 F10\n")
    before = source.read_bytes()
    message = one_error(capsys, *program_args(source, source))
    assert "also an input" in message and source.read_bytes() == before


def test_targets_outside_the_workspace_box_are_named_by_line(capsys, tmp_path):
    _, _, err = filter_program(capsys, tmp_path, "G1 X0 Y0 Z800 F10\nX280\nX0\n", "--quiet")
    warnings = [line for line in err.splitlines() if "outside the workspace box" in line]
    assert warnings and warnings[0].endswith("1 target(s) of the program outside the workspace box: line 2")


def test_a_target_the_nominal_controller_cannot_reach_is_named():
    # leg 1 3 m longer than the others: no pose of the nominal machine has such legs
    far = NOMINAL.replace(initial_leg_lengths=NOMINAL.initial_leg_lengths + [3000.0, 0, 0, 0, 0, 0])
    with pytest.raises(PathError, match="forward kinematics does not converge") as caught:
        correct_poses(TRUE, far, np.array([HOME, HOME + [10, 0, 0, 0, 0, 0]]), np.array([4, 7]))
    assert caught.value.move == 4
