"""Hypothesis: hexcal's readers end with a valid result or one clean HexcalError, whatever the bytes.

Random bytes, and random mutations (bytes inserted, deleted, replaced; lines duplicated,
dropped or swapped; cells emptied or replaced by tricky tokens) of valid CSV and YAML files,
fed to every reader. Any other exception (TypeError, RecursionError, csv.Error, OverflowError,
yaml errors...) fails the test. The file is never modified by reading it.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hexcal.core.geometry import Geometry
from hexcal.core.presets import preset
from hexcal.errors import HexcalError
from hexcal.io import (
    iter_legs,
    iter_poses,
    load_geometry,
    read_legs,
    read_measurements,
    read_poses,
    read_table,
)

SETTINGS = settings(
    max_examples=int(os.environ.get("HEXCAL_FUZZ_EXAMPLES", "60")),  # more: a longer fuzzing run
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

MEASUREMENT = (
    "# tracker export\n"
    "id,dl1,dl2,dl3,dl4,dl5,dl6,x,y,z,a_deg,b_deg,c_deg\n"
    "p1,10,20,30,40,50,60,1.5,-2,800,1,2,3\n"
    "p2,11,21,31,41,51,61,2.5,-3,810,-1,0.5,0\n"
    '"p,3",12,22,32,42,52,62,3.5,-4,790,0,0,-2\n'
)
LEGS = "l1,l2,l3,l4,l5,l6,dl1,dl2,dl3,dl4,dl5,dl6\r\n800,801,802,803,804,805,0,1,2,3,4,5\r\n"
GEOMETRY = yaml.safe_dump(preset("paper-hmt").to_dict(), sort_keys=False)
TOKENS = [
    "",
    "nan",
    "inf",
    "-0",
    "1e999",
    "1_0",
    "#",
    '"',
    '""',
    ",",
    "\ufeff",
    "\x00",
    "٣",
    "&a",
    "*a",
    "[",
    "{",
]

CSV_READERS = {
    "table": read_table,
    "poses": lambda p: read_poses(p, "XYZ"),
    "measurements": lambda p: read_measurements(p, "zyx"),
    "legs": read_legs,
    "pose blocks": lambda p: list(iter_poses(p, "XYZ", block_rows=2)),
    "leg blocks": lambda p: list(iter_legs(p, block_rows=1)),
}


def _check(reader, path: Path, data: bytes) -> None:
    path.write_bytes(data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            result = reader(path)
        except HexcalError as exc:
            message = str(exc)
            assert message and "\n" not in message, repr(message)
            assert message.startswith(str(path)), message
            result = None
    assert path.read_bytes() == data
    if isinstance(result, Geometry):
        assert np.all(np.isfinite(result.to_vector(gains=True)))
        assert np.all(result.leg_gains > 0) and np.all(result.initial_leg_lengths > 0)


@st.composite
def mutated(draw, text: str) -> bytes:
    """A valid file after a few random edits, at the byte, line and cell levels."""
    data = bytearray(text.encode("utf-8"))
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["insert", "delete", "replace", "line", "token"]))
        at = draw(st.integers(0, max(len(data) - 1, 0)))
        if kind == "insert":
            data[at:at] = draw(st.binary(min_size=1, max_size=4))
        elif kind == "delete":
            del data[at : at + draw(st.integers(1, 8))]
        elif kind == "replace" and data:
            data[at] = draw(st.integers(0, 255))
        elif kind == "token":
            data[at : at + draw(st.integers(0, 4))] = draw(st.sampled_from(TOKENS)).encode("utf-8")
        else:
            lines = bytes(data).split(b"\n")
            k = draw(st.integers(0, len(lines) - 1))
            op = draw(st.sampled_from(["dup", "drop", "swap", "hash"]))
            if op == "dup":
                lines.insert(k, lines[k])
            elif op == "drop":
                del lines[k]
            elif op == "swap":
                j = draw(st.integers(0, len(lines) - 1))
                lines[k], lines[j] = lines[j], lines[k]
            else:
                lines[k] = b"#" + lines[k]
            data = bytearray(b"\n".join(lines))
    return bytes(data)


@pytest.mark.parametrize("reader", sorted(CSV_READERS))
@SETTINGS
@given(data=st.binary(max_size=300))
def test_csv_readers_on_random_bytes(tmp_path, reader, data):
    _check(CSV_READERS[reader], tmp_path / "in.csv", data)


@pytest.mark.parametrize("reader", sorted(CSV_READERS))
@SETTINGS
@given(data=st.one_of(mutated(MEASUREMENT), mutated(LEGS)))
def test_csv_readers_on_mutated_files(tmp_path, reader, data):
    _check(CSV_READERS[reader], tmp_path / "in.csv", data)


@SETTINGS
@given(data=st.binary(max_size=400))
def test_geometry_reader_on_random_bytes(tmp_path, data):
    _check(load_geometry, tmp_path / "g.yaml", data)


@settings(SETTINGS, max_examples=SETTINGS.max_examples * 2)
@given(data=mutated(GEOMETRY))
def test_geometry_reader_on_mutated_files(tmp_path, data):
    _check(load_geometry, tmp_path / "g.yaml", data)


_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=7) | st.dictionaries(st.text(max_size=3) | st.integers(), inner),
    max_leaves=30,
)


@settings(SETTINGS, max_examples=SETTINGS.max_examples * 2)
@given(key=st.sampled_from(sorted(preset("paper-hmt").to_dict())), value=_VALUES, extra=st.booleans())
def test_geometry_reader_on_any_value_of_any_key(tmp_path, key, value, extra):
    data = preset("paper-hmt").to_dict()
    data[key] = value
    if extra:
        data[7] = "an integer key beside the string keys"
    text = yaml.safe_dump(data, sort_keys=False, allow_unicode=True)
    _check(load_geometry, tmp_path / "g.yaml", text.encode("utf-8"))
