"""Calibrating a real machine from measurement files, through the ``hexcal`` command.

``synthesize`` stands in for the measurement campaign (the seed paper's machine and noise,
see tests/test_workflow.py for the provenance), then ``identify``, ``validate`` and
``compensate`` run as a user would run them. Commands run in-process through
:func:`hexcal.cli.main`, in temporary folders. A known failure must give a non-zero status,
exactly one line ``hexcal: error: ...`` on stderr, no traceback and no output file; inputs are
never modified.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose, assert_array_equal
from scipy.spatial.transform import Rotation

from hexcal.calibration import estimate
from hexcal.calibration.validation import validate
from hexcal.cli import main
from hexcal.core.kinematics import forward_kinematics, inverse_kinematics, leg_lengths, leg_readings
from hexcal.core.parameters import PARAMETER_NAMES, select_parameters
from hexcal.core.presets import preset
from hexcal.core.workspace import workspace_corners
from hexcal.instruments.pose import Measurements
from hexcal.io import (
    load_geometry,
    read_legs,
    read_measurements,
    read_poses,
    read_table,
    save_geometry,
    write_measurements,
    write_poses,
    write_table,
)

NOMINAL = preset("paper-hmt")
TRUE = preset("paper-hmt-true")
CORNERS = workspace_corners(NOMINAL)
CORNER_IDS = [f"c{k:02d}" for k in range(64)]
_PICK = np.random.default_rng(2009).permutation(64)
CALIBRATION = _PICK[:20]
HELD_OUT = _PICK[20:30]
SECTIONS = (
    "[[Fit statistics]]",
    "[[Parameters]]",
    "[[Correlations]]",
    "[[Identifiability]]",
    "[[Pose check]]",
)


# -- helpers ----------------------------------------------------------------------------------------


def run(capsys, *argv) -> tuple[int, str, str]:
    """``hexcal argv...`` in-process: (status, stdout, stderr)."""
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def ok(capsys, *argv) -> str:
    status, out, err = run(capsys, *argv)
    assert status == 0, err
    assert "Traceback" not in err
    return out


def assert_one_error_line(status: int, err: str) -> str:
    assert status != 0
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("hexcal: error:")
    return lines[0]


def listing(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def snapshot(*paths: Path) -> dict[Path, bytes]:
    return {p: p.read_bytes() for p in paths}


def assert_unchanged(before: dict[Path, bytes]) -> None:
    for path, content in before.items():
        assert path.read_bytes() == content, f"{path} was modified"


def identify_json(capsys, tmp_path: Path, data: Path, *extra, tag: str = "fit") -> dict:
    """``hexcal identify`` on ``data``; the JSON summary."""
    out_json = tmp_path / f"{tag}.json"
    ok(
        capsys,
        "identify",
        "--geometry",
        "paper-hmt",
        "--data",
        data,
        "--out",
        tmp_path / f"{tag}.yaml",
        "--json",
        out_json,
        *extra,
    )
    return json.loads(out_json.read_text())


def assert_same_parameters(a: dict, b: dict, atol: float) -> None:
    assert list(a) == list(b)
    assert_allclose(np.array(list(a.values())), np.array(list(b.values())), rtol=0, atol=atol)


def write_corner_poses(path: Path, indices, orientation: str = "rad") -> Path:
    ids = [CORNER_IDS[k] for k in indices]
    poses = CORNERS[indices]
    if orientation == "rad":
        write_poses(path, poses, ids)
    else:  # unit quaternions, scalar last: the same physical poses in any Euler sequence
        quat = Rotation.from_euler("XYZ", poses[:, 3:]).as_quat()
        write_table(path, ["x", "y", "z", "qx", "qy", "qz", "qw"], np.column_stack([poses[:, :3], quat]), ids)
    return path


def synthesize(
    capsys, poses: Path, out: Path, seed: int, *extra, true: str | Path = "paper-hmt-true"
) -> Path:
    ok(
        capsys,
        "synthesize",
        "--nominal",
        "paper-hmt",
        "--true",
        true,
        "--poses",
        poses,
        "--out",
        out,
        "--seed",
        seed,
        *extra,
    )
    return out


@pytest.fixture
def files(tmp_path, capsys) -> dict[str, Path]:
    """Calibration (20 corners, seed 1) and held-out (10 corners, seed 2) measurement files."""
    cal_poses = write_corner_poses(tmp_path / "cal_poses.csv", CALIBRATION)
    val_poses = write_corner_poses(tmp_path / "val_poses.csv", HELD_OUT)
    return {
        "cal": synthesize(capsys, cal_poses, tmp_path / "cal.csv", 1),
        "val": synthesize(capsys, val_poses, tmp_path / "val.csv", 2),
    }


# -- 1. file variants --------------------------------------------------------------------------------


@pytest.mark.parametrize(("orientation", "column"), [("deg", "a_deg"), ("quat", "qx")])
def test_orientation_columns_do_not_change_the_identified_machine(
    capsys, tmp_path, files, orientation, column
):
    """The same seed written as rad, deg or quaternion columns: the same parameters (1e-6 mm).

    Measured with the default estimator: 6e-12 mm (deg) and 2.1e-7 mm (quat), the latter the
    solver's stopping point, not the file's 15 significant digits.
    """
    other = synthesize(
        capsys,
        tmp_path / "cal_poses.csv",
        tmp_path / f"cal_{orientation}.csv",
        1,
        "--orientation",
        orientation,
    )
    assert column in read_table(other).columns
    assert other.read_bytes() != files["cal"].read_bytes()
    rad = identify_json(capsys, tmp_path, files["cal"], tag="rad")
    variant = identify_json(capsys, tmp_path, other, tag=orientation)
    assert_same_parameters(variant["parameters"], rad["parameters"], atol=1e-6)
    assert max(abs(v - rad["start"][k]) for k, v in rad["parameters"].items()) > 1.0


@pytest.mark.parametrize("orientation", ["rad", "quat"])
def test_euler_option_reads_another_sequence(capsys, tmp_path, files, orientation):
    """The calibration file rewritten in zyx angles, identified with ``--euler zyx``."""
    data = read_measurements(files["cal"], "XYZ")
    zyx = Rotation.from_euler("XYZ", data.poses[:, 3:]).as_euler("zyx")
    path = tmp_path / f"cal_zyx_{orientation}.csv"
    write_measurements(
        path,
        Measurements(np.column_stack([data.poses[:, :3], zyx]), data.readings, data.ids),
        "zyx",
        orientation,
    )
    xyz = identify_json(capsys, tmp_path, files["cal"], tag="xyz")
    result = identify_json(capsys, tmp_path, path, "--euler", "zyx", tag="zyx")
    assert_same_parameters(result["parameters"], xyz["parameters"], atol=1e-6)
    assert load_geometry(tmp_path / "zyx.yaml").euler == "zyx"
    if orientation == "rad":  # negative control: the same file without --euler is another machine
        status, _, err = run(
            capsys, "identify", "--geometry", "paper-hmt", "--data", path, "--out", tmp_path / "w.yaml"
        )
        assert "Euler sequence looks wrong" in assert_one_error_line(status, err)  # refused, named
        assert not (tmp_path / "w.yaml").exists()
        wrong = identify_json(capsys, tmp_path, path, "--force", tag="wrong")
        assert max(abs(wrong["parameters"][k] - v) for k, v in xyz["parameters"].items()) > 0.1


def test_synthesize_and_identify_in_zyx(capsys, tmp_path):
    """Quaternion target poses are the same physical poses in XYZ and in zyx.

    Without angle measurement noise (which is drawn per Euler angle, so in a sequence-dependent
    way) the same seed gives the same physical measurements, and the same machine. Measured:
    the parameters differ by 1.8e-7 mm.
    """
    poses = write_corner_poses(tmp_path / "poses_q.csv", CALIBRATION, orientation="quat")
    xyz_file = synthesize(capsys, poses, tmp_path / "xyz.csv", 3, "--noise", "ang=0", "--orientation", "deg")
    zyx_file = synthesize(capsys, poses, tmp_path / "zyx.csv", 3, "--noise", "ang=0", "--euler", "zyx")
    assert not np.allclose(
        read_table(xyz_file).numbers(["a_deg"]), np.rad2deg(read_table(zyx_file).numbers(["a"]))
    )
    xyz = identify_json(capsys, tmp_path, xyz_file, tag="xyz")
    zyx = identify_json(capsys, tmp_path, zyx_file, "--euler", "zyx", tag="zyx")
    assert_same_parameters(zyx["parameters"], xyz["parameters"], atol=1e-6)


# -- 2. identify then validate ------------------------------------------------------------------------


def test_identify_then_validate(capsys, tmp_path, files):
    """Calibrate on 20 corners, validate on 10 others; the per-pose table has their ids.

    Measured on the 10 held-out corners: position error RMS 47.9 mm nominal, 0.052 mm calibrated
    with the default estimator (ml), 0.216 mm with ``--method length``.
    """
    before = snapshot(files["cal"], files["val"])
    calibrated, table = tmp_path / "calibrated.yaml", tmp_path / "validation.csv"
    ok(capsys, "identify", "--geometry", "paper-hmt", "--data", files["cal"], "--out", calibrated)
    out = ok(
        capsys,
        "validate",
        "--geometry",
        calibrated,
        "--data",
        files["val"],
        "--nominal",
        "paper-hmt",
        "--out",
        table,
    )
    assert "Validation on 10 held-out pose(s)" in out
    assert_unchanged(before)
    t = read_table(table)
    assert t.columns == (
        "id",
        "leg_rms",
        "position_error",
        "orientation_error",
        "nominal_leg_rms",
        "nominal_position_error",
        "nominal_orientation_error",
    )
    assert list(t.ids()) == [CORNER_IDS[k] for k in HELD_OUT]
    position, nominal_position = (
        t.numbers(["position_error"])[:, 0],
        t.numbers(["nominal_position_error"])[:, 0],
    )
    rms = np.sqrt(np.mean(position**2))
    nominal_rms = np.sqrt(np.mean(nominal_position**2))
    assert rms < 1.0
    assert nominal_rms > 10.0
    # the table is the library's validation, to the 15 digits written
    held_out = read_measurements(files["val"], "XYZ")
    library = validate(load_geometry(calibrated), held_out)
    assert_allclose(position, library.position_error, rtol=1e-12, atol=1e-12)
    assert_allclose(t.numbers(["orientation_error"])[:, 0], library.orientation_error, rtol=1e-12, atol=1e-15)
    assert_allclose(nominal_position, validate(NOMINAL, held_out).position_error, rtol=1e-12)
    assert f"{rms:.4g}" in out and f"{nominal_rms:.4g}" in out


# -- 3. gross errors ----------------------------------------------------------------------------------


def spoil(path: Path, kind: str, out: Path) -> tuple[Path, list[str], Measurements]:
    """A copy of a measurement file with one row bumped 5 mm in x, or two rows' readings swapped."""
    data = read_measurements(path, "XYZ")
    poses, readings = data.poses.copy(), data.readings.copy()
    if kind == "bump":
        rows = [3]
        poses[3, 0] += 5.0
    else:
        rows = [5, 12]
        readings[rows] = readings[rows[::-1]]
    write_measurements(out, Measurements(poses, readings, data.ids), "XYZ")
    return out, [data.ids[k] for k in rows], Measurements(poses, readings, data.ids)


