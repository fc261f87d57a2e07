"""The ``hexcal`` command line, end to end in temporary folders.

Commands run in-process through :func:`hexcal.cli.main` (which returns the exit status),
and a few through the installed ``hexcal`` console script to prove the entry point.
A known failure must give a non-zero status, exactly one line ``hexcal: error: ...`` on
stderr, no traceback, and no output file (nor temporary file) left behind.
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose, assert_array_equal

from hexcal.cli import main
from hexcal.core.kinematics import inverse_kinematics, leg_readings
from hexcal.core.presets import preset
from hexcal.core.workspace import workspace_corners
from hexcal.io import load_geometry, read_legs, read_poses, save_geometry, write_poses, write_table

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
L_COLUMNS = [f"l{i}" for i in range(1, 7)]
DL_COLUMNS = [f"dl{i}" for i in range(1, 7)]


# -- helpers ----------------------------------------------------------------------------


def run(capsys, *argv) -> tuple[int, str, str]:
    """``hexcal argv...`` in-process: (status, stdout, stderr)."""
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def hexcal_executable() -> str:
    beside = Path(sys.executable).parent / "hexcal"
    if beside.exists():
        return str(beside)
    found = shutil.which("hexcal")
    if found is None:
        pytest.fail("the hexcal console script is not installed beside the interpreter nor on PATH")
    return found


def run_script(*argv, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [hexcal_executable(), *map(str, argv)],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def assert_one_error_line(status: int, err: str) -> str:
    assert status != 0
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("hexcal: error:")
    assert lines[0][len("hexcal: error:") :].strip()
    return lines[0]


def listing(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


@pytest.fixture
def paper():
    return preset("paper-hmt")


@pytest.fixture
def corners_file(tmp_path, paper) -> Path:
    path = tmp_path / "corners.csv"
    write_poses(path, workspace_corners(paper), ids=[f"c{k:02d}" for k in range(64)])
    return path


# -- preset ---------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["paper-hmt", "paper-hmt-true"])
def test_preset_writes_a_geometry_that_loads_back_equal(capsys, tmp_path, name):
    out = tmp_path / "g.yaml"
    status, stdout, err = run(capsys, "preset", name, "--out", out)
    assert status == 0, err
    assert err == ""
    assert str(out) in stdout
    loaded, expected = load_geometry(out), preset(name)
    for field in ("base_joints", "platform_joints", "initial_leg_lengths", "leg_gains", "workspace"):
        assert_array_equal(getattr(loaded, field), getattr(expected, field))
    assert loaded.name == name
    assert listing(tmp_path) == {"g.yaml"}


# -- ik / fk ---------------------------------------------------------------------------------


def test_ik_then_fk_returns_the_64_corners(capsys, tmp_path, paper, corners_file):
    legs, poses_out = tmp_path / "legs.csv", tmp_path / "fk.csv"
    status, _, err = run(capsys, "ik", "--geometry", "paper-hmt", "--poses", corners_file, "--out", legs)
    assert status == 0, err
    leg_data = read_legs(legs)
    corners = workspace_corners(paper)
    assert leg_data.ids == tuple(f"c{k:02d}" for k in range(64))
    assert_allclose(leg_data.lengths, inverse_kinematics(paper, corners), rtol=0, atol=1e-9)
    assert_allclose(leg_data.readings, leg_data.lengths - paper.initial_leg_lengths, rtol=0, atol=1e-9)

    status, stdout, err = run(capsys, "fk", "--geometry", "paper-hmt", "--legs", legs, "--out", poses_out)
    assert status == 0, err
    assert "64 pose(s)" in stdout
    poses, ids = read_poses(poses_out, "XYZ")
    assert ids == leg_data.ids
    assert_allclose(poses, corners, rtol=0, atol=1e-7)


def test_fk_with_readings_only(capsys, tmp_path, paper):
    targets = workspace_corners(paper)[::5] * [0.5, 0.5, 1, 0.5, 0.5, 0.5]
    readings = leg_readings(paper, inverse_kinematics(paper, targets))
    legs = tmp_path / "readings.csv"
    write_table(legs, DL_COLUMNS, readings)
    out = tmp_path / "poses.csv"
    status, _, err = run(capsys, "fk", "--geometry", "paper-hmt", "--legs", legs, "--out", out)
    assert status == 0, err
    poses, ids = read_poses(out, "XYZ")
    assert ids == tuple(str(k + 1) for k in range(len(targets)))
    assert_allclose(poses, targets, rtol=0, atol=1e-7)


def test_fk_readings_use_the_geometry_initial_lengths(capsys, tmp_path):
    # the true machine has other l0: the same readings give other poses
    legs, a, b = tmp_path / "dl.csv", tmp_path / "a.csv", tmp_path / "b.csv"
    write_table(legs, DL_COLUMNS, np.full((1, 6), 200.0))
    assert run(capsys, "fk", "--geometry", "paper-hmt", "--legs", legs, "--out", a)[0] == 0
    assert run(capsys, "fk", "--geometry", "paper-hmt-true", "--legs", legs, "--out", b)[0] == 0
    pose_a, pose_b = read_poses(a, "XYZ")[0], read_poses(b, "XYZ")[0]
    true = preset("paper-hmt-true")
    assert_allclose(inverse_kinematics(true, pose_b[0]), true.initial_leg_lengths + 200.0, atol=1e-8)
    assert np.max(np.abs(pose_a - pose_b)[:, :3]) > 0.5


def test_fk_with_guess(capsys, tmp_path, paper, corners_file):
    legs, guess, out = tmp_path / "legs.csv", tmp_path / "guess.csv", tmp_path / "fk.csv"
    assert run(capsys, "ik", "--geometry", "paper-hmt", "--poses", corners_file, "--out", legs)[0] == 0
    corners = workspace_corners(paper)
    write_poses(guess, corners + [3, -3, 2, 0.01, -0.01, 0.01])
    status, _, err = run(
        capsys, "fk", "--geometry", "paper-hmt", "--legs", legs, "--guess", guess, "--out", out
    )
    assert status == 0, err
    assert_allclose(read_poses(out, "XYZ")[0], corners, rtol=0, atol=1e-7)


def test_fk_guess_is_required_without_home_pose(capsys, tmp_path, paper):
    data = paper.to_dict()
    del data["home_pose"]
    geometry = tmp_path / "nohome.yaml"
    geometry.write_text(yaml.safe_dump(data), encoding="utf-8")
    target = np.array([[20.0, -10.0, 820.0, 0.02, -0.03, 0.05]])
    legs, guess, out = tmp_path / "legs.csv", tmp_path / "guess.csv", tmp_path / "fk.csv"
    write_table(legs, L_COLUMNS, inverse_kinematics(paper, target))
    write_poses(guess, [[0, 0, 800, 0, 0, 0]])

    status, _, err = run(capsys, "fk", "--geometry", geometry, "--legs", legs, "--out", out)
    assert "--guess" in assert_one_error_line(status, err)
    assert not out.exists()

    status, _, err = run(capsys, "fk", "--geometry", geometry, "--legs", legs, "--guess", guess, "--out", out)
    assert status == 0, err
    assert_allclose(read_poses(out, "XYZ")[0], target, rtol=0, atol=1e-7)


def test_geometry_as_yaml_path_or_preset_name_gives_the_same_output(capsys, tmp_path, corners_file):
    yaml_path = tmp_path / "g.yaml"
    assert run(capsys, "preset", "paper-hmt", "--out", yaml_path)[0] == 0
    outputs = {}
    for label, spec in (("name", "paper-hmt"), ("yaml", yaml_path)):
        legs, poses = tmp_path / f"legs_{label}.csv", tmp_path / f"fk_{label}.csv"
        assert run(capsys, "ik", "--geometry", spec, "--poses", corners_file, "--out", legs)[0] == 0
        assert run(capsys, "fk", "--geometry", spec, "--legs", legs, "--out", poses)[0] == 0
        outputs[label] = (legs.read_bytes(), poses.read_bytes())
    assert outputs["name"] == outputs["yaml"]


def test_ik_euler_option_with_quaternion_poses(capsys, tmp_path, paper):
    # quaternions fix the physical rotation: any --euler gives the same leg lengths
    from scipy.spatial.transform import Rotation

    poses = workspace_corners(paper)[::7] * [0.8, 0.8, 1, 0.5, 0.5, 0.5]
    quat = Rotation.from_euler("XYZ", poses[:, 3:]).as_quat()
    path = tmp_path / "q.csv"
    write_table(path, ["x", "y", "z", "qx", "qy", "qz", "qw"], np.hstack([poses[:, :3], quat]))
    results = {}
    for euler in ("XYZ", "zyx"):
        out = tmp_path / f"legs_{euler}.csv"
        status, _, err = run(
            capsys, "ik", "--geometry", "paper-hmt", "--poses", path, "--euler", euler, "--out", out
        )
        assert status == 0, err
        results[euler] = read_legs(out).lengths
    assert_allclose(results["zyx"], results["XYZ"], rtol=0, atol=1e-9)
    assert_allclose(results["XYZ"], inverse_kinematics(paper, poses), rtol=0, atol=1e-9)


def test_ik_warns_about_infeasible_poses_and_degree_like_radians(capsys, tmp_path):
    poses, out = tmp_path / "p.csv", tmp_path / "legs.csv"
    write_poses(
        poses, [[0, 0, 800, 0, 0, 0], [0, 0, 2000, 0, 0, 0], [0, 0, 800, 2, 0, 0]], ids=["a", "b", "c"]
    )
    status, _, err = run(capsys, "ik", "--geometry", "paper-hmt", "--poses", poses, "--out", out)
    assert status == 0
    assert "Traceback" not in err
    lines = err.splitlines()
    assert all(line.startswith("hexcal: warning:") for line in lines)
    assert any("outside the leg length limits" in line and ": b" in line for line in lines)
    assert any("a_deg" in line for line in lines)
    assert read_legs(out).ids == ("a", "b", "c")


# -- paper ------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def paper_run(tmp_path_factory):
    """One small run of the paper experiment: (status, stdout, stderr, out folder)."""
    out = tmp_path_factory.mktemp("paper") / "results"
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        status = main(["paper", "--trials", "5", "--seed", "1", "--out", str(out), "--quiet"])
    return status, stdout.getvalue(), stderr.getvalue(), out


def test_paper_writes_table1_json(paper_run):
    status, _, err, out = paper_run
    assert status == 0, err
    summary = json.loads((out / "table1.json").read_text(encoding="utf-8"))
    for key in ("before", "interior", "boundary"):
        assert isinstance(summary[key], float)
        assert np.isfinite(summary[key])
    assert summary["trials"] == 5 and summary["seed"] == 1
    for when in ("before", "after"):
        stats = summary["validation"][when]
        for key in ("position_max", "position_rms", "orientation_max", "orientation_rms"):
            assert isinstance(stats[key], float) and np.isfinite(stats[key]), (when, key)
    # calibration helps, and the order of Table I holds: corners beat interior poses
    assert summary["boundary"] < summary["interior"] < summary["before"]
    after, before = summary["validation"]["after"], summary["validation"]["before"]
    assert after["position_rms"] < before["position_rms"]
    assert after["orientation_rms"] < before["orientation_rms"]
    assert summary["before"] == pytest.approx(2.6652, abs=1e-3)  # fixed true machine: the paper's figure


def test_paper_writes_two_png_figures(paper_run):
    status, _, _, out = paper_run
    assert status == 0
    pngs = sorted(p for p in out.iterdir() if p.suffix == ".png")
    assert len(pngs) == 2
    for png in pngs:
        assert png.read_bytes()[:8] == PNG_MAGIC
        assert png.stat().st_size > 1000
    assert listing(out) == {"table1.json", *(p.name for p in pngs)}  # no temporary files


def test_paper_prints_the_paper_figures(paper_run):
    status, stdout, err, _ = paper_run
    assert status == 0
    for figure in ("2.6652", "0.7236", "0.3752"):
        assert figure in stdout
    assert "table1.json" in stdout
    assert "Traceback" not in err
    assert not any(line.lstrip().startswith("identifications:") for line in err.splitlines())  # --quiet


# -- known failures ------------------------------------------------------------------------------

POSE_HEADER = "x,y,z,a,b,c\n"


def _setup_bad(tmp_path: Path, case: str) -> list[str]:
    """Write the inputs of a failing command; return its arguments (output: tmp_path/'out')."""
    out = str(tmp_path / "out")
    good_poses = tmp_path / "poses.csv"
    good_poses.write_text(POSE_HEADER + "0,0,800,0,0,0\n10,0,820,0.05,0,0\n")
    if case == "missing_geometry":
        return ["ik", "--geometry", str(tmp_path / "nope.yaml"), "--poses", str(good_poses), "--out", out]
    if case == "bad_yaml":
        (tmp_path / "bad.yaml").write_text("units: mm\nbase_joints: [[1, 2, 3]\n  x: : y\n")
        return ["ik", "--geometry", str(tmp_path / "bad.yaml"), "--poses", str(good_poses), "--out", out]
    if case == "units_cm":
        data = preset("paper-hmt").to_dict()
        data["units"] = "cm"
        (tmp_path / "cm.yaml").write_text(yaml.safe_dump(data))
        return ["ik", "--geometry", str(tmp_path / "cm.yaml"), "--poses", str(good_poses), "--out", out]
    if case == "bad_euler":
        return ["ik", "--geometry", "paper-hmt", "--poses", str(good_poses), "--euler", "XXY", "--out", out]
    if case == "nan_pose":
        (tmp_path / "nan.csv").write_text(POSE_HEADER + "0,0,800,0,0,0\n0,nan,800,0,0,0\n")
        return ["ik", "--geometry", "paper-hmt", "--poses", str(tmp_path / "nan.csv"), "--out", out]
    if case == "missing_pose_column":
        (tmp_path / "noz.csv").write_text("x,y,a,b,c\n0,0,0,0,0\n")
        return ["ik", "--geometry", "paper-hmt", "--poses", str(tmp_path / "noz.csv"), "--out", out]
    if case == "missing_pose_file":
        return ["ik", "--geometry", "paper-hmt", "--poses", str(tmp_path / "absent.csv"), "--out", out]
    if case == "ik_out_folder_missing":
        return [
            "ik",
            "--geometry",
            "paper-hmt",
            "--poses",
            str(good_poses),
            "--out",
            str(tmp_path / "no" / "o"),
        ]
    if case == "preset_out_folder_missing":
        return ["preset", "paper-hmt", "--out", str(tmp_path / "no" / "g.yaml")]
    legs = tmp_path / "legs.csv"
    if case == "missing_leg_column":
        write_table(legs, [c for c in DL_COLUMNS if c != "dl3"], np.zeros((2, 5)))
        return ["fk", "--geometry", "paper-hmt", "--legs", str(legs), "--out", out]
    if case == "legs_too_short":
        write_table(legs, L_COLUMNS, np.full((2, 6), 10.0))
        return ["fk", "--geometry", "paper-hmt", "--legs", str(legs), "--out", out]
    if case == "legs_inconsistent":
        write_table(legs, L_COLUMNS, np.array([[700.0, 3000, 700, 3000, 700, 3000]]))
        return ["fk", "--geometry", "paper-hmt", "--legs", str(legs), "--out", out]
    if case == "guess_rows":
        write_table(legs, L_COLUMNS, np.full((3, 6), 800.0))
        return [
            "fk",
            "--geometry",
            "paper-hmt",
            "--legs",
            str(legs),
            "--guess",
            str(good_poses),
            "--out",
            out,
        ]
    if case == "guess_missing":
        write_table(legs, L_COLUMNS, np.full((2, 6), 800.0))
        guess = str(tmp_path / "absent.csv")
        return ["fk", "--geometry", "paper-hmt", "--legs", str(legs), "--guess", guess, "--out", out]
    paper = ["paper", "--trials", "1", "--quiet", "--out", out]
    if case == "trials_0":
        return [*paper, "--trials", "0"]
    if case == "noise_not_a_number":
        return [*paper, "--noise", "leg=abc"]
    if case == "noise_unknown_key":
        return [*paper, "--noise", "foo=1"]
    if case == "noise_no_value":
        return [*paper, "--noise", "leg"]
    if case == "noise_negative":
        return [*paper, "--noise", "pos=-0.1"]
    if case == "paper_missing_geometry":
        return [*paper, "--geometry", str(tmp_path / "nope.yaml")]
    if case == "paper_missing_true":
        return [*paper, "--true", str(tmp_path / "nope.yaml")]
    raise AssertionError(case)


BAD_CASES = [
    "missing_geometry",
    "bad_yaml",
    "units_cm",
    "bad_euler",
    "nan_pose",
    "missing_pose_column",
    "missing_pose_file",
    "ik_out_folder_missing",
    "preset_out_folder_missing",
    "missing_leg_column",
    "legs_too_short",
    "legs_inconsistent",
    "guess_rows",
    "guess_missing",
    "trials_0",
    "noise_not_a_number",
    "noise_unknown_key",
    "noise_no_value",
    "noise_negative",
    "paper_missing_geometry",
    "paper_missing_true",
]
EXPECTED_IN_MESSAGE = {
    "missing_geometry": "nope.yaml",
    "bad_yaml": "not valid YAML",
    "units_cm": "'cm'",
    "bad_euler": "XXY",
    "nan_pose": "column 'y'",
    "missing_pose_column": "missing column 'z'",
    "missing_pose_file": "absent.csv",
    "ik_out_folder_missing": "does not exist",
    "preset_out_folder_missing": "does not exist",
    "missing_leg_column": "dl3",
    "legs_too_short": "outside the leg length limits",
    "legs_inconsistent": "outside the leg length limits",
    "guess_rows": "guess",
    "guess_missing": "absent.csv",
    "trials_0": "--trials",
    "noise_not_a_number": "abc",
    "noise_unknown_key": "foo=1",
    "noise_no_value": "--noise",
    "noise_negative": "--noise",
    "paper_missing_geometry": "nope.yaml",
    "paper_missing_true": "nope.yaml",
}


@pytest.mark.parametrize("case", BAD_CASES)
def test_known_failures_give_one_error_line_and_no_output(capsys, tmp_path, case):
    argv = _setup_bad(tmp_path, case)
    before = listing(tmp_path)
    status, _, err = run(capsys, *argv)
    line = assert_one_error_line(status, err)
    assert EXPECTED_IN_MESSAGE[case] in line
    assert not (tmp_path / "out").exists()
    assert listing(tmp_path) == before  # no output, no temporary file, inputs in place


def test_fk_refuses_leg_lengths_beyond_the_limits(capsys, tmp_path):
    legs, out = tmp_path / "legs.csv", tmp_path / "out.csv"
    write_table(legs, L_COLUMNS, np.full((2, 6), 3000.0))
    status, _, err = run(capsys, "fk", "--geometry", "paper-hmt", "--legs", legs, "--out", out)
    assert_one_error_line(status, err)
    assert not out.exists()


def test_paper_out_that_is_a_file_is_refused_and_kept(capsys, tmp_path):
    out = tmp_path / "results"
    out.write_bytes(b"not a folder")
    status, _, err = run(capsys, "paper", "--trials", "1", "--out", out, "--quiet")
    assert "not a folder" in assert_one_error_line(status, err)
    assert out.read_bytes() == b"not a folder"


def test_failure_keeps_an_existing_output_file(capsys, tmp_path):
    out = tmp_path / "legs.csv"
    out.write_bytes(b"previous result\n")
    (tmp_path / "nan.csv").write_text(POSE_HEADER + "0,0,800,0,inf,0\n")
    status, _, err = run(
        capsys, "ik", "--geometry", "paper-hmt", "--poses", tmp_path / "nan.csv", "--out", out
    )
    assert_one_error_line(status, err)
    assert out.read_bytes() == b"previous result\n"
    assert listing(tmp_path) == {"legs.csv", "nan.csv"}


def test_inputs_are_unchanged_by_commands(capsys, tmp_path, corners_file):
    geometry = tmp_path / "g.yaml"
    save_geometry(preset("paper-hmt"), geometry)
    legs, poses = tmp_path / "legs.csv", tmp_path / "fk.csv"
    inputs = [geometry, corners_file]
    before = [p.read_bytes() for p in inputs]
    assert run(capsys, "ik", "--geometry", geometry, "--poses", corners_file, "--out", legs)[0] == 0
    legs_bytes = legs.read_bytes()
    assert run(capsys, "fk", "--geometry", geometry, "--legs", legs, "--out", poses)[0] == 0
    assert [p.read_bytes() for p in inputs] == before
    assert legs.read_bytes() == legs_bytes


def test_usage_errors_exit_with_status_2(capsys):
    with pytest.raises(SystemExit) as info:
        main(["preset", "no-such-machine", "--out", "x.yaml"])
    assert info.value.code == 2
    assert "invalid choice" in capsys.readouterr().err


# -- the installed console script ------------------------------------------------------------------


def test_console_script_runs_preset(tmp_path):
    proc = run_script("preset", "paper-hmt", "--out", "g.yaml", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "g.yaml" in proc.stdout
    loaded = load_geometry(tmp_path / "g.yaml")
    assert_array_equal(loaded.base_joints, preset("paper-hmt").base_joints)


def test_console_script_reports_errors_in_one_line(tmp_path):
    (tmp_path / "nan.csv").write_text(POSE_HEADER + "0,0,nan,0,0,0\n")
    proc = run_script(
        "ik", "--geometry", "paper-hmt", "--poses", "nan.csv", "--out", "legs.csv", cwd=tmp_path
    )
    assert proc.returncode == 1
    line = assert_one_error_line(proc.returncode, proc.stderr)
    assert "nan.csv" in line and "line 2" in line
    assert listing(tmp_path) == {"nan.csv"}


def test_python_dash_m_hexcal(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "hexcal", "paper", "--trials", "0"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 1
    assert "--trials" in assert_one_error_line(proc.returncode, proc.stderr)


def test_fk_unreachable_lengths_without_limits_report_no_convergence(capsys, tmp_path, paper):
    """Without leg limits the solver itself must refuse leg lengths no pose can produce."""
    free = tmp_path / "free.yaml"
    save_geometry(paper.replace(leg_length_limits=None), free)
    legs, out = tmp_path / "legs.csv", tmp_path / "poses.csv"
    write_table(legs, [f"l{i}" for i in range(1, 7)], np.full((2, 6), 10.0))
    status, _, err = run(capsys, "fk", "--geometry", str(free), "--legs", str(legs), "--out", str(out))
    line = assert_one_error_line(status, err)
    assert "did not converge" in line and "1, 2" in line
    assert not out.exists()


# -- structure and start-up of the command line (issue 8) --------------------------------------

CLI_DIR = Path(__file__).resolve().parents[1] / "src" / "hexcal" / "cli"


def _top_imports(path: Path) -> set[str]:
    """Modules imported at the top level of a file (not inside functions or TYPE_CHECKING)."""
    import ast

    names: set[str] = set()
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.Import):
            names |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
    return names


def test_cli_module_tops_import_only_the_standard_library_errors_and_common():
    allowed = {"hexcal.errors", "hexcal.cli.common", "hexcal.cli.noise", "hexcal._lazy"}
    for path in sorted(CLI_DIR.glob("*.py")):
        imports = _top_imports(path)
        hexcal_imports = {m for m in imports if m.split(".")[0] == "hexcal"} - allowed
        if path.name == "main.py":  # assembles the parser from the command modules
            hexcal_imports -= {"hexcal.cli"}
        if path.name == "__init__.py":  # re-exports main
            hexcal_imports -= {"hexcal.cli.main"}
        assert not hexcal_imports, f"{path.name} imports {hexcal_imports} at its top"
        third_party = {m for m in imports if m.split(".")[0] in ("numpy", "scipy", "yaml", "matplotlib")}
        assert not third_party, f"{path.name} imports {third_party} at its top"
    # the command modules never import main nor the package (no cycle), even inside functions
    import ast

    for name in ("common", "noise", "kinematics", "calibrate", "simulate", "plan"):
        for node in ast.walk(ast.parse((CLI_DIR / f"{name}.py").read_text())):
            if isinstance(node, ast.ImportFrom):
                assert node.module not in ("hexcal.cli", "hexcal.cli.main"), name
            elif isinstance(node, ast.Import):
                assert not {a.name for a in node.names} & {"hexcal.cli", "hexcal.cli.main"}, name


def _modules_after(argv: list[str], cwd: Path) -> set[str]:
    probe = (
        "import sys\n"
        "from hexcal.cli import main\n"
        "try:\n    main(sys.argv[1:])\nexcept SystemExit:\n    pass\n"
        "print(' '.join(sorted(sys.modules)), file=sys.stderr)\n"
    )
    run = subprocess.run(
        [sys.executable, "-c", probe, *argv],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    return set(run.stderr.strip().splitlines()[-1].split())


def test_help_imports_no_numpy_and_ik_no_scipy(tmp_path):
    assert "numpy" not in _modules_after(["--help"], tmp_path)
    assert "numpy" not in _modules_after(["ik", "--help"], tmp_path)
    poses = workspace_corners(preset("paper-hmt"))[:5]
    write_poses(tmp_path / "poses.csv", poses, [f"p{k}" for k in range(5)])
    modules = _modules_after(
        ["ik", "--geometry", "paper-hmt", "--poses", "poses.csv", "--out", "legs.csv"], tmp_path
    )
    assert (tmp_path / "legs.csv").exists()
    assert "numpy" in modules and "scipy" not in modules and "matplotlib" not in modules


def test_preset_names_of_the_parser_are_the_presets():
    from hexcal.cli.common import PRESET_NAMES
    from hexcal.core import PRESETS

    assert tuple(PRESET_NAMES) == tuple(PRESETS)


def test_command_error_is_a_usage_error_and_main_is_the_function():
    import hexcal.cli
    from hexcal.cli import CommandError
    from hexcal.errors import HexcalError, UsageError

    assert issubclass(CommandError, UsageError) and issubclass(CommandError, HexcalError)
    assert callable(hexcal.cli.main) and hexcal.cli.main is main


def test_interrupt_prints_one_line_and_exits_130(capsys, monkeypatch, tmp_path):
    from hexcal.cli import kinematics

    def interrupted(_args):
        raise KeyboardInterrupt

    monkeypatch.setattr(kinematics, "cmd_preset", interrupted)
    status, out, err = run(capsys, "preset", "paper-hmt", "--out", tmp_path / "g.yaml")
    assert (status, out, err) == (130, "", "hexcal: interrupted\n")


def test_warnings_print_as_one_hexcal_line(capsys, monkeypatch, tmp_path):
    import warnings

    from hexcal.cli import kinematics
    from hexcal.errors import InputWarning

    def warns(_args):
        warnings.warn("angles look like degrees", InputWarning, stacklevel=1)

    monkeypatch.setattr(kinematics, "cmd_preset", warns)
    status, _, err = run(capsys, "preset", "paper-hmt", "--out", tmp_path / "g.yaml")
    assert (status, err) == (0, "hexcal: warning: angles look like degrees\n")


def test_public_api_is_lazy_and_complete():
    probe = "import sys, hexcal; print('numpy' in sys.modules); print(' '.join(hexcal.__all__))"
    run = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=60, check=True
    )
    numpy_loaded, names = run.stdout.splitlines()
    assert numpy_loaded == "False"
    import hexcal

    for name in names.split():
        assert getattr(hexcal, name) is not None, name
    assert {"Geometry", "preset", "estimate", "ESTIMATORS", "run_study", "HexcalError"} <= set(names.split())
