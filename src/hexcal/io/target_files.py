"""Instrument exports: target measurement files and tool pose files as tracker software
writes them (docs/formats.md "Target measurement file").

Real exports use ``;`` or tabs between fields and decimal commas, and some add a unit row
under the header. They are read by hexcal's one table reader (:mod:`hexcal.io.tables`), like
every other table: the delimiter and the decimal mark are detected (or given with
``delimiter=``/``decimal=``, a contradicting choice warned about), a unit row is checked
(lengths in mm) and skipped, thousands separators and oversized fields are refused, the row
limit (:data:`~hexcal.io.inputs.MEASUREMENT_MAX_ROWS`, ``--max-rows``) is checked while
reading, and ``columns=`` maps hexcal's names to the export's (:func:`parse_column_map`
reads a map from a command line). Also the pose covariance matrix file (:func:`read_matrix`).
"""

from __future__ import annotations

import csv
import os
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from hexcal.core.text import printable
from hexcal.errors import InputError, UsageError
from hexcal.instruments.pose import Measurements
from hexcal.instruments.setup import Setup
from hexcal.instruments.targets import TargetMeasurements
from hexcal.io.covariate_columns import covariate_columns, table_covariates
from hexcal.io.files import atomic_write
from hexcal.io.inputs import MEASUREMENT_MAX_ROWS, read_text
from hexcal.io.measurement_files import table_poses
from hexcal.io.table_reading import read_table
from hexcal.io.tables import (
    DELIMITERS,
    LEG_READING_COLUMNS,
    ORIENTATION_GROUPS,
    TARGET_COLUMN,
    UNIT_WORDS,
    Table,
    check_column_map,
)

__all__ = ["DELIMITERS", "UNIT_WORDS", "parse_column_map", "read_export", "read_matrix"]


def read_export(
    path: str | os.PathLike[str],
    delimiter: str | None = None,
    decimal: str | None = None,
    columns: Mapping[str, str] | None = None,
    max_rows: int | None = MEASUREMENT_MAX_ROWS,
) -> Table:
    """A table from an instrument export (the rules of :func:`~hexcal.io.table_reading.read_table`)."""
    return read_table(path, max_rows, delimiter, decimal, columns)


def _target_values(table: Table, setup: Setup) -> NDArray[np.float64]:
    """Target positions ``(m, n, 3)`` with NaN for empty cells (whole targets only)."""
    names = setup.target_names
    for col in table.columns:
        match = TARGET_COLUMN.match(col)
        if match and match.group(1) not in names:
            raise InputError(
                f"{table.path}: column '{table.label(col)}': target {match.group(1)} "
                f"is not in the setup ({_listed(names)})"
            )
    cols = [f"{t}.{ax}" for t in names for ax in "xyz"]
    for col in cols:
        if col not in table.columns:
            raise InputError(
                f"{table.path}: missing column '{table.label(col)}' (the setup's targets: {_listed(names)})"
            )
    values = table.numbers(cols, empty=True).reshape(len(table), len(names), 3)
    lost = np.isnan(values)
    partly = np.argwhere(lost.any(axis=2) & ~lost.all(axis=2))
    if partly.size:  # the first in reading order
        r, t = partly[0]
        a = int(np.flatnonzero(lost[r, t])[0])
        raise InputError(
            f"{table.path}: line {table.line(int(r))}, column '{table.label(cols[3 * t + a])}': "
            f"empty, but target {names[t]} has other coordinates"
        )
    blind = np.flatnonzero(lost.all(axis=(1, 2)))
    if blind.size:
        raise InputError(
            f"{table.path}: line {table.line(int(blind[0]))}: no target seen (every target cell is empty)"
        )
    return values


def read_target_measurements(
    path: str | os.PathLike[str],
    setup: Setup,
    delimiter: str | None = None,
    decimal: str | None = None,
    columns: Mapping[str, str] | None = None,
    max_rows: int | None = MEASUREMENT_MAX_ROWS,
) -> TargetMeasurements:
    """A target measurement file: leg readings, target positions (instrument frame), ids.

    ``delimiter``, ``decimal``, ``columns`` and ``max_rows`` (default 100,000; ``--max-rows``)
    as for :func:`~hexcal.io.table_reading.read_table`.
    """
    if setup.kind != "targets":
        raise InputError(f"{path}: the setup has a tool, not targets: read the file as tool poses")
    table = read_export(path, delimiter, decimal, columns, max_rows)
    found = covariate_columns(table)
    readings = table.numbers((*LEG_READING_COLUMNS, *found))[:, :6]  # in one pass
    values, names = _target_values(table, setup), setup.target_names
    return TargetMeasurements(readings, values, names, table.ids(), table_covariates(table, found))