@pytest.mark.parametrize("kind", ["bump", "swap"])
def test_robust_identify_reports_exactly_the_spoiled_rows(capsys, tmp_path, files, kind):
    path, bad, data = spoil(files["cal"], kind, tmp_path / "spoiled.csv")
    before = snapshot(path)
    robust = identify_json(capsys, tmp_path, path, "--robust", tag="robust")
    assert sorted(robust["outliers"]) == sorted(bad)
    assert robust["poses"] == 20 - len(bad)
    assert robust["ids"] == [i for i in data.ids if i not in bad]
    assert robust["flagged"] == []
    meta = load_geometry(tmp_path / "robust.yaml").calibration
    assert sorted(meta["outliers"]) == sorted(bad) and meta["poses"] == 20 - len(bad)
    # the robust result is the plain identification on the file without those rows, to where the
    # solvers stop (1.3e-9 mm measured: the last fits start from their noise iterations' last
    # parameters, which differ by the paths taken)
    keep = [k for k, i in enumerate(data.ids) if i not in bad]
    write_measurements(tmp_path / "without.csv", data.subset(keep), "XYZ")
    plain = identify_json(capsys, tmp_path, tmp_path / "without.csv", tag="without")
    assert_same_parameters(robust["parameters"], plain["parameters"], atol=1e-8)
    assert_unchanged(before)


