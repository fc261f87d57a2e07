"""A new controller export is one module and one registration, and ``hexcal export`` takes it.

``toy_export`` writes a toy controller's file (one line of joint coordinates, ``l0`` and gain per
leg) and registers it as ``toyctl`` with one record (:class:`hexcal.io.ControllerExport`). The
command line, which knows nothing of it, writes its file from a calibrated geometry (the numbers
read back to the geometry's, to the last bit), declares that file as an output before any work
(an input there is refused and nothing written), refuses a geometry the controller cannot take in
one line, and names the registered controllers for an unknown one. LinuxCNC's export goes
through the same record.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hexcal.core import preset
from hexcal.core.stroke_legs import StrokeLegs
from hexcal.io import EXPORTS, export_geometry, save_geometry
from instrument_campaigns import run
from toy_export import TOY_FILE, registered


@pytest.fixture
def toy():
    with registered():
        yield


def _read_back(text: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    rows = [line.split() for line in text.splitlines()]
    numbers = np.array([[float(w) for k, w in enumerate(r) if k in (3, 4, 5, 7, 8, 9, 11, 13)] for r in rows])
    return numbers[:, :3], numbers[:, 3:6], numbers[:, 6], numbers[:, 7]


def test_the_command_line_writes_a_registered_export(toy, tmp_path: Path):
    geometry = preset("paper-hmt-true")
    save_geometry(geometry, tmp_path / "cal.yaml")
    done = run("export", "toyctl", "--geometry", tmp_path / "cal.yaml", "--out", tmp_path / "ctl")
    assert done.code == 0, done.err
    assert f"load {TOY_FILE} in the toy controller" in done.out
    base, platform, l0, gain = _read_back((tmp_path / "ctl" / TOY_FILE).read_text())
    np.testing.assert_array_equal(base, geometry.base_joints)  # repr round-trips every double
    np.testing.assert_array_equal(platform, geometry.platform_joints)
    np.testing.assert_array_equal(l0, geometry.initial_leg_lengths)
    np.testing.assert_array_equal(gain, geometry.leg_gains)
    assert export_geometry("toyctl", geometry).files[TOY_FILE] == (tmp_path / "ctl" / TOY_FILE).read_text()


def test_its_file_is_a_declared_output_and_its_refusal_one_line(toy, tmp_path: Path):
    # the output file is the geometry itself: refused before any work, the input untouched
    out = tmp_path / "ctl"
    out.mkdir()
    save_geometry(preset("paper-hmt"), out / TOY_FILE)
    before = (out / TOY_FILE).read_bytes()
    done = run("export", "toyctl", "--geometry", out / TOY_FILE, "--out", out)
    assert done.code == 1 and (out / TOY_FILE).read_bytes() == before
    assert done.err.count("\n") == 1 and TOY_FILE in done.err
    # a stroke leg model: the toy controller's struts are linear
    legs = preset("paper-hmt").replace(leg_model=StrokeLegs(3, -100, 100), leg_terms=np.zeros((6, 2)))
    save_geometry(legs, tmp_path / "stroke.yaml")
    done = run("export", "toyctl", "--geometry", tmp_path / "stroke.yaml", "--out", tmp_path / "s")
    assert done.code == 1 and done.err.endswith("struts are linear; the stroke legs are not\n")
    assert not (tmp_path / "s" / TOY_FILE).exists()


def test_an_unknown_controller_names_the_registered_ones(toy, tmp_path: Path):
    done = run("export", "nosuch", "--geometry", "paper-hmt", "--out", tmp_path / "x")
    assert done.code == 1
    assert done.err == "hexcal: error: export 'nosuch': unknown controller; choose from linuxcnc, toyctl\n"


def test_linuxcnc_is_a_record_like_any_other(tmp_path: Path):
    assert "toyctl" not in EXPORTS and EXPORTS["linuxcnc"].files[:2] == (
        "hexcal-kins.hal",
        "hexcal-joints.ini",
    )
    done = run("export", "linuxcnc", "--geometry", "paper-hmt", "--out", tmp_path / "l")
    assert done.code == 0, done.err
    assert sorted(p.name for p in (tmp_path / "l").iterdir()) == ["hexcal-joints.ini", "hexcal-kins.hal"]