def read_tool_measurements(
    path: str | os.PathLike[str],
    euler: str,
    delimiter: str | None = None,
    decimal: str | None = None,
    columns: Mapping[str, str] | None = None,
    max_rows: int | None = MEASUREMENT_MAX_ROWS,
) -> Measurements:
    """A tool pose file (the columns of a measurement file, the tool's pose in the instrument frame)."""
    table = read_export(path, delimiter, decimal, columns, max_rows)
    pose = ("x", "y", "z", *(c for group in ORIENTATION_GROUPS.values() for c in group))
    found = covariate_columns(table)
    table.numbers([c for c in pose if table.has(c)] + list(LEG_READING_COLUMNS) + list(found))  # in one pass
    poses, readings = table_poses(table, euler), table.numbers(LEG_READING_COLUMNS)
    return Measurements(poses, readings, table.ids(), table_covariates(table, found))


def _listed(names: list[str] | tuple[str, ...], most: int = 8) -> str:
    """Names for a message: the first ``most``, then how many more."""
    shown = ", ".join(names[:most])
    return shown if len(names) <= most else f"{shown} and {len(names) - most} more"


def write_target_measurements(
    path: str | os.PathLike[str], data: TargetMeasurements, comment: str | None = None
) -> None:
    """Write a target measurement file (standard CSV; lost targets as empty cells; the covariates
    after the targets), atomically."""
    extra = data.covariates.to_columns()
    cols = ["id", *LEG_READING_COLUMNS] + [f"{t}.{ax}" for t in data.names for ax in "xyz"] + list(extra)
    more = np.column_stack(list(extra.values())) if extra else np.empty((len(data), 0))
    with atomic_write(path) as fh:
        for line in comment.rstrip("\n").split("\n") if comment else ():
            fh.write(f"# {printable(line)}\n")
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(cols)
        flat = data.targets.reshape(len(data), -1)
        for k in range(len(data)):
            cells = [format(float(v), ".15g") for v in data.readings[k]]
            cells += ["" if np.isnan(v) else format(float(v), ".15g") for v in flat[k]]
            cells += [format(float(v), ".15g") for v in more[k]]
            writer.writerow([data.ids[k], *cells])


def parse_column_map(text: str) -> dict[str, str]:
    """A column map from a command-line spec ``dl1=leg_length_1,x=position_x,...``.

    Each item is ``hexcal_name=file_column`` (blanks around either are ignored; a file
    column name cannot hold ``,`` or ``=``).

    Raises
    ------
    UsageError
        One line naming the problem: an item without ``=``, an empty name, an unknown
        hexcal name, a hexcal name given twice, a file column mapped twice.

    Examples
    --------
    >>> parse_column_map("x=position_x, y=position_y")
    {'x': 'position_x', 'y': 'position_y'}
    """
    out: dict[str, str] = {}
    items = [item.strip() for item in text.split(",")]
    if not any(items):
        raise UsageError("column map: empty; give hexcal_name=file_column,...")
    for item in items:
        ours, sep, theirs = item.partition("=")
        ours, theirs = ours.strip(), theirs.strip()
        if not sep or not ours or not theirs or "=" in theirs:
            raise UsageError(f"column map: {item!r} is not hexcal_name=file_column")
        if ours in out:
            raise UsageError(f"column map: {ours} is given twice ({ours}={out[ours]} and {ours}={theirs})")
        out[ours] = theirs
    check_column_map(out)
    return out


def read_matrix(path: str | os.PathLike[str], shape: tuple[int, int]) -> NDArray[np.float64]:
    """A small numeric matrix: rows of numbers separated by commas or blanks; ``#`` comments."""
    name = str(path)
    lines = read_text(path, max_bytes=1 << 20).splitlines()
    rows = []
    for lineno, line in enumerate(lines, start=1):
        text = line.split("#", 1)[0].replace(",", " ").split()
        if not text:
            continue
        try:
            if any("_" in v for v in text):  # float() accepts digit separators
                raise ValueError
            values = [float(v) for v in text]
        except ValueError:
            raise InputError(f"{name}: line {lineno}: not a row of numbers: {line.strip()[:80]!r}") from None
        if len(values) != shape[1]:
            raise InputError(f"{name}: line {lineno}: {len(values)} numbers, expected {shape[1]}")
        if not all(np.isfinite(v) for v in values):
            raise InputError(f"{name}: line {lineno}: NaN or inf")
        rows.append(values)
    if len(rows) != shape[0]:
        raise InputError(f"{name}: {len(rows)} rows, expected {shape[0]}")
    return np.array(rows)