def test_plain_identify_warns_about_the_bumped_pose(capsys, tmp_path, files):
    path, bad, _ = spoil(files["cal"], "bump", tmp_path / "bumped.csv")
    report, out_json = tmp_path / "report.txt", tmp_path / "fit.json"
    out = ok(
        capsys,
        "identify",
        "--geometry",
        "paper-hmt",
        "--data",
        path,
        "--out",
        tmp_path / "fit.yaml",
        "--report",
        report,
        "--json",
        out_json,
    )
    result = json.loads(out_json.read_text())
    assert result["flagged"][0] == bad[0]
    assert result["outliers"] == []
    for text in (out, report.read_text()):
        pose_check = text.split("[[Pose check]]", 1)[1]
        warning = [line for line in pose_check.splitlines() if "warning" in line]
        assert len(warning) == 1 and bad[0] in warning[0] and "--robust" in warning[0]
    clean = identify_json(capsys, tmp_path, files["cal"], tag="clean")
    assert clean["flagged"] == []


# -- 4. compensation ------------------------------------------------------------------------------------

INFEASIBLE = {"low": [0, 0, 500, 0, 0, 0], "high": [0, 0, 1150, 0, 0, 0]}


def write_targets(
    path: Path, extra: dict[str, list[float]] | None = None
) -> tuple[Path, np.ndarray, list[str]]:
    """Ten corners as targets, with extra named targets inserted after the third."""
    ids = [CORNER_IDS[k] for k in HELD_OUT]
    poses = list(CORNERS[HELD_OUT])
    for name, pose in (extra or {}).items():
        ids.insert(3, name)
        poses.insert(3, np.array(pose, dtype=float))
    write_poses(path, np.array(poses), ids)
    return path, np.array(poses), ids


