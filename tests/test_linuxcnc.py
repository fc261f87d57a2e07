"""LinuxCNC genhexkins export and import, without LinuxCNC: texts, round trips, errors, CLI.

The controller itself is exercised in ``test_linuxcnc_controller.py``.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hexcal.cli import main
from hexcal.cli.linuxcnc import EXPORT_FILES
from hexcal.core.kinematics import inverse_kinematics
from hexcal.core.presets import preset
from hexcal.io import load_geometry, save_geometry
from hexcal.io.linuxcnc import (
    GENHEXKINS_DEFAULT_BASE,
    GENHEXKINS_DEFAULT_PLATFORM,
    HAL_FILE,
    INI_FILE,
    LinuxCNCFormatError,
    euler_warning,
    export_linuxcnc,
)
from hexcal.io.linuxcnc_import import import_linuxcnc, parse_ini

SAMPLE_CONFIG = Path("/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/hexapod-sim")
SETP = re.compile(r"setp genhexkins\.(base|platform)\.(\d)\.([xyz]) (\S+)")


def awkward(seed: int = 1):
    """paper-hmt-true with xyz angles, gains != 1 and floats that need all 17 digits."""
    rng = np.random.default_rng(seed)
    g = preset("paper-hmt-true")
    return g.replace(
        euler="xyz",
        base_joints=g.base_joints + rng.uniform(-1, 1, (6, 3)) / 3,
        platform_joints=g.platform_joints + rng.uniform(-1, 1, (6, 3)) / 7,
        initial_leg_lengths=g.initial_leg_lengths + rng.uniform(-1, 1, 6) * np.pi,
        leg_gains=1 + rng.uniform(-1e-3, 1e-3, 6),
        home_pose=[1 / 3, -2 / 7, 800.1, np.deg2rad(1.1), np.deg2rad(-0.7), np.deg2rad(2.3)],
    )


def assert_same_geometry(a, b) -> None:
    """Coordinates, l0, gains and limits bit-exact; angles of the home pose and workspace
    to 1e-15 rad (they pass through degrees: one rounding each way)."""
    for field in ("base_joints", "platform_joints", "initial_leg_lengths", "leg_gains", "leg_length_limits"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field
    assert np.array_equal(a.home_pose[:3], b.home_pose[:3])
    np.testing.assert_allclose(a.home_pose[3:], b.home_pose[3:], rtol=0, atol=1e-15)
    assert np.array_equal(a.workspace[:3], b.workspace[:3])
    np.testing.assert_allclose(a.workspace[3:], b.workspace[3:], rtol=0, atol=1e-15)


# -- export -----------------------------------------------------------------------------


def test_hal_file_sets_each_coordinate_once_in_leg_order_repr_exact():
    g = awkward()
    hal = export_linuxcnc(g)[HAL_FILE]
    found = [SETP.fullmatch(line) for line in hal.splitlines() if line.startswith("setp")]
    assert all(found) and len(found) == 36
    expected = [(part, n, axis) for part in ("base", "platform") for n in range(6) for axis in "xyz"]
    assert [(m[1], int(m[2]), m[3]) for m in found] == expected
    values = np.array([float(m[4]) for m in found])
    assert np.array_equal(values, np.concatenate([g.base_joints.ravel(), g.platform_joints.ravel()]))


def test_header_states_source_calibration_and_angle_convention():
    g = awkward().replace(calibration={"method": "ml", "poses": 30, "date": "2026-11-30"})
    files = export_linuxcnc(g, source="cal.yaml", source_sha256="ab" * 32)
    for text in files.values():
        head = text.split("\n\n")[0]
        assert "source geometry: cal.yaml" in head
        assert "sha256 of the geometry file: " + "ab" * 32 in head
        assert "calibration: method ml, 30 poses" in head and "date 2026-11-30" in head
        assert "Euler sequence 'xyz' in degrees" in head
    nominal = export_linuxcnc(preset("paper-hmt"), source="paper-hmt")[HAL_FILE]
    assert "calibration: none" in nominal
    assert "'XYZ'" in nominal  # the note that this geometry's angles are not G-code's


def test_joints_ini_holds_l0_gains_limits_and_home():
    g = awkward()
    ini = parse_ini(export_linuxcnc(g)[INI_FILE])
    home_lengths = inverse_kinematics(g, g.home_pose)
    for n in range(6):
        assert ini.number(f"JOINT_{n}", "HOME_OFFSET") == g.initial_leg_lengths[n]
        assert ini.number(f"JOINT_{n}", "HEXCAL_LEG_GAIN") == g.leg_gains[n]
        assert ini.number(f"JOINT_{n}", "HOME") == home_lengths[n]
        assert ini.number(f"JOINT_{n}", "MIN_LIMIT") == g.leg_length_limits[0]
    assert ini.get("TRAJ", "LINEAR_UNITS")[0] == "mm"
    assert ini.numbers("AXIS_C", "MAX_LIMIT") == [10.0]


def test_other_euler_sequences_warn_and_home_angles_become_xyz():
    g = awkward().replace(euler="XYZ")
    assert euler_warning(awkward()) is None
    assert "'XYZ'" in euler_warning(g) and "\n" not in euler_warning(g)
    files = export_linuxcnc(g)
    ini = parse_ini(files[INI_FILE])
    home = ini.numbers("TRAJ", "HOME")
    exported = Rotation.from_euler("xyz", home[3:], degrees=True)
    same = exported * Rotation.from_euler("XYZ", g.home_pose[3:]).inv()
    assert same.magnitude() < 1e-14  # rad: the same orientation, written in G-code's angles
    assert ini.get("AXIS_A", "MIN_LIMIT") is None  # an XYZ box is not an xyz box
    # the joint coordinates do not depend on the sequence
    assert files[HAL_FILE].split("\n\n", 1)[1] == export_linuxcnc(awkward())[HAL_FILE].split("\n\n", 1)[1]


# -- import -----------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_import_of_export_gives_back_the_geometry(seed):
    g = awkward(seed)
    files = export_linuxcnc(g)
    back, warnings = import_linuxcnc(files[HAL_FILE], files[INI_FILE])
    assert warnings == []
    assert back.euler == "xyz"
    assert_same_geometry(g, back)


@pytest.mark.parametrize("euler", ["XYZ", "zyx", "ZYZ"])
def test_import_keeps_the_geometrys_euler_sequence_workspace_and_name(euler):
    # issue 31: an `euler: XYZ` geometry came back as xyz without its workspace box and name.
    # The sequence, the name and the workspace's angle ranges travel as [TRAJ] HEXCAL_* keys,
    # which LinuxCNC ignores; no [AXIS_A..C] is written (those are the user's A B C limits)
    g = awkward().replace(euler=euler, name="hmt-2.cell_4")
    files = export_linuxcnc(g)
    ini = parse_ini(files[INI_FILE])
    assert ini.get("AXIS_A", "MIN_LIMIT") is None
    assert ini.get("TRAJ", "HEXCAL_EULER")[0] == euler
    back, warnings = import_linuxcnc(files[HAL_FILE], files[INI_FILE])
    assert warnings == []
    assert back.euler == euler and back.name == "hmt-2.cell_4"
    # the home pose's angles go through G-code's xyz degrees and back: a few roundings
    for field in ("base_joints", "platform_joints", "initial_leg_lengths", "leg_gains", "leg_length_limits"):
        assert np.array_equal(getattr(g, field), getattr(back, field)), field
    assert np.array_equal(g.home_pose[:3], back.home_pose[:3])
    np.testing.assert_allclose(back.home_pose[3:], g.home_pose[3:], rtol=0, atol=1e-14)
    assert np.array_equal(g.workspace[:3], back.workspace[:3])
    np.testing.assert_allclose(back.workspace[3:], g.workspace[3:], rtol=0, atol=1e-15)
    # the same machine: the same leg lengths at the same poses
    poses = g.workspace.mean(axis=1) + np.array([[0, 0, 0, 0, 0, 0], [5, -3, 2, 0.01, -0.02, 0.03]])
    lengths = inverse_kinematics(g, poses)
    np.testing.assert_allclose(inverse_kinematics(back, poses), lengths, rtol=0, atol=1e-9)


def test_a_name_reaches_the_ini_only_as_one_safe_word():
    # the INI is parsed by LinuxCNC: a name with a newline, '#', '=' or '[' must not reach it
    g = awkward().replace(name="a\n[EMC]\nMACHINE = x # y")
    files = export_linuxcnc(g)
    assert "HEXCAL_NAME = a__EMC__MACHINE___x___y" in files[INI_FILE].split("\n")
    assert not any(line.startswith(("[EMC]", "MACHINE")) for line in files[INI_FILE].split("\n"))
    back, _ = import_linuxcnc(files[HAL_FILE], files[INI_FILE])
    assert back.name == "a__EMC__MACHINE___x___y"
    # a name given on import wins; without HEXCAL_NAME, [EMC] MACHINE, then "linuxcnc"
    assert import_linuxcnc(files[HAL_FILE], files[INI_FILE], name="mine")[0].name == "mine"
    plain = files[INI_FILE].replace("HEXCAL_NAME = a__EMC__MACHINE___x___y\n", "")
    assert import_linuxcnc(files[HAL_FILE], plain)[0].name == "linuxcnc"
    assert import_linuxcnc(files[HAL_FILE], "[EMC]\nMACHINE = cell4\n" + plain)[0].name == "cell4"


def test_an_unknown_hexcal_euler_is_one_line_naming_file_and_line():
    files = export_linuxcnc(awkward().replace(euler="XYZ"))
    bad = files[INI_FILE].replace("HEXCAL_EULER = XYZ", "HEXCAL_EULER = XXY")
    with pytest.raises(LinuxCNCFormatError, match=r"INI file: line \d+: \[TRAJ\] HEXCAL_EULER: .*XXY"):
        import_linuxcnc(files[HAL_FILE], bad)


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("HEXCAL_HOME_ANGLES", "1 2", r"2 value\(s\), not 3"),
        ("HEXCAL_WORKSPACE_ANGLES", "-10 10", r"2 value\(s\), not 6"),
        ("HEXCAL_WORKSPACE_ANGLES", "10 -10 -10 10 -10 10", "each range is a minimum then a maximum"),
        ("HEXCAL_WORKSPACE_ANGLES", "-1e9 1e9 -10 10 -10 10", "within ±180 degrees"),
    ],
)
def test_an_edited_hexcal_angle_key_is_refused_not_left_out(key, value, message):
    # the red-team pass of issue 31: these were dropped (a warning, or nothing at all) and the
    # geometry written without its workspace or with HOME's angles
    files = export_linuxcnc(awkward().replace(euler="ZYX"))
    bad = re.sub(rf"^{key} = .*$", f"{key} = {value}", files[INI_FILE], flags=re.M)
    assert bad != files[INI_FILE]
    with pytest.raises(LinuxCNCFormatError, match=rf"INI file: line \d+: \[TRAJ\] {key}: (.* )?{message}"):
        import_linuxcnc(files[HAL_FILE], bad)


def test_import_without_ini_takes_l0_at_the_home_pose_and_says_so():
    g = awkward()
    back, warnings = import_linuxcnc(export_linuxcnc(g)[HAL_FILE], home_pose=[0, 0, 800, 0, 0, 0])
    assert np.array_equal(back.base_joints, g.base_joints)
    assert np.array_equal(back.initial_leg_lengths, inverse_kinematics(back, [0, 0, 800, 0, 0, 0]))
    assert np.array_equal(back.leg_gains, np.ones(6))
    assert len(warnings) == 1 and "0 0 800 0 0 0" in warnings[0]


def test_joints_without_home_offset_take_l0_at_the_given_home_pose():
    g = awkward()
    ini = "[JOINT_0]\nHOME_OFFSET = 600.5\n"
    back, warnings = import_linuxcnc(export_linuxcnc(g)[HAL_FILE], ini, home_pose=[0, 0, 800, 0, 0, 0])
    assert back.initial_leg_lengths[0] == 600.5
    assert np.array_equal(back.initial_leg_lengths[1:], inverse_kinematics(back, back.home_pose)[1:])
    (warning,) = warnings
    assert (
        "joint(s) 1, 2, 3, 4, 5" in warning and "the given home pose X Y Z A B C = 0 0 800 0 0 0" in warning
    )


def test_unset_coordinates_take_genhexkins_defaults_with_a_warning_naming_them():
    hal = (
        "loadrt genhexkins\nsetp genhexkins.base.0.x 1.5  # comment\nsetp genhexkins.platform.5.z -2\n"
        "setp genhexkins.max-error [KINS]MAX_ERROR\n"
        "net tool-offset genhexkins.tool-offset motion.tooloffset.z\n"
    )
    g, warnings = import_linuxcnc(hal)
    base, platform = GENHEXKINS_DEFAULT_BASE.copy(), GENHEXKINS_DEFAULT_PLATFORM.copy()
    base[0, 0], platform[5, 2] = 1.5, -2.0
    assert np.array_equal(g.base_joints, base) and np.array_equal(g.platform_joints, platform)
    (missing,) = [w for w in warnings if "defaults" in w]
    assert "base.0.y" in missing and "platform.5.y" in missing
    assert "base.0.x" not in missing and "platform.5.z" not in missing


def test_inch_configuration_spindle_offset_and_ini_substitution():
    hal = (
        "setp genhexkins.spindle-offset 0.5\n"
        + "".join(f"setp genhexkins.base.{n}.{a} 1.0\n" for n in range(6) for a in "xyz")
        + "".join(f"setp genhexkins.platform.{n}.{a} [KINEMATICS]P\n" for n in range(6) for a in "xyz")
    )
    ini = "[KINEMATICS]\nP = 2.0\n[TRAJ]\nLINEAR_UNITS = inch\nHOME = 0 0 20 0 0 0\n"
    g, warnings = import_linuxcnc(hal, ini)
    np.testing.assert_allclose(g.base_joints, [[25.4, 25.4, 38.1]] * 6, rtol=1e-15)
    np.testing.assert_allclose(g.platform_joints, [[50.8, 50.8, 63.5]] * 6, rtol=1e-15)
    np.testing.assert_allclose(g.home_pose, [0, 0, 508, 0, 0, 0], rtol=1e-15)
    assert any("inch" in w for w in warnings) and any("spindle-offset" in w for w in warnings)


@pytest.mark.skipif(not SAMPLE_CONFIG.is_dir(), reason="LinuxCNC's hexapod-sim sample is not installed")
def test_linuxcncs_own_hexapod_sample_imports():
    """The sample's HOME_OFFSET (29.7466 in) is its struts' length at [TRAJ] HOME to 4e-4 in."""
    g, _ = import_linuxcnc(
        (SAMPLE_CONFIG / "kinematics.hal").read_text(), (SAMPLE_CONFIG / "hexapod.ini").read_text()
    )
    assert g.euler == "xyz"
    np.testing.assert_allclose(g.base_joints, GENHEXKINS_DEFAULT_BASE * 25.4, rtol=1e-15)
    np.testing.assert_allclose(g.initial_leg_lengths, 29.7466 * 25.4, rtol=1e-15)
    np.testing.assert_allclose(inverse_kinematics(g, g.home_pose), g.initial_leg_lengths, atol=4e-4 * 25.4)
    assert g.workspace is None  # its ±1000 degree limits are not a workspace


@pytest.mark.parametrize(
    ("hal", "ini", "message"),
    [
        ("setp genhexkins.base.0.x 1,5\n", None, r"^machine\.hal: line 1: genhexkins\.base\.0\.x: '1,5'"),
        ("\nsetp genhexkins.base.0.x nan\n", None, r"^machine\.hal: line 2: .*not a number"),
        ("setp genhexkins.base.6.x 1\n", None, r"^machine\.hal: line 1: .*joints 0\.\.5"),
        ("setp genhexkins.base.0.x\n", None, r"^machine\.hal: line 1: expected 'setp"),
        ("setp genhexkins.base.0.x [K]X\n", None, r"^machine\.hal: line 1: .*give the INI file"),
        ("setp genhexkins.base.0.x [K]X\n", "[K]\nY = 1\n", r"^machine\.hal: line 1: \[K\]X is not in m\."),
        ("", "[JOINT_0\nHOME_OFFSET = 1\n", r"^m\.ini: line 1: malformed section header"),
        ("", "[JOINT_0]\nHOME_OFFSET = twelve\n", r"^m\.ini: line 2: \[JOINT_0\] HOME_OFFSET: 'twelve'"),
        ("", "HOME = 1\n", r"^m\.ini: line 1: HOME is outside any \[SECTION\]"),
        ("", "[TRAJ]\nLINEAR_UNITS = furlong\n", r"^m\.ini: line 2: .*not mm or inch"),
        ("", "[JOINT_3]\nHEXCAL_LEG_GAIN = -1\n", r"^m\.ini: line 2: HEXCAL_LEG_GAIN must be > 0"),
    ],
)
def test_malformed_files_give_one_line_naming_file_and_line(hal, ini, message):
    with pytest.raises(LinuxCNCFormatError, match=message) as info:
        import_linuxcnc(hal, ini, hal_name="machine.hal", ini_name="m.ini")
    assert "\n" not in str(info.value)


# -- command line -------------------------------------------------------------------------


def run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def test_cli_export_then_import_round_trip(tmp_path, capsys):
    g = awkward().replace(calibration={"method": "ml", "poses": 30})
    save_geometry(g, tmp_path / "cal.yaml")
    argv = ["export", "linuxcnc", "--geometry", tmp_path / "cal.yaml", "--out", tmp_path / "lc"]
    status, _, err = run(capsys, *argv)
    assert status == 0 and err == ""
    assert sorted(p.name for p in (tmp_path / "lc").iterdir()) == [INI_FILE, HAL_FILE]
    hal = (tmp_path / "lc" / HAL_FILE).read_text()
    assert "date " in hal and "(geometry file modified)" in hal  # no date in the calibration: the file's
    status, _, err = run(
        capsys, "import", "linuxcnc", "--hal", tmp_path / "lc" / HAL_FILE,
        "--ini", tmp_path / "lc" / INI_FILE, "--out", tmp_path / "back.yaml",
    )  # fmt: skip
    assert status == 0 and err == ""
    assert_same_geometry(g, load_geometry(tmp_path / "back.yaml"))


def test_cli_export_warns_once_for_another_euler_sequence(tmp_path, capsys):
    status, _, err = run(capsys, "export", "linuxcnc", "--geometry", "paper-hmt", "--out", tmp_path / "lc")
    assert status == 0
    assert len(err.splitlines()) == 1 and err.startswith("hexcal: warning: ") and "'XYZ'" in err


@pytest.mark.parametrize(
    "argv",
    [
        ["import", "linuxcnc", "--hal", "{tmp}/missing.hal", "--out", "{tmp}/g.yaml"],
        ["import", "linuxcnc", "--hal", "{tmp}/bad.hal", "--out", "{tmp}/g.yaml"],
        ["import", "linuxcnc", "--hal", "{tmp}/bad.hal", "--out", "{tmp}/bad.hal"],
        ["import", "linuxcnc", "--hal", "{tmp}/bad.hal", "--out", "{tmp}/no/g.yaml"],
        ["import", "linuxcnc", "--hal", "{tmp}/bad.hal", "--home", "1,2,3", "--out", "{tmp}/g.yaml"],
        ["export", "linuxcnc", "--geometry", "{tmp}/missing.yaml", "--out", "{tmp}/lc"],
        ["export", "linuxcnc", "--geometry", "paper-hmt", "--out", "{tmp}/bad.hal/lc"],
        ["export", "linuxcnc", "--geometry", "paper-hmt", "--out", "{tmp}/bad.hal"],
    ],
)
def test_cli_errors_are_one_line_and_write_nothing(tmp_path, capsys, argv):
    (tmp_path / "bad.hal").write_text("setp genhexkins.base.0.x one\n")
    before = sorted(os.listdir(tmp_path))
    status, _, err = run(capsys, *[a.format(tmp=tmp_path) for a in argv])
    assert status == 1 and "Traceback" not in err
    assert len(err.splitlines()) == 1 and err.startswith("hexcal: error: "), err
    assert sorted(os.listdir(tmp_path)) == before
    assert (tmp_path / "bad.hal").read_text() == "setp genhexkins.base.0.x one\n"


def test_export_never_overwrites_its_input(tmp_path, capsys):
    folder = tmp_path / "lc"
    folder.mkdir()
    save_geometry(awkward(), folder / HAL_FILE)  # a geometry file that happens to bear the name
    text = (folder / HAL_FILE).read_text()
    status, _, err = run(capsys, "export", "linuxcnc", "--geometry", folder / HAL_FILE, "--out", folder)
    assert status == 1 and "this output is also an input" in err
    assert (folder / HAL_FILE).read_text() == text and sorted(os.listdir(folder)) == [HAL_FILE]


def test_export_files_are_declared_with_the_names_written():
    assert EXPORT_FILES == (HAL_FILE, INI_FILE)


def test_export_writes_both_files_or_neither_when_a_rename_fails(tmp_path, monkeypatch, capsys):
    """The export commits through the command's output set: a failing second rename puts the
    first file back (the set's roll-back, shared with every command)."""
    save_geometry(awkward(), tmp_path / "g.yaml")  # xyz angles: no warning
    folder = tmp_path / "lc"
    folder.mkdir()
    (folder / HAL_FILE).write_text("old hal")
    (folder / INI_FILE).write_text("old ini")
    real_replace, calls = os.replace, []

    def failing_replace(src, dst):
        calls.append(dst)
        if len(calls) == 2:
            raise OSError(28, "No space left on device")
        return real_replace(src, dst)

    monkeypatch.setattr(os, "replace", failing_replace)
    status, _, err = run(capsys, "export", "linuxcnc", "--geometry", tmp_path / "g.yaml", "--out", folder)
    assert status == 1 and len(err.splitlines()) == 1 and "No space left" in err
    assert sorted(os.listdir(folder)) == [INI_FILE, HAL_FILE]
    assert (folder / HAL_FILE).read_text() == "old hal" and (folder / INI_FILE).read_text() == "old ini"
