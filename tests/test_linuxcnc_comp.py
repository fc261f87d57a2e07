"""Joint compensation tables of a stroke leg model (``hexcal.io.linuxcnc_comp``), without LinuxCNC.

- the tables are exact at their entries (trim = l0 + g dl - l(dl)) and within their stated
  interpolation error between them (checked against the model's own inverse); their ends are
  the stroke's, and beyond them the end trims held (LinuxCNC's rule) are the model's own
  continuation, exactly, the home switch (reading 0, outside the stroke) included;
- a table of another stroke (an older export widened to reading 0) is fitted on its points on
  the stroke and the disagreement of the others named;
- ``export linuxcnc`` of a stroke geometry writes six numbers-only tables and the INI keys, and
  ``import linuxcnc`` reads them back into the same leg model (terms to 1e-9 mm), also from
  ``COMP_FILE_TYPE = 0`` tables; a linear geometry writes no table;
- malformed tables (a word, two numbers, decreasing positions, backlash), a joint without a table
  and an ``--out`` that is a table are refused in one line, nothing written; any mutation of a
  table reads or is one clean error (Hypothesis).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from hexcal.cli.main import main
from hexcal.core import preset
from hexcal.core.kinematics import leg_lengths
from hexcal.core.legs import LinearLegs
from hexcal.core.stroke_legs import StrokeLegs, legendre_values
from hexcal.errors import HexcalError
from hexcal.io import load_geometry, save_geometry
from hexcal.io.linuxcnc import LinuxCNCFormatError
from hexcal.io.linuxcnc_comp import (
    COMP_FILES,
    MAX_ENTRIES,
    CompTable,
    comp_tables,
    parse_comp_table,
    stroke_from_tables,
)
from test_io_properties import SETTINGS, mutated

TERMS = np.random.default_rng(3).uniform(-0.2, 0.2, (6, 3))


def stroke_geometry(low: float = 20.0, high: float = 495.0):
    machine = preset("paper-hmt").replace(euler="xyz", name="stroke")
    return machine.replace(leg_model=StrokeLegs(4, [low] * 6, [high] * 6), leg_terms=TERMS)


def run(capsys, *argv):
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def test_tables_are_exact_at_entries_and_within_their_error_between():
    geometry = stroke_geometry()
    tables = comp_tables(geometry)
    model, block = geometry.leg_model, geometry.leg_block()
    ends = leg_lengths(geometry, np.array([[20.0] * 6, [495.0] * 6]))
    for leg, table in enumerate(tables):
        assert 9 <= len(table.nominal) <= MAX_ENTRIES and np.all(np.diff(table.nominal) > 0)
        # the stroke's ends are the table's: the home switch (reading 0) lies beyond it
        np.testing.assert_allclose(table.nominal[[0, -1]], ends[:, leg], rtol=0, atol=1e-12)
        # from reading -100 to 700: LinuxCNC holds the end trims beyond the table (as np.interp
        # does), which is the model's continuation: exact there, within the stated error on it
        dl = np.linspace(-100.0, 700.0, 4001)
        lengths = leg_lengths(geometry, np.broadcast_to(dl[:, None], (4001, 6)))[:, leg]
        full = np.broadcast_to(lengths[:, None], (4001, 6)).copy()
        back = model.readings(block, full)[:, leg]  # the model's inverse
        exact = geometry.initial_leg_lengths[leg] + geometry.leg_gains[leg] * back - lengths
        error = np.abs(np.interp(lengths, table.nominal, table.trim) - exact)
        beyond = (dl < 20.0) | (dl > 495.0)
        assert np.max(error[~beyond]) <= table.max_error + 1e-12
        assert np.max(error[beyond]) <= 1e-9
        assert table.max_error <= 1e-3


def test_export_and_import_round_trip(capsys, tmp_path):
    geometry = stroke_geometry()
    save_geometry(geometry, tmp_path / "g.yaml")
    status, out, err = run(
        capsys, "export", "linuxcnc", "--geometry", tmp_path / "g.yaml", "--out", tmp_path / "x"
    )
    assert status == 0, err
    assert "copy hexcal-comp-0.tbl" in out
    for name in COMP_FILES:
        text = (tmp_path / "x" / name).read_text()
        assert all(len(line.split()) == 3 for line in text.splitlines())  # numbers only
        [float(v) for v in text.split()]
    ini = (tmp_path / "x" / "hexcal-joints.ini").read_text()
    assert ini.count("COMP_FILE_TYPE = 1") == 6 and "COMP_FILE = hexcal-comp-5.tbl" in ini
    status, _, err = run(
        capsys,
        "import",
        "linuxcnc",
        "--hal",
        tmp_path / "x" / "hexcal-kins.hal",
        "--ini",
        tmp_path / "x" / "hexcal-joints.ini",
        "--out",
        tmp_path / "back.yaml",
    )
    assert status == 0, err
    back = load_geometry(tmp_path / "back.yaml")
    assert back.leg_model == geometry.leg_model
    np.testing.assert_allclose(back.leg_terms, geometry.leg_terms, rtol=0, atol=1e-9)
    np.testing.assert_allclose(back.initial_leg_lengths, geometry.initial_leg_lengths, rtol=0, atol=1e-6)


def test_a_table_of_another_stroke_is_fitted_on_this_one():
    """An older export widened the table to reading 0 with the polynomial extrapolated there;
    read with its HEXCAL_STROKE [20, 495], the points on the stroke give the terms exactly and
    the residual names how far the others differ from the held curve."""
    geometry = stroke_geometry()
    dl = np.linspace(0.0, 495.0, 100)
    x = (2 * dl - 20.0 - 495.0) / 475.0  # not clipped: the old extrapolation
    curve = legendre_values(x, 4)[0][:, 2:] @ TERMS.T  # (100, 6)
    lengths = geometry.initial_leg_lengths + geometry.leg_gains * dl[:, None] + curve
    tables = [CompTable(lengths[:, leg], -curve[:, leg]) for leg in range(6)]
    linear = geometry.replace(leg_model=LinearLegs(), leg_terms=None)
    fitted, worst = stroke_from_tables(linear, tables, 4, np.full(6, 20.0), np.full(6, 495.0))
    np.testing.assert_allclose(fitted.leg_terms, TERMS, rtol=0, atol=1e-12)
    held = legendre_values(np.full(1, -1.0), 4)[0][:, 2:] @ TERMS.T  # the curve at the stroke's low end
    assert worst == pytest.approx(np.max(np.abs(curve[0] - held[0])), rel=1e-9)


def test_type_0_tables_read_as_positions_reached():
    table = comp_tables(stroke_geometry())[0]
    positions = table.nominal - table.trim  # type 0: what the joint reached, trim = nominal - it
    text = "".join(
        f"{float(n)!r} {float(p)!r} {float(p)!r}\n" for n, p in zip(table.nominal, positions, strict=True)
    )
    back = parse_comp_table(text, "t0.tbl", 0)
    np.testing.assert_allclose(back.trim, table.trim, rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("1 2 2\nnominal forward reverse\n", "line 2: not three numbers"),
        ("1 2\n", "line 1: not three numbers"),
        ("1 0 0\n1 0 0\n", "line 2: the nominal positions must increase"),
        ("1 0 0\n2 0.1 -0.1\n", "line 2: forward and reverse differ"),
        ("1 nan nan\n", "line 1: not three numbers"),
        ("", "no table entry"),
    ],
)
def test_malformed_tables_are_refused_naming_the_line(text, words):
    with pytest.raises(LinuxCNCFormatError, match=words):
        parse_comp_table(text, "bad.tbl", 1)


def test_import_refusals_write_nothing(capsys, tmp_path):
    save_geometry(stroke_geometry(), tmp_path / "g.yaml")
    assert (
        run(capsys, "export", "linuxcnc", "--geometry", tmp_path / "g.yaml", "--out", tmp_path / "x")[0] == 0
    )
    ini = tmp_path / "x" / "hexcal-joints.ini"
    hal = tmp_path / "x" / "hexcal-kins.hal"
    (tmp_path / "x" / "hexcal-comp-3.tbl").write_text("1 0 0\nbroken\n")
    status, _, err = run(
        capsys, "import", "linuxcnc", "--hal", hal, "--ini", ini, "--out", tmp_path / "b.yaml"
    )
    assert status == 1 and "hexcal-comp-3.tbl: line 2" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "b.yaml").exists()
    ini.write_text(ini.read_text().replace("COMP_FILE = hexcal-comp-2.tbl\n", ""))
    status, _, err = run(
        capsys, "import", "linuxcnc", "--hal", hal, "--ini", ini, "--out", tmp_path / "b.yaml"
    )
    assert status == 1 and "joint(s) 2 none" in err
    status, _, err = run(
        capsys,
        "import",
        "linuxcnc",
        "--hal",
        hal,
        "--ini",
        ini,
        "--out",
        tmp_path / "x" / "hexcal-comp-0.tbl",
    )
    assert status != 0 and (tmp_path / "x" / "hexcal-comp-0.tbl").read_text().count("\n") > 5


def test_linear_geometry_writes_no_table(capsys, tmp_path):
    status, _, _ = run(capsys, "export", "linuxcnc", "--geometry", "paper-hmt", "--out", tmp_path / "x")
    assert status == 0 and "COMP_FILE" not in (tmp_path / "x" / "hexcal-joints.ini").read_text()
    assert not any((tmp_path / "x" / name).exists() for name in COMP_FILES)


_TABLE = "".join(f"{600.0 + 10 * k!r} {0.01 * k!r} {0.01 * k!r}\n" for k in range(12))


@SETTINGS
@given(data=mutated(_TABLE), kind=st.sampled_from([0, 1]))
def test_any_table_text_reads_or_is_one_clean_error(data, kind):
    text = data.decode("utf-8", errors="replace")
    try:
        table = parse_comp_table(text, "fuzz.tbl", kind)
    except HexcalError as exc:
        message = str(exc)
        assert message.startswith("fuzz.tbl") and "\n" not in message
        return
    assert np.all(np.diff(table.nominal) > 0) and np.all(np.isfinite(table.trim))
    assert 1 <= len(table.nominal) <= MAX_ENTRIES
