"""Issue 22, files that LinuxCNC executes: ``export linuxcnc`` lets nothing from its input
reach ``hexcal-kins.hal`` or ``hexcal-joints.ini`` except numbers and one-line comments, and
writes them through the command's output set like every other command.

Hostile text sits in every input field that reaches the files (the geometry's ``name``, every
``calibration:`` field, the geometry file's path): the files' non-comment lines must be those
of a harmless export, every comment one printable line, the re-import must give the original
numbers; where LinuxCNC is installed, ``halcmd`` and ``inivar`` (LinuxCNC's own readers) must
see exactly the lines hexcal meant.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from hexcal.cli import main
from hexcal.core.presets import preset
from hexcal.io import load_geometry, save_geometry
from hexcal.io.linuxcnc import HAL_FILE, INI_FILE, MAX_LINE_BYTES
from hexcal.io.linuxcnc_import import parse_ini

#: Texts that would add a line to a HAL or INI file if written as they are ({marker}: a file
#: that a HAL line run by halcmd would create).
HOSTILE = {
    "newline_loadusr": "m1\nloadusr -w touch {marker}\n",
    "ini_key": "ml\nl0_1 = 1.5",
    "ini_sections": "x\n[JOINT_0]\nHOME_OFFSET = 1.5\n[HAL]\nHALFILE = evil.hal",
    "continuation": "calibrated \\",
    "other_line_breaks": "a\rb\x0bc\x0cd\x1ce\x85f\u2028g\u2029loadusr -w touch {marker}",
    "long_line": "#" * 254 + "l0_1 = 1.5" + "y" * 300 + "loadusr -w touch {marker}",
    "format_and_nul": "\u202eevil\x00\x1b[2J\t",
}


def _geometry(text: str):
    """paper-hmt-true in G-code's angles, with ``text`` in the name and every calibration field."""
    g = preset("paper-hmt-true").replace(euler="xyz")
    rng = np.random.default_rng(3)
    g = g.replace(initial_leg_lengths=g.initial_leg_lengths + rng.uniform(-1, 1, 6) / 3)
    return g.replace(
        name=text,
        calibration={"method": text, "poses": text, "data": text, "date": text, "outliers": [text]},
    )


def _run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def _export(capsys, geometry_file: Path, out: Path) -> dict[str, str]:
    status, _, err = _run(capsys, "export", "linuxcnc", "--geometry", geometry_file, "--out", out)
    assert status == 0, err
    return {name: (out / name).read_text(encoding="utf-8") for name in (HAL_FILE, INI_FILE)}


def _content(text: str) -> list[str]:
    """The lines that are not comments or blank (what LinuxCNC acts on), but the geometry's name
    for ``hexcal import linuxcnc``, which must be one safe word (letters, digits, ``_ . + -``)."""
    lines = [line for line in text.split("\n") if line.strip() and not line.lstrip().startswith(("#", ";"))]
    for line in lines:
        if line.startswith("HEXCAL_NAME"):
            assert re.fullmatch(r"HEXCAL_NAME = [A-Za-z0-9_.+-]{1,80}", line), repr(line)
    return [line for line in lines if not line.startswith("HEXCAL_NAME")]


def _assert_safe_comments(text: str) -> None:
    for line in text.split("\n"):
        if line.startswith("#"):
            assert line.isprintable(), repr(line)
            assert not line.endswith("\\"), repr(line)
            assert len(line.encode("utf-8")) <= MAX_LINE_BYTES, len(line)


@pytest.fixture(scope="module")
def harmless(tmp_path_factory) -> dict[str, str]:
    """The export of the same geometry with a plain name: the lines a hostile one must match."""
    folder = tmp_path_factory.mktemp("harmless")
    save_geometry(_geometry("plain"), folder / "cal.yaml")
    argv = ["export", "linuxcnc", "--geometry", str(folder / "cal.yaml"), "--out", str(folder / "lc")]
    assert main(argv) == 0
    return {name: (folder / "lc" / name).read_text() for name in (HAL_FILE, INI_FILE)}


