"""Issue 22, geometry and configuration files: what hexcal reads and what it writes follow one
set of rules. A YAML key given twice, collinear joints, workspace angles beyond ±180° are
refused in one line; ``import linuxcnc`` refuses a machine whose geometry hexcal would then
refuse to load, and an INI key or section given twice."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from hexcal.cli import main
from hexcal.core.presets import preset
from hexcal.errors import GeometryError
from hexcal.io import load_geometry, save_geometry
from hexcal.io.linuxcnc import HAL_FILE, INI_FILE, export_linuxcnc


def _run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hexcal: error: ") and "Traceback" not in err, err
    return lines[0]


def _refused(capsys, folder: Path, *argv) -> str:
    before = sorted(os.listdir(folder))
    status, out, err = _run(capsys, *argv)
    assert status == 1 and out == "", err
    assert sorted(os.listdir(folder)) == before
    return _one_line(err)


def _geometry_text() -> str:
    return yaml.safe_dump(preset("paper-hmt").to_dict(), sort_keys=False, default_flow_style=None)


# -- YAML: a key given twice ----------------------------------------------------------------------
@pytest.mark.parametrize(
    ("edit", "key"),
    [
        (lambda t: t + "initial_leg_lengths: [700, 700, 700, 700, 700, 700]\n", "initial_leg_lengths"),
        (lambda t: t.replace("units: mm\n", "units: mm\nname: twice\n"), "name"),
        (lambda t: t.replace("workspace:\n  x: ", "workspace:\n  x: [-1, 1]\n  x: "), "x"),
        (lambda t: t + "calibration: {method: ml, poses: 3, method: paper}\n", "method"),
    ],
)
def test_a_yaml_key_given_twice_is_refused_naming_the_key_and_line(capsys, tmp_path, edit, key):
    text = edit(_geometry_text())
    (tmp_path / "g.yaml").write_text(text)
    argv = ["candidates", "--geometry", tmp_path / "g.yaml", "--candidates", "corners"]
    message = _refused(capsys, tmp_path, *argv, "--out", tmp_path / "c.csv")
    pattern = r"g\.yaml: line (\d+): not valid YAML \(the key '(\w+)' is given twice in one mapping, on "
    found = re.search(pattern + r"(lines (\d+) and (\d+)|line (\d+))\)$", message)
    assert found and found[2] == key, message
    lines = text.split("\n")
    named = [int(n) for n in found.groups()[3:] if n]
    assert int(found[1]) == named[-1]
    assert all(re.search(rf"(^|[{{ ,]){key}:", lines[n - 1]) for n in named)
    if len(named) == 1:  # both on one line (a flow mapping)
        assert len(re.findall(rf"(^|[{{ ,]){key}:", lines[named[0] - 1])) == 2


def test_a_target_given_twice_in_a_setup_is_refused(capsys, tmp_path):
    targets = "targets:\n  t1: [0, 0, 60]\n  t2: [150, 20, 55]\n  t1: [-40, 160, 70]\n"
    (tmp_path / "s.yaml").write_text("units: mm\ninstrument_frame: auto\n" + targets)
    argv = ["select", "--geometry", "paper-hmt", "--setup", tmp_path / "s.yaml", "--candidates", "corners"]
    message = _refused(capsys, tmp_path, *argv, "--n", "40", "--out", tmp_path / "p.csv")
    assert (
        "s.yaml: line 6: " in message
        and "the key 't1' is given twice" in message
        and "lines 4 and 6" in message
    )


def test_yaml_merge_keys_may_still_be_overridden(tmp_path):
    text = _geometry_text().replace("units: mm\n", "units: mm\n")
    text = text.replace("workspace:\n", "workspace: &box\n")
    text += "calibration:\n  box: {<<: *box, x: [-1, 1]}\n"
    (tmp_path / "g.yaml").write_text(text)
    assert load_geometry(tmp_path / "g.yaml").calibration["box"]["x"] == [-1, 1]


# -- geometry rules ---------------------------------------------------------------------------------
def _with(tmp_path: Path, **changes) -> Path:
    data = preset("paper-hmt").to_dict() | changes
    (tmp_path / "g.yaml").write_text(yaml.safe_dump(data, sort_keys=False))
    return tmp_path / "g.yaml"


@pytest.mark.parametrize("frame", ["platform_joints", "base_joints"])
def test_collinear_joints_are_refused(capsys, tmp_path, frame):
    along = np.linspace(-100, 100, 6)
    joints = np.column_stack([along, 0.5 * along + 3, np.full(6, 7.0)]).tolist()
    path = _with(tmp_path, **{frame: joints})
    message = _refused(capsys, tmp_path, "candidates", "--geometry", path, "--out", tmp_path / "c.csv")
    assert f"g.yaml: {frame}: the six joints lie on one line" in message


def test_coplanar_joints_are_still_accepted(tmp_path):
    load_geometry(_with(tmp_path))  # the seed paper's machine: every frame planar


@pytest.mark.parametrize("box", [{"a_deg": [-720, 720]}, {"c_deg": [0, 190]}, {"b": [-4.0, 0.0]}])
def test_workspace_angles_beyond_180_degrees_are_refused(capsys, tmp_path, box):
    workspace = preset("paper-hmt").to_dict()["workspace"]
    workspace = {k: v for k, v in workspace.items() if k[0] != next(iter(box))[0]} | box
    path = _with(tmp_path, workspace=workspace)
    message = _refused(capsys, tmp_path, "candidates", "--geometry", path, "--out", tmp_path / "c.csv")
    assert "g.yaml: workspace: " in message and "beyond ±180 degrees" in message


def test_workspace_angles_of_180_degrees_are_accepted(tmp_path):
    workspace = preset("paper-hmt").to_dict()["workspace"] | {"c_deg": [-180, 180]}
    assert load_geometry(_with(tmp_path, workspace=workspace)).workspace[5, 1] == np.pi


def test_save_geometry_never_writes_a_file_load_would_refuse(tmp_path):
    g = preset("paper-hmt")
    base = g.base_joints.copy()
    base[2] = base[1]
    with pytest.raises(GeometryError, match=r"g\.yaml: not written: .*joints u2 and u3 coincide"):
        save_geometry(g.replace(base_joints=base), tmp_path / "g.yaml")
    assert not os.listdir(tmp_path)


# -- import linuxcnc ------------------------------------------------------------------------------
@pytest.fixture
def config(tmp_path) -> Path:
    """An exported LinuxCNC configuration of a plausible machine (xyz angles)."""
    files = export_linuxcnc(preset("paper-hmt-true").replace(euler="xyz"))
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    return tmp_path


def _import(capsys, folder: Path, hal: str = HAL_FILE, ini: str | None = INI_FILE) -> str:
    argv = ["import", "linuxcnc", "--hal", folder / hal, "--out", folder / "g.yaml"]
    return _refused(capsys, folder, *argv, *(["--ini", folder / ini] if ini else []))


def test_import_refuses_the_genhexkins_defaults_whose_base_joints_coincide(capsys, config):
    (config / "empty.hal").write_text("loadrt genhexkins\n")
    message = _import(capsys, config, "empty.hal", None)
    assert "empty.hal: hexcal cannot use the machine they describe: " in message
    assert "base_joints: joints u1 and u6 coincide" in message


def test_import_refuses_a_home_pose_outside_the_workspace(capsys, config):
    ini = (config / INI_FILE).read_text()
    ini = re.sub(r"(\[AXIS_Z\]\n# workspace box, mm\n)MIN_LIMIT = \S+", r"\1MIN_LIMIT = 850.0", ini)
    (config / INI_FILE).write_text(ini)
    message = _import(capsys, config)
    assert f"{HAL_FILE} and " in message and "home_pose: z = 800 mm is outside the workspace [850" in message


def test_import_of_a_plausible_configuration_still_works(capsys, config):
    status, _, err = _run(
        capsys, "import", "linuxcnc", "--hal", config / HAL_FILE, "--ini", config / INI_FILE,
        "--out", config / "g.yaml",
    )  # fmt: skip
    assert status == 0, err
    assert np.array_equal(load_geometry(config / "g.yaml").base_joints, preset("paper-hmt-true").base_joints)


@pytest.mark.parametrize(
    ("edit", "words"),
    [
        (
            lambda t: t.replace("[JOINT_3]\n", "[JOINT_3]\nHOME_OFFSET = 1.5\n"),
            "[JOINT_3] HOME_OFFSET is set again",
        ),
        (lambda t: t + "\n[TRAJ]\nLINEAR_UNITS = inch\n", "section [TRAJ] appears again"),
        (lambda t: t + "\n[JOINT_0]\nHEXCAL_LEG_GAIN = 2\n", "section [JOINT_0] appears again"),
    ],
)
def test_import_refuses_an_ini_key_or_section_given_twice(capsys, config, edit, words):
    text = edit((config / INI_FILE).read_text())
    (config / INI_FILE).write_text(text)
    message = _import(capsys, config)
    again = re.search(r"line (\d+): ", message)
    assert again and words in message and f"{INI_FILE}: line " in message
    named = text.split("\n")[int(again[1]) - 1].strip()
    assert named.startswith("HOME_OFFSET = ") or named in ("[TRAJ]", "[JOINT_0]")


def test_import_accepts_keys_it_does_not_read_given_twice(capsys, config):
    text = (config / INI_FILE).read_text() + "\n[HAL]\nHALFILE = core.hal\nHALFILE = hexcal-kins.hal\n"
    (config / INI_FILE).write_text(text)
    status, _, err = _run(
        capsys, "import", "linuxcnc", "--hal", config / HAL_FILE, "--ini", config / INI_FILE,
        "--out", config / "g.yaml",
    )  # fmt: skip
    assert status == 0, err


def test_numbers_with_an_exponent_are_numbers_in_every_yaml_file_read(tmp_path):
    # PyYAML (YAML 1.1) reads 1e-3 and 1.5e3 as text: a setup's noise {position: 1e-3} was
    # refused as "must be a number > 0, got '1e-3'"; YAML 1.2 and hexcal read numbers
    from hexcal.io import load_setup
    from hexcal.io.inputs import parse_yaml

    assert parse_yaml("a: 1e-3\nb: -2E5\nc: 1.5e3\nd: .5e1\ne: x1e3\nf: .inf\n", "x.yaml") == {
        "a": 0.001,
        "b": -200000.0,
        "c": 1500.0,
        "d": 5.0,
        "e": "x1e3",
        "f": float("inf"),
    }
    text = "units: mm\ninstrument_frame: auto\ntargets: {t1: [1e0, -1, 6.1e1]}\nnoise: {position: 1.5e-2}\n"
    (tmp_path / "s.yaml").write_text(text)
    setup = load_setup(tmp_path / "s.yaml")
    assert setup.noise == {"position": 0.015}
    assert np.allclose(setup.target_array, [[1.0, -1.0, 61.0]])
