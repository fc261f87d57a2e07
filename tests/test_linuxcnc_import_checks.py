"""``import linuxcnc`` checks what it imports by the rules of what reads it, before writing
(issue 31): compensation tables that describe no leg, a ``HEXCAL_STROKE`` that does not cover
them, tables whose fitted model ``ik``/``fk``/``export`` would refuse, joint limits without a
range. Each is refused in one line, and nothing is written."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from hexcal.core import preset
from hexcal.core.stroke_legs import StrokeLegs
from hexcal.io import load_geometry, save_geometry
from instrument_campaigns import run

TERMS = np.random.default_rng(3).uniform(-0.2, 0.2, (6, 3))


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> Path:
    """hexcal's export of a stroke geometry: six tables, HEXCAL_STROKE = 20 495."""
    folder = tmp_path_factory.mktemp("export")
    machine = preset("paper-hmt").replace(euler="xyz", name="stroke")
    save_geometry(machine.replace(leg_model=StrokeLegs(4, [20.0] * 6, [495.0] * 6), leg_terms=TERMS),
                  folder / "g.yaml")  # fmt: skip
    assert run("export", "linuxcnc", "--geometry", folder / "g.yaml", "--out", folder / "x").code == 0
    return folder / "x"


def _import(folder: Path, out: Path):
    return run("import", "linuxcnc", "--hal", folder / "hexcal-kins.hal",
               "--ini", folder / "hexcal-joints.ini", "--out", out)  # fmt: skip


def _copy(exported: Path, tmp_path: Path) -> Path:
    folder = tmp_path / "cfg"
    folder.mkdir()
    for f in exported.iterdir():
        (folder / f.name).write_text(f.read_text())
    return folder


def _rows(path: Path) -> list[list[float]]:
    return [[float(v) for v in line.split()] for line in path.read_text().splitlines()]


def _write(path: Path, rows) -> None:
    path.write_text("".join(f"{float(a)!r} {float(b)!r} {float(c)!r}\n" for a, b, c in rows))


def test_hexcal_own_tables_still_import(exported: Path, tmp_path: Path) -> None:
    done = _import(exported, tmp_path / "back.yaml")
    assert done.code == 0, done.err
    assert load_geometry(tmp_path / "back.yaml").leg_model.name == "stroke"


def _point_of_a_million(folder: Path) -> None:
    """The issue's ``700 1e6 1e6``: LinuxCNC would add 1e6 mm there."""
    rows = _rows(folder / "hexcal-comp-0.tbl")
    _write(folder / "hexcal-comp-0.tbl", sorted([*rows, [700.0, 1e6, 1e6]]))


def _motor_back(folder: Path) -> None:
    """A trim that falls by 3 mm over 1 mm of joint travel: the motor turns back."""
    rows = _rows(folder / "hexcal-comp-1.tbl")
    k = len(rows) // 2
    rows[k][1:] = [rows[k - 1][1] - (rows[k][0] - rows[k - 1][0]) - 3.0] * 2
    _write(folder / "hexcal-comp-1.tbl", rows)


def _stroke_of_nothing(folder: Path) -> None:
    ini = folder / "hexcal-joints.ini"
    ini.write_text(ini.read_text().replace("HEXCAL_STROKE = 20.0 495.0", "HEXCAL_STROKE = 0 1e-9"))


def _type_0_mix_up(folder: Path) -> None:
    """hexcal's trims (type 1) declared as positions reached (type 0)."""
    ini = folder / "hexcal-joints.ini"
    ini.write_text(ini.read_text().replace("COMP_FILE_TYPE = 1", "COMP_FILE_TYPE = 0"))


def _sawtooth(folder: Path) -> None:
    """Monotonic motor positions, trims within the travel, but a 3 mm sawtooth that no stroke
    model follows: the fitted model misses LinuxCNC's trims by more than a millimetre."""
    ini = folder / "hexcal-joints.ini"
    kept = [line for line in ini.read_text().splitlines() if "HEXCAL_STROKE" not in line]
    ini.write_text("\n".join(kept) + "\n")
    for n in range(6):
        rows = _rows(folder / f"hexcal-comp-{n}.tbl")
        nominal = np.linspace(rows[0][0], rows[-1][0], 160)
        trim = np.where(np.arange(160) % 2 == 1, 2.9, 0.0)
        _write(folder / f"hexcal-comp-{n}.tbl", zip(nominal, trim, trim, strict=True))


def _limits_crossed(folder: Path) -> None:
    ini = folder / "hexcal-joints.ini"
    ini.write_text(ini.read_text().replace("MIN_LIMIT = 604.8652", "MIN_LIMIT = 1200", 1))


@pytest.mark.parametrize(
    ("change", "message"),
    [
        # the entry's number and the trim depend on the table's layout (its points over the stroke)
        (_point_of_a_million, r"hexcal-comp-0\.tbl: entry \d+ \(joint position 700\): a trim of 1e\+06 mm"),
        (_motor_back, "the motor would go back from"),
        (_stroke_of_nothing, re.escape("[JOINT_0] HEXCAL_STROKE = 0 1e-09 does not cover the readings of")),
        (_type_0_mix_up, r"a trim of [\d.]+ mm, more than the leg's whole travel"),
        (_sawtooth, "the tables do not describe a leg of this model"),
        (
            _limits_crossed,
            re.escape("[JOINT_0] MIN_LIMIT 1200 exceeds its MAX_LIMIT 1100: the joint has no range"),
        ),
    ],
)
def test_what_describes_no_leg_is_refused_in_one_line(exported: Path, tmp_path: Path, change, message):
    """Each was imported (exit 0; 'follows the tables within 0.00285 mm', or the limits
    dropped), and some written geometries were then refused by ik, fk and export."""
    folder = _copy(exported, tmp_path)
    change(folder)
    done = _import(folder, tmp_path / "g.yaml")
    assert done.code == 1 and re.search(message, done.err), done.err
    assert done.err.count("\n") == 1 and not (tmp_path / "g.yaml").exists()