def test_compensate_with_the_exact_geometry(capsys, tmp_path):
    targets_file, targets, ids = write_targets(tmp_path / "targets.csv")
    before = snapshot(targets_file)
    legs_file, corrected_file = tmp_path / "legs.csv", tmp_path / "corrected.csv"
    ok(
        capsys,
        "compensate",
        "--geometry",
        "paper-hmt-true",
        "--poses",
        targets_file,
        "--out",
        legs_file,
        "--nominal",
        "paper-hmt",
        "--corrected-poses",
        corrected_file,
    )
    assert_unchanged(before)
    legs = read_legs(legs_file)
    assert list(legs.ids) == ids
    reached = forward_kinematics(TRUE, leg_lengths(TRUE, legs.readings), guess=targets)
    assert reached.all_converged
    assert_allclose(reached.poses, targets, rtol=0, atol=1e-6)
    assert_allclose(legs.lengths, inverse_kinematics(TRUE, targets), rtol=0, atol=1e-9)
    corrected, corrected_ids = read_poses(corrected_file, "XYZ")
    assert list(corrected_ids) == ids
    assert_allclose(
        leg_readings(NOMINAL, inverse_kinematics(NOMINAL, corrected)), legs.readings, rtol=0, atol=1e-6
    )
    assert np.max(np.abs(corrected[:, :3] - targets[:, :3])) > 10.0


