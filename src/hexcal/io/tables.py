"""CSV tables: strict reading (every problem named by file, line and column) and writing."""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hexcal.errors import InputError
from hexcal.io.files import atomic_write


@dataclass(frozen=True)
class Table:
    """A parsed CSV table: column names, string cells and their physical line numbers."""

    path: str
    columns: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    lines: tuple[int, ...]

    def has(self, name: str) -> bool:
        return name in self.columns

    def numbers(self, names: Sequence[str]) -> NDArray[np.float64]:
        """Numeric values of the named columns, shape ``(rows, len(names))``."""
        for name in names:
            if name not in self.columns:
                raise InputError(f"{self.path}: missing column '{name}'")
        idx = [self.columns.index(n) for n in names]
        out = np.empty((len(self.rows), len(names)))
        for r, (row, line) in enumerate(zip(self.rows, self.lines, strict=True)):
            for c, (k, name) in enumerate(zip(idx, names, strict=True)):
                text = row[k]
                try:
                    if "_" in text:  # float() accepts digit separators; a CSV number has none
                        raise ValueError(text)
                    value = float(text)
                except ValueError:
                    raise InputError(
                        f"{self.path}: line {line}, column '{name}': not a number: {text!r}"
                    ) from None
                if not math.isfinite(value):
                    raise InputError(
                        f"{self.path}: line {line}, column '{name}': {text} is not a finite number"
                    )
                out[r, c] = value
        return out

    def ids(self) -> tuple[str, ...]:
        """The ``id`` column, or the row numbers 1, 2, ... when there is none."""
        if "id" not in self.columns:
            return tuple(str(k + 1) for k in range(len(self.rows)))
        k = self.columns.index("id")
        ids = tuple(row[k] for row in self.rows)
        seen: dict[str, int] = {}
        for value, line in zip(ids, self.lines, strict=True):
            if value == "":
                raise InputError(f"{self.path}: line {line}, column 'id': empty id")
            if value in seen:
                raise InputError(
                    f"{self.path}: line {line}, column 'id': id {value!r} repeats line {seen[value]}"
                )
            seen[value] = line
        return ids


def read_table(path: str | os.PathLike[str]) -> Table:
    """Read a CSV table with a header row; ``#`` lines before the header are comments."""
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
    header: tuple[str, ...] | None = None
    rows: list[tuple[str, ...]] = []
    lines: list[int] = []
    # one physical line is one record: comments are skipped before the csv module sees
    # them (an unbalanced quote in a comment must not swallow the header)
    for lineno, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        if header is None and line.lstrip().startswith("#"):
            continue
        fields = next(csv.reader([line]))
        if header is None:
            header = tuple(f.strip() for f in fields)
            for k, col in enumerate(header):
                if col == "":
                    raise InputError(f"{name}: line {lineno}: column {k + 1} of the header has no name")
                if col in header[:k]:
                    raise InputError(f"{name}: line {lineno}: column '{col}' appears twice in the header")
            continue
        if len(fields) != len(header):
            raise InputError(f"{name}: line {lineno}: {len(fields)} fields, but the header has {len(header)}")
        rows.append(tuple(f.strip() for f in fields))
        lines.append(lineno)
    if header is None:
        raise InputError(f"{name}: empty file (no header row)")
    if not rows:
        raise InputError(f"{name}: the header has no data rows")
    return Table(name, header, tuple(rows), tuple(lines))


def _format(value: float) -> str:
    return format(float(value), ".15g")


def write_table(
    path: str | os.PathLike[str],
    columns: Sequence[str],
    data: NDArray[np.float64],
    ids: Sequence[str] | None = None,
    comment: str | None = None,
) -> None:
    """Write a CSV table (with an ``id`` column when ``ids`` is given), atomically."""
    data = np.asarray(data, dtype=float)
    with atomic_write(path) as fh:
        if comment:
            for line in comment.splitlines():
                fh.write(f"# {line}\n")
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow((["id"] if ids is not None else []) + list(columns))
        for k, row in enumerate(data):
            cells = [_format(v) for v in row]
            writer.writerow(([ids[k]] if ids is not None else []) + cells)


def read_matrix(path: str | os.PathLike[str], shape: tuple[int, int]) -> NDArray[np.float64]:
    """A small numeric matrix: rows of numbers separated by commas or blanks; ``#`` comments."""
    name = str(path)
    try:
        with open(path, encoding="utf-8") as fh:
            lines = fh.read().splitlines()
    except FileNotFoundError:
        raise InputError(f"{name}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{name}: cannot read: {exc}") from None
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
            raise InputError(f"{name}: line {lineno}: not a row of numbers: {line.strip()!r}") from None
        if len(values) != shape[1]:
            raise InputError(f"{name}: line {lineno}: {len(values)} numbers, expected {shape[1]}")
        if not all(math.isfinite(v) for v in values):
            raise InputError(f"{name}: line {lineno}: NaN or inf")
        rows.append(values)
    if len(rows) != shape[0]:
        raise InputError(f"{name}: {len(rows)} rows, expected {shape[0]}")
    return np.array(rows)
