"""The vectorised table writer writes exactly what ``format(v, ".15g")`` and the csv module wrote.

Every number is compared with Python's own formatting: random bit patterns (every exponent,
subnormals), values at the edges of the numpy path (powers of ten, the exponent range
``[-8, 14]`` and just beyond it, values that round up to the next power of ten, exact ties),
and Hypothesis floats; ids that need quoting or are refused take the exact path.
"""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from hexcal.io import OutputError, read_table, write_table
from hexcal.io.table_writing import TableWriter, format_rows, format_values


def _texts(values: np.ndarray, missing: bool = False) -> list[str]:
    return [bytes(row).replace(b"\0", b"").decode("ascii") for row in format_values(values, missing)]


def _python(values: np.ndarray) -> list[str]:
    return [format(float(v), ".15g") for v in values]


EDGES = np.array(
    [
        0.0, -0.0, 5e-324, -5e-324, 2.2250738585072014e-308, 1.7976931348623157e308, 0.5, 2.5, -1.5,
        1e15, 1e14, 999999999999999.5, 999999999999999.4, 99999999999999.95, 1234567890123455.0,
        1234567890123445.0, 0.0001, 0.00001, 9.9999999999999995e-5, 1e-8, 9.9999999999999995e-9,
        1e-9, 0.1 + 0.2, 123456789012345678.0, 1e22, 1e23, 100.0, 12300.0, 0.000123,
    ]
)  # fmt: skip


def test_random_bit_patterns_and_edges_match_python():
    rng = np.random.default_rng(20)
    bits = rng.integers(0, 2**64, 100_000, dtype=np.uint64, endpoint=False)
    raw = bits.view(np.float64)
    scales = 10.0 ** rng.integers(-12, 18, 50_000)
    near_powers = np.nextafter(10.0 ** rng.integers(-10, 17, 20_000), rng.choice([0.0, np.inf], 20_000))
    short = np.floor(rng.uniform(-1e8, 1e8, 50_000)) / 10.0 ** rng.integers(0, 9, 50_000)
    for values in (raw[np.isfinite(raw)], rng.normal(0, 1, 50_000) * scales, near_powers, short, EDGES):
        assert _texts(values) == _python(values)


@settings(max_examples=200, deadline=None)
@given(hnp.arrays(np.float64, st.integers(1, 40), elements=st.floats(allow_nan=False, allow_infinity=False)))
def test_any_finite_float_is_written_as_python_writes_it(values):
    assert _texts(values) == _python(values)


def test_missing_values_are_empty_cells():
    assert _texts(np.array([1.5, np.nan, -2.0, 0.0]), missing=True) == ["1.5", "", "-2", "0"]


@pytest.mark.parametrize(
    "ids",
    [
        ["p0", "p1", "p2"],
        ["with,comma", 'with "quote"', "é-non-ascii"],
        [" spaced", "x-=nul", "-7"],
        [1, 2, 3],
    ],
)
def test_rows_match_the_csv_module(ids):
    data = np.array([[1.0, -2.5e-7], [3e20, 0.1], [-0.0, 123456.789]])
    expected = io.StringIO()
    writer = csv.writer(expected, lineterminator="\n")
    for k, row in enumerate(data):
        writer.writerow([ids[k], *(format(float(v), ".15g") for v in row)])
    assert format_rows("t.csv", data, ids).decode("utf-8") == expected.getvalue()


@pytest.mark.parametrize(
    "bad", ["", "  ", "#3", " #3", "a\nb", "a\rb", "a\x00b", "a\u2028b", "=1+1", "+x", "-x", "@x", "\tx"]
)
def test_ids_that_cannot_be_read_back_are_refused(tmp_path, bad):
    with pytest.raises(OutputError, match="cannot be written"):
        write_table(tmp_path / "t.csv", ["u"], np.ones((2, 1)), ids=["ok", bad])
    assert list(tmp_path.iterdir()) == []


def test_blocks_of_any_size_give_the_same_file(tmp_path, monkeypatch):
    import hexcal.io.table_writing as module

    rng = np.random.default_rng(3)
    data = rng.normal(0, 100, (1000, 5))
    ids = [f"r{k}" for k in range(1000)]
    write_table(tmp_path / "a.csv", list("uvwxy"), data, ids)
    monkeypatch.setattr(module, "FORMAT_ROWS", 7)
    write_table(tmp_path / "b.csv", list("uvwxy"), data, ids)
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    np.testing.assert_allclose(read_table(tmp_path / "a.csv").numbers(list("uvwxy")), data, rtol=1e-14)


def test_a_writer_needs_columns():
    with pytest.raises(ValueError, match="at least one column"):
        TableWriter(io.StringIO(), "t.csv", [], with_ids=False)