def test_compensate_refuses_infeasible_targets_by_name(capsys, tmp_path):
    targets_file, _, _ = write_targets(tmp_path / "targets.csv", INFEASIBLE)
    before, names = listing(tmp_path), snapshot(targets_file)
    status, _, err = run(
        capsys,
        "compensate",
        "--geometry",
        "paper-hmt-true",
        "--poses",
        targets_file,
        "--out",
        tmp_path / "legs.csv",
        "--nominal",
        "paper-hmt",
        "--corrected-poses",
        tmp_path / "corrected.csv",
    )
    line = assert_one_error_line(status, err)
    assert "low" in line and "high" in line and "outside the leg length limits" in line
    assert listing(tmp_path) == before
    assert_unchanged(names)


def test_compensate_skip_infeasible_writes_the_others(capsys, tmp_path):
    targets_file, targets, ids = write_targets(tmp_path / "targets.csv", INFEASIBLE)
    legs_file, corrected_file = tmp_path / "legs.csv", tmp_path / "corrected.csv"
    status, _, err = run(
        capsys,
        "compensate",
        "--geometry",
        "paper-hmt-true",
        "--poses",
        targets_file,
        "--out",
        legs_file,
        "--nominal",
        "paper-hmt",
        "--corrected-poses",
        corrected_file,
        "--skip-infeasible",
    )
    assert status == 0, err
    assert "low" in err and "high" in err and "skipped 2" in err
    feasible = [i for i in ids if i not in INFEASIBLE]
    legs = read_legs(legs_file)
    assert list(legs.ids) == feasible
    assert list(read_poses(corrected_file, "XYZ")[1]) == feasible
    keep = [k for k, i in enumerate(ids) if i not in INFEASIBLE]
    reached = forward_kinematics(TRUE, leg_lengths(TRUE, legs.readings), guess=targets[keep])
    assert_allclose(reached.poses, targets[keep], rtol=0, atol=1e-6)


def test_skip_infeasible_with_a_target_the_nominal_controller_cannot_solve(capsys, tmp_path):
    """A target in the base plane (z = 1 mm: a pose file in metres?) is outside the leg limits."""
    targets_file, _, ids = write_targets(tmp_path / "targets.csv", {"flat": [0, 0, 1, 0, 0, 0]})
    legs_file = tmp_path / "legs.csv"
    status, _, err = run(
        capsys,
        "compensate",
        "--geometry",
        "paper-hmt-true",
        "--poses",
        targets_file,
        "--out",
        legs_file,
        "--nominal",
        "paper-hmt",
        "--skip-infeasible",
    )
    assert status == 0, err
    assert "flat" in err
    assert list(read_legs(legs_file).ids) == [i for i in ids if i != "flat"]


# -- 5. leg gains -------------------------------------------------------------------------------------


def test_identify_leg_gains(capsys, tmp_path):
    """True gains 1 + U(±1e-3) (seed 0), 64 corners, the paper's noise: g1..g6 in the JSON.

    With the default estimator, and with ``--method length`` compared to the library's
    :func:`hexcal.estimation.identification.identify` on the same file. Measured (RMS true deviation
    0.00072): RMS gain error 0.000084 (ml), 0.00030 (length); largest error 1.5 (ml) and 2.9
    (length) reported standard errors.
    """
    gains = 1 + np.random.default_rng(0).uniform(-1e-3, 1e-3, 6)
    true_file = tmp_path / "true.yaml"
    save_geometry(TRUE.replace(leg_gains=gains), true_file)
    poses = write_corner_poses(tmp_path / "corners.csv", np.arange(64))
    data = synthesize(capsys, poses, tmp_path / "m.csv", 4, true=true_file)
    result = identify_json(capsys, tmp_path, data, "--fit", "joints,l0,gains")
    assert list(result["parameters"]) == list(PARAMETER_NAMES)
    assert result["n_parameters"] == 48
    identified = np.array([result["parameters"][f"g{i}"] for i in range(1, 7)])
    stderr = np.array([result["stderr"][f"g{i}"] for i in range(1, 7)])
    assert np.all(np.abs(identified - gains) <= 4 * stderr)
    assert_allclose(load_geometry(tmp_path / "fit.yaml").leg_gains, identified, rtol=0, atol=1e-15)
    length = identify_json(capsys, tmp_path, data, "--fit", "joints,l0,gains", "--method", "length", tag="ls")
    library = estimate(
        NOMINAL,
        read_measurements(data, "XYZ"),
        "length",
        select_parameters("joints,l0,gains"),
        with_bound=False,
    )
    assert_allclose(list(length["parameters"].values()), library.values, rtol=0, atol=1e-9)
    assert_allclose(list(length["stderr"].values()), library.stderr, rtol=1e-9)
    # without gains in --fit the gains stay at 1
    plain = identify_json(capsys, tmp_path, data, tag="plain")
    assert "g1" not in plain["parameters"]
    assert_array_equal(load_geometry(tmp_path / "plain.yaml").leg_gains, np.ones(6))


