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


# -- files named inside an option's value, files inside an --out folder ------------------------
@pytest.fixture
def poses(tmp_path, monkeypatch, capsys) -> Path:
    """A pose file in the current folder (``p.csv``), made by hexcal."""
    monkeypatch.chdir(tmp_path)
    argv = ["candidates", "--geometry", "paper-hmt", "--candidates", "random:30", "--out", "p.csv"]
    assert main(argv) == 0
    capsys.readouterr()
    return tmp_path / "p.csv"


@pytest.mark.parametrize(
    "argv",
    [
        ["candidates", "--geometry", "paper-hmt", "--candidates", "corners+p.csv", "--out", "p.csv"],
        ["candidates", "--geometry", "paper-hmt", "--candidates", " p.csv ", "--out", "./p.csv"],
        ["select", "--geometry", "paper-hmt", "--candidates", "p.csv", "--out", "p.csv"],
        [
            "select",
            "--geometry",
            "paper-hmt",
            "--candidates",
            "grid:2+p.csv",
            "--out",
            "s.csv",
            "--json",
            "p.csv",
        ],
    ],
)
def test_an_output_naming_a_file_of_the_candidate_spec_is_refused(capsys, poses, argv):
    before = poses.read_bytes()
    status, out, err = _run(capsys, *argv)
    lines = err.strip().splitlines()
    assert status == 1 and out == "" and len(lines) == 1, err
    assert "this output is also an input" in lines[0] and "p.csv" in lines[0]
    assert poses.read_bytes() == before and sorted(os.listdir(poses.parent)) == ["p.csv"]


def _boom(*_args, **_kw):
    raise AssertionError("the command started its work before refusing an output")


SIMULATE = ["simulate", "--trials", "2", "--methods", "length", "--strategies", "corners", "--quiet"]


@pytest.mark.parametrize(
    ("argv", "name"),
    [
        ([*SIMULATE, "--out", "res"], "study.json"),
        ([*SIMULATE, "--out", "res"], "study.png"),
        (["paper", "--trials", "2", "--quiet", "--out", "res"], "table1.json"),
        (["paper", "--trials", "2", "--quiet", "--out", "res"], "fig11_validation_errors.png"),
        (["study", "selection", "--trials", "2", "--poses", "8", "--quiet", "--out", "res"], "selection.csv"),
        (["errormap", "--geometry", "paper-hmt", "--draws", "2", "--out", "res"], "claims.json"),
        (["errormap", "--geometry", "paper-hmt", "--draws", "2", "--out", "res"], "errormap_b-c.csv"),
        (["export", "linuxcnc", "--geometry", "paper-hmt", "--out", "res"], INI_FILE),
    ],
)
@pytest.mark.parametrize("kind", ["fifo", "read-only"])
def test_a_bad_file_inside_the_out_folder_is_refused_before_any_work(
    capsys, tmp_path, monkeypatch, argv, name, kind
):
    import hexcal.io

    monkeypatch.chdir(tmp_path)
    (tmp_path / "res").mkdir()
    if kind == "fifo":
        os.mkfifo(tmp_path / "res" / name)
    else:
        (tmp_path / "res" / name).write_text("kept\n")
        os.chmod(tmp_path / "res" / name, 0o444)
    monkeypatch.setattr(hexcal.io, "load_geometry", _boom)  # every command loads a geometry first
    status, out, err = _run(capsys, *argv)
    lines = err.strip().splitlines()
    assert status == 1 and out == "" and len(lines) == 1 and lines[0].startswith("hexcal: error: "), err
    assert name in lines[0] and ("FIFO" in lines[0] if kind == "fifo" else "read-only" in lines[0])
    assert os.listdir(tmp_path / "res") == [name]
    if kind == "read-only":
        assert (tmp_path / "res" / name).read_text() == "kept\n"


def test_two_outputs_of_one_command_on_one_file_are_refused_up_front(capsys, tmp_path, monkeypatch):
    import hexcal.io

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(hexcal.io, "load_geometry", _boom)
    status, _, err = _run(capsys, "paper", "--trials", "2", "--out", "res", "--html", "res/table1.json")
    assert status == 1 and "two outputs name the same file" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "res").exists()


def test_the_declarations_are_not_options_a_report_shows(capsys, tmp_path, monkeypatch):
    """input_lists and folder_files are consumed by the output set: the HTML page's record of
    the command's options does not show them (a function's repr was there)."""
    monkeypatch.chdir(tmp_path)
    argv = ["select", "--geometry", "paper-hmt", "--candidates", "corners", "--n", "15", "--no-exchange"]
    status, _, err = _run(capsys, *argv, "--out", "s.csv", "--html", "s.html")
    assert status == 0, err
    page = (tmp_path / "s.html").read_text(encoding="utf-8")
    assert "--strategy optimal" in page  # the options are there, as typed flags
    assert "input_lists" not in page and "folder_files" not in page
    assert "&lt;function" not in page and "<function" not in page