@pytest.mark.parametrize("kind", sorted(HOSTILE))
def test_hostile_text_reaches_the_files_only_as_one_line_comments(tmp_path, capsys, harmless, kind):
    marker = tmp_path / "pwned"
    text = HOSTILE[kind].format(marker=marker)
    geometry = _geometry(text)
    save_geometry(geometry, tmp_path / "cal.yaml")
    files = _export(capsys, tmp_path / "cal.yaml", tmp_path / "lc")
    for name, written in files.items():
        assert _content(written) == _content(harmless[name]), name
        _assert_safe_comments(written)
    ini = parse_ini(files[INI_FILE])
    assert set(ini.values) == set(parse_ini(harmless[INI_FILE]).values)
    # the re-import gives the original numbers
    status, _, err = _run(
        capsys, "import", "linuxcnc", "--hal", tmp_path / "lc" / HAL_FILE,
        "--ini", tmp_path / "lc" / INI_FILE, "--out", tmp_path / "back.yaml",
    )  # fmt: skip
    assert status == 0, err
    back = load_geometry(tmp_path / "back.yaml")
    for field in ("base_joints", "platform_joints", "initial_leg_lengths", "leg_gains", "leg_length_limits"):
        assert np.array_equal(getattr(back, field), getattr(geometry, field)), field
    assert not marker.exists()


@pytest.mark.parametrize(
    "name", ["cal\nloadusr -w touch pwned\n.yaml", "cal.yaml\\", "c\u2028[HAL]\nHALFILE = x"]
)
def test_a_hostile_source_path_is_one_comment(tmp_path, capsys, harmless, name):
    path = tmp_path / name
    save_geometry(_geometry("plain").replace(name=""), path)  # the path ends the line
    files = _export(capsys, path, tmp_path / "lc")
    for written_name, written in files.items():
        assert _content(written) == _content(harmless[written_name])
        _assert_safe_comments(written)
        (source,) = [line for line in written.split("\n") if line.startswith("# source geometry: ")]
        assert "cal" in source or "c\\u2028" in source


def _private_ipc() -> list[str] | None:
    """``unshare --ipc``: halcmd attaches to the machine's HAL shared memory, and its setp
    lines would set the pins of a LinuxCNC running there (another test run's); in a private
    IPC namespace it meets none. None where that cannot be had."""
    if not shutil.which("unshare"):
        return None
    done = subprocess.run(["unshare", "--ipc", "true"], capture_output=True, timeout=60)
    return ["unshare", "--ipc"] if done.returncode == 0 else None


@pytest.mark.skipif(
    not (shutil.which("halcmd") and shutil.which("inivar")), reason="LinuxCNC is not installed"
)
@pytest.mark.parametrize("kind", ["newline_loadusr", "long_line", "other_line_breaks"])
def test_linuxcncs_own_readers_see_only_hexcals_lines(tmp_path, capsys, kind):
    """halcmd runs every command of the HAL file (-k: on after failures; genhexkins is not
    loaded in its private IPC namespace, so each setp fails and says so): exactly the 36 setp
    lines, and nothing else runs.
    inivar (LinuxCNC's INI reader) finds the numbers written and no injected key."""
    isolated = _private_ipc()
    if isolated is None:
        pytest.skip("no private IPC namespace (unshare --ipc) for halcmd")
    marker = tmp_path / "pwned"
    geometry = _geometry(HOSTILE[kind].format(marker=marker))
    save_geometry(geometry, tmp_path / "cal.yaml")
    _export(capsys, tmp_path / "cal.yaml", tmp_path / "lc")
    done = subprocess.run(
        [*isolated, "halcmd", "-k", "-f", str(tmp_path / "lc" / HAL_FILE)],
        cwd=tmp_path, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    messages = [line for line in (done.stdout + done.stderr).splitlines() if line.strip()]
    assert len(messages) == 36 and all("genhexkins." in m and "not found" in m for m in messages), messages
    assert not marker.exists()

    def inivar(section: str, key: str) -> str | None:
        found = subprocess.run(
            ["inivar", "-var", key, "-sec", section, "-ini", str(tmp_path / "lc" / INI_FILE)],
            capture_output=True, text=True, timeout=60,
        )  # fmt: skip
        return found.stdout.strip() if found.returncode == 0 else None

    for n in range(6):
        assert float(inivar(f"JOINT_{n}", "HOME_OFFSET")) == geometry.initial_leg_lengths[n]
    assert inivar("JOINT_0", "l0_1") is None and inivar("HAL", "HALFILE") is None
    assert inivar("TRAJ", "l0_1") is None