# -- 6. fixed parameters and bad names ---------------------------------------------------------------


def test_fix_holds_parameters_at_their_nominal_values(capsys, tmp_path, files):
    result = identify_json(capsys, tmp_path, files["cal"], "--fix", "u1.z", "l0_1")
    assert "u1.z" not in result["parameters"] and "l0_1" not in result["parameters"]
    assert "u1.z" not in result["stderr"] and "l0_1" not in result["stderr"]
    assert list(result["parameters"]) == [n for n in PARAMETER_NAMES[:42] if n not in ("u1.z", "l0_1")]
    assert result["n_parameters"] == 40
    calibrated = load_geometry(tmp_path / "fit.yaml")
    assert calibrated.base_joints[0, 2] == NOMINAL.base_joints[0, 2] == 0.0
    assert calibrated.initial_leg_lengths[0] == NOMINAL.initial_leg_lengths[0] == 604.8652
    # the others were identified (they move by millimetres)
    assert max(abs(v - result["start"][k]) for k, v in result["parameters"].items()) > 1.0
    assert_allclose(
        calibrated.to_vector(),
        [result["parameters"].get(n, NOMINAL.parameters()[n]) for n in PARAMETER_NAMES[:42]],
    )
    assert set(calibrated.calibration["stderr"]) == set(result["parameters"])


@pytest.mark.parametrize(
    ("option", "value", "named"),
    [("--fix", "u9.x", "u9.x"), ("--fix", "l0_7", "l0_7"), ("--fit", "joints,l0,wheels", "wheels")],
)
def test_unknown_parameter_names_give_one_error_line(capsys, tmp_path, files, option, value, named):
    before = listing(tmp_path)
    status, out, err = run(
        capsys,
        "identify",
        "--geometry",
        "paper-hmt",
        "--data",
        files["cal"],
        "--out",
        tmp_path / "fit.yaml",
        "--json",
        tmp_path / "fit.json",
        option,
        value,
    )
    assert named in assert_one_error_line(status, err)
    assert listing(tmp_path) == before
    assert "[[Parameters]]" not in out


# -- 9. bad inputs --------------------------------------------------------------------------------------


def bad_input(kind: str, tmp_path: Path, cal: Path) -> Path:
    path = tmp_path / f"{kind}.csv"
    data = read_measurements(cal, "XYZ")
    if kind == "too_few":
        write_measurements(path, data.subset(np.arange(5)), "XYZ")
    elif kind == "no_rotation":
        # the true machine measured exactly at poses that never rotate
        poses = np.column_stack([data.poses[:, :3], np.zeros((len(data), 3))])
        readings = leg_readings(TRUE, inverse_kinematics(TRUE, poses))
        write_measurements(path, Measurements(poses, readings, data.ids), "XYZ")
    else:  # a NaN on line 5 (after the comment, the header and two rows), column dl3
        lines = cal.read_text().splitlines(keepends=True)
        assert lines[0].startswith("#") and lines[1].startswith("id,")
        cells = lines[4].split(",")
        cells[3] = "nan"
        lines[4] = ",".join(cells)
        path.write_text("".join(lines))
    return path


