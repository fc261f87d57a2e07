"""Instrument exports: target measurement files and tool pose files as tracker software
writes them (FORMATS.md "Target measurement file").

Real exports use ``;`` or tabs between fields and decimal commas, and some add a unit row
under the header. :func:`read_export` detects the delimiter (from the header: ``;``, then tab,
else ``,``) and the decimal mark (a comma-separated file has decimal points; otherwise a
decimal comma when the numbers look like ``12,5``), or takes ``delimiter``/``decimal``; a
unit row (only unit words such as ``mm``, ``[mm]``, ``rad``, ``deg``) is skipped, and a length
unit other than mm is refused. When the file looks like one convention but is read as
another (an override that contradicts the file), an :class:`InputWarning` says so.
"""

from __future__ import annotations

import csv
import itertools
import math
import os
import re
import warnings

import numpy as np
from numpy.typing import NDArray

from hexcal.errors import InputError, InputWarning
from hexcal.instruments.pose import Measurements
from hexcal.instruments.setup import Setup
from hexcal.instruments.targets import TargetMeasurements
from hexcal.io.files import atomic_write
from hexcal.io.measurement_files import LEG_READING_COLUMNS, table_poses
from hexcal.io.tables import Table

DELIMITERS = {",": "comma", ";": "semicolon", "\t": "tab"}
UNIT_WORDS = {"mm", "rad", "deg", "°", "-", "", "1"}
_DECIMAL_COMMA = re.compile(r"^[+-]?\d*,\d+([eE][+-]?\d+)?$")
_DECIMAL_POINT = re.compile(r"^[+-]?\d*\.\d+([eE][+-]?\d+)?$")
_TARGET_COLUMN = re.compile(r"^(t[0-9]+)\.([xyz])$")


def _split(line: str, delimiter: str) -> list[str]:
    return [f.strip() for f in next(csv.reader([line], delimiter=delimiter))]


def _unit(cell: str) -> str:
    return cell.strip().strip("[]()").strip().lower()


def read_export(
    path: str | os.PathLike[str], delimiter: str | None = None, decimal: str | None = None
) -> Table:
    """A table from an instrument export, cells normalised to decimal points (see module)."""
    name = str(path)
    try:
        with open(path, encoding="utf-8-sig", newline="") as fh:
            text = fh.read()
    except FileNotFoundError:
        raise InputError(f"{name}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{name}: is a folder, not a file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{name}: cannot read: {exc}") from None
    records = [(k, line) for k, line in enumerate(text.splitlines(), start=1) if line.strip()]
    while records and records[0][1].lstrip().startswith("#"):
        records.pop(0)
    if not records:
        raise InputError(f"{name}: empty file (no header row)")
    head_line, head = records[0]
    looks = ";" if ";" in head else "\t" if "\t" in head else ","
    if delimiter is None:
        delimiter = looks
    elif delimiter not in DELIMITERS:
        raise InputError(f"delimiter must be one of ',', ';', tab, got {delimiter!r}")
    elif delimiter != looks:
        warnings.warn(
            f"{name}: the header looks {DELIMITERS[looks]}-separated, but the file is read "
            f"{DELIMITERS[delimiter]}-separated as asked",
            InputWarning,
            stacklevel=2,
        )
    header = tuple(_split(head, delimiter))
    for k, col in enumerate(header):
        if col == "":
            raise InputError(f"{name}: line {head_line}: column {k + 1} of the header has no name")
        if col in header[:k]:
            raise InputError(f"{name}: line {head_line}: column '{col}' appears twice in the header")
    body = [(k, _split(line, delimiter)) for k, line in records[1:]]
    if (
        body
        and all(_unit(c) in UNIT_WORDS or not _looks_numeric(c) for c in body[0][1])
        and any(_unit(c) in UNIT_WORDS - {""} for c in body[0][1])
    ):
        unit_line, units = body.pop(0)
        for col, cell in zip(header, units, strict=False):
            unit = _unit(cell)
            if unit not in UNIT_WORDS:
                raise InputError(
                    f"{name}: line {unit_line}, column '{col}': unit {cell!r}; "
                    "only mm (and rad/deg for angles)"
                )
    if not body:
        raise InputError(f"{name}: the header has no data rows")
    cells = [c for _, row in body for c in row]
    commas = sum(bool(_DECIMAL_COMMA.match(c)) for c in cells)
    points = sum(bool(_DECIMAL_POINT.match(c)) for c in cells)
    looks_dec = "," if delimiter != "," and commas > points else "."
    if decimal is None:
        decimal = looks_dec
    elif decimal not in (",", "."):
        raise InputError(f"decimal mark must be ',' or '.', got {decimal!r}")
    elif decimal != looks_dec:
        warnings.warn(
            f"{name}: the numbers look like decimal {'commas' if looks_dec == ',' else 'points'}, but "
            f"they are read with a decimal {'comma' if decimal == ',' else 'point'} as asked",
            InputWarning,
            stacklevel=2,
        )
    if decimal == "," and delimiter == ",":
        raise InputError(f"{name}: a comma cannot be both the delimiter and the decimal mark")
    rows, lines = [], []
    for line, row in body:
        if len(row) != len(header):
            hint = ""
            if (
                delimiter == ","
                and len(row) > len(header)
                and any(_DECIMAL_COMMA.match(f"{x},{y}") for x, y in itertools.pairwise(row))
            ):
                hint = " (decimal commas in a comma-separated file? export with ';' between fields)"
            raise InputError(
                f"{name}: line {line}: {len(row)} fields, but the header has {len(header)}{hint}"
            )
        if decimal == ",":
            for c in row:
                if "." in c and "," in c:
                    raise InputError(f"{name}: line {line}: {c!r} has a thousands separator; remove it")
            row = [c.replace(",", ".") for c in row]
        rows.append(tuple(row))
        lines.append(line)
    return Table.from_rows(name, header, rows, lines)


