"""Issue 22, one output mechanism: every file a command writes, ``export linuxcnc`` included,
goes through the command's output set, and every file it names (inside an option's value, or
a fixed name inside its ``--out`` folder) is declared, so that it is checked before any work.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np
import pytest

from hexcal.cli import main
from hexcal.core.presets import preset
from hexcal.io import save_geometry
from hexcal.io.linuxcnc import HAL_FILE, INI_FILE


def _run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def _geometry():
    g = preset("paper-hmt-true").replace(euler="xyz", name="plain")  # xyz angles: no warning
    return g.replace(initial_leg_lengths=g.initial_leg_lengths + np.random.default_rng(3).uniform(-1, 1, 6))


def _export(capsys, geometry_file: Path, out: Path) -> None:
    status, _, err = _run(capsys, "export", "linuxcnc", "--geometry", geometry_file, "--out", out)
    assert status == 0, err


# -- export linuxcnc through the output set ---------------------------------------------------------
@pytest.fixture
def exported(tmp_path, capsys) -> Path:
    """A folder with an earlier export, and the geometry file (xyz angles: no warning)."""
    save_geometry(_geometry(), tmp_path / "cal.yaml")
    _export(capsys, tmp_path / "cal.yaml", tmp_path / "lc")
    return tmp_path


def _state(folder: Path) -> dict[str, tuple[bytes, int, bool]]:
    return {
        p.name: (p.read_bytes() if p.is_file() else b"", os.lstat(p).st_mode, p.is_symlink())
        for p in sorted(folder.iterdir())
    }


def _refused(capsys, folder: Path, geometry: Path) -> str:
    before = _state(folder)
    status, out, err = _run(capsys, "export", "linuxcnc", "--geometry", geometry, "--out", folder / "lc")
    lines = err.strip().splitlines()
    assert status == 1 and out == "" and len(lines) == 1 and lines[0].startswith("hexcal: error: "), err
    assert _state(folder) == before
    assert not [p for p in (folder / "lc").iterdir() if ".tmp" in p.name]
    return lines[0]


def test_export_writes_through_a_symbolic_link(exported, capsys):
    lc = exported / "lc"
    (exported / "kept.hal").write_text("old\n")
    (lc / HAL_FILE).unlink()
    (lc / HAL_FILE).symlink_to(exported / "kept.hal")
    _export(capsys, exported / "cal.yaml", lc)
    assert (lc / HAL_FILE).is_symlink()
    assert (exported / "kept.hal").read_text().startswith("# hexcal-kins.hal")


def test_export_refuses_a_read_only_target(exported, capsys):
    os.chmod(exported / "lc" / INI_FILE, 0o444)
    assert "read-only" in _refused(capsys, exported, exported / "cal.yaml")


def test_export_refuses_a_hard_linked_target(exported, capsys):
    os.link(exported / "lc" / HAL_FILE, exported / "other.hal")
    assert "hard links" in _refused(capsys, exported, exported / "cal.yaml")


def test_export_refuses_a_fifo_target_before_any_work(exported, capsys):
    (exported / "lc" / INI_FILE).unlink()
    os.mkfifo(exported / "lc" / INI_FILE)
    assert "FIFO" in _refused(capsys, exported, exported / "cal.yaml")


def test_export_keeps_the_mode_of_a_replaced_file(exported, capsys):
    os.chmod(exported / "lc" / HAL_FILE, 0o640)
    (exported / "lc" / INI_FILE).write_text("old\n")
    _export(capsys, exported / "cal.yaml", exported / "lc")
    assert stat.S_IMODE(os.stat(exported / "lc" / HAL_FILE).st_mode) == 0o640
    assert (exported / "lc" / INI_FILE).read_text().startswith("# hexcal-joints.ini")


def test_export_refuses_to_write_over_its_input_through_a_link(exported, capsys):
    (exported / "lc" / HAL_FILE).unlink()
    (exported / "lc" / HAL_FILE).symlink_to(exported / "cal.yaml")
    assert "also an input" in _refused(capsys, exported, exported / "cal.yaml")