@pytest.mark.parametrize(
    ("kind", "expected"),
    [("too_few", ["poses"]), ("no_rotation", ["rank-deficient"]), ("nan", ["line 5", "column 'dl3'"])],
)
def test_identify_bad_inputs(capsys, tmp_path, files, kind, expected):
    """Each bad file, with and without --robust: one error line, no output, input unchanged."""
    path = bad_input(kind, tmp_path, files["cal"])
    outputs = [tmp_path / "fit.yaml", tmp_path / "fit.json", tmp_path / "report.txt"]
    for robust in ([], ["--robust"]):
        before, content = listing(tmp_path), snapshot(path, files["cal"])
        status, _, err = run(
            capsys,
            "identify",
            "--geometry",
            "paper-hmt",
            "--data",
            path,
            "--out",
            outputs[0],
            "--json",
            outputs[1],
            "--report",
            outputs[2],
            *robust,
        )
        line = assert_one_error_line(status, err)
        for words in expected:
            assert words in line
        assert not any(p.exists() for p in outputs)
        assert listing(tmp_path) == before
        assert_unchanged(content)


@pytest.mark.parametrize(
    "robust",
    [pytest.param([], id="plain"), pytest.param(["--robust"], id="robust")],
)
def test_too_few_poses_message_counts_the_rows_of_the_file(capsys, tmp_path, files, robust):
    path = bad_input("too_few", tmp_path, files["cal"])
    status, _, err = run(
        capsys, "identify", "--geometry", "paper-hmt", "--data", path, "--out", tmp_path / "fit.yaml", *robust
    )
    assert "5 poses" in assert_one_error_line(status, err)


# -- 10. report and calibrated geometry files ---------------------------------------------------------


def test_identify_writes_a_loadable_calibrated_geometry_and_report(capsys, tmp_path, files):
    out_yaml, report, out_json = tmp_path / "fit.yaml", tmp_path / "report.txt", tmp_path / "fit.json"
    out = ok(
        capsys,
        "identify",
        "--geometry",
        "paper-hmt",
        "--data",
        files["cal"],
        "--out",
        out_yaml,
        "--report",
        report,
        "--json",
        out_json,
    )
    result = json.loads(out_json.read_text())
    text = report.read_text()
    assert text.strip() in out
    lines = text.splitlines()
    positions = [lines.index(next(line for line in lines if line.startswith(s))) for s in SECTIONS]
    assert positions == sorted(positions)
    rows = [line.split() for line in lines[positions[1] + 1 : positions[2]]]
    names = [row[0] for row in rows if row and row[0] in PARAMETER_NAMES]
    assert names == list(PARAMETER_NAMES[:42])
    after = next(line for line in lines if line.strip().startswith("leg RMS after"))
    assert float(after.split()[3]) == pytest.approx(result["leg_rms_after"], rel=1e-5)
    # the YAML: the geometry schema plus a calibration mapping
    raw = yaml.safe_load(out_yaml.read_text())
    meta = raw["calibration"]
    assert isinstance(meta, dict)
    assert meta["method"] == result["method"] in ("ml", "gls", "length", "paper")
    assert meta["poses"] == 20
    assert meta["stderr"] == result["stderr"]
    assert list(meta["stderr"]) == list(PARAMETER_NAMES[:42])
    assert meta["leg_rms_after_mm"] == result["leg_rms_after"]
    assert meta["outliers"] == []
    calibrated = load_geometry(out_yaml)
    assert calibrated.calibration == meta
    assert calibrated.name == "paper-hmt-calibrated"
    assert_allclose(calibrated.to_vector(), list(result["parameters"].values()), rtol=1e-15, atol=0)
    assert_array_equal(calibrated.workspace, NOMINAL.workspace)
    assert_array_equal(calibrated.leg_length_limits, NOMINAL.leg_length_limits)