def _looks_numeric(cell: str) -> bool:
    try:
        float(cell.replace(",", "."))
    except ValueError:
        return False
    return True


def _target_values(table: Table, setup: Setup) -> NDArray[np.float64]:
    """Target positions ``(m, n, 3)`` with NaN for empty cells (whole targets only)."""
    names = setup.target_names
    for col in table.columns:
        match = _TARGET_COLUMN.match(col)
        if match and match.group(1) not in names:
            raise InputError(
                f"{table.path}: column '{col}': target {match.group(1)} "
                f"is not in the setup ({', '.join(names)})"
            )
    cols = [f"{t}.{ax}" for t in names for ax in "xyz"]
    for col in cols:
        if col not in table.columns:
            raise InputError(
                f"{table.path}: missing column '{col}' (the setup has targets {', '.join(names)})"
            )
    idx = [table.columns.index(c) for c in cols]
    out = np.full((len(table.rows), len(names), 3), np.nan)
    for r, (row, line) in enumerate(zip(table.rows, table.lines, strict=True)):
        seen = 0
        for t, target in enumerate(names):
            cells = [row[idx[3 * t + a]] for a in range(3)]
            empty = [c == "" for c in cells]
            if all(empty):
                continue
            if any(empty):
                col = cols[3 * t + empty.index(True)]
                raise InputError(
                    f"{table.path}: line {line}, column '{col}': "
                    f"empty, but target {target} has other coordinates"
                )
            for a, text in enumerate(cells):
                try:
                    value = float(text) if "_" not in text else float("nan")
                except ValueError:
                    value = float("nan")
                if not math.isfinite(value):
                    raise InputError(
                        f"{table.path}: line {line}, column '{cols[3 * t + a]}': not a number: {text!r}"
                    )
                out[r, t, a] = value
            seen += 1
        if not seen:
            raise InputError(f"{table.path}: line {line}: no target seen (every target cell is empty)")
    return out


def read_target_measurements(
    path: str | os.PathLike[str], setup: Setup, delimiter: str | None = None, decimal: str | None = None
) -> TargetMeasurements:
    """A target measurement file: leg readings, target positions (instrument frame), ids."""
    if setup.kind != "targets":
        raise InputError(f"{path}: the setup has a tool, not targets: read the file as tool poses")
    table = read_export(path, delimiter, decimal)
    readings = table.numbers(LEG_READING_COLUMNS)
    return TargetMeasurements(readings, _target_values(table, setup), setup.target_names, table.ids())


def read_tool_measurements(
    path: str | os.PathLike[str], euler: str, delimiter: str | None = None, decimal: str | None = None
) -> Measurements:
    """A tool pose file (the columns of a measurement file, the tool's pose in the instrument frame)."""
    table = read_export(path, delimiter, decimal)
    return Measurements(table_poses(table, euler), table.numbers(LEG_READING_COLUMNS), table.ids())


def write_target_measurements(
    path: str | os.PathLike[str], data: TargetMeasurements, comment: str | None = None
) -> None:
    """Write a target measurement file (standard CSV; lost targets as empty cells), atomically."""
    cols = ["id", *LEG_READING_COLUMNS] + [f"{t}.{ax}" for t in data.names for ax in "xyz"]
    with atomic_write(path) as fh:
        for line in (comment or "").splitlines():
            fh.write(f"# {line}\n")
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(cols)
        flat = data.targets.reshape(len(data), -1)
        for k in range(len(data)):
            cells = [format(float(v), ".15g") for v in data.readings[k]]
            cells += ["" if np.isnan(v) else format(float(v), ".15g") for v in flat[k]]
            writer.writerow([data.ids[k], *cells])
