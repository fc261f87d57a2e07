"""CSV tables: strict reading (every problem named by file, line and column) and writing.

Reading rules (FORMATS.md, with two extensions marked *):

- one physical line is one record (no line breaks inside quoted fields); blank lines are
  skipped; a UTF-8 byte order mark at the start is skipped;
- lines whose first non-blank character is ``#`` are comments: before the header (FORMATS.md)
  and, *, after it too (a commented-out row is skipped, never read as a row with id ``#``;
  an ``id`` cell starting with ``#`` is refused);
- * a second byte order mark at the start of the file is skipped with an
  :class:`~hexcal.errors.InputWarning` (it would otherwise hide the first column's name);
- a quoted field over the csv module's limit (131,072 characters) is refused with one line.

Only regular files are read (:mod:`hexcal.io.inputs`). :func:`read_table` refuses a file with
more than ``max_rows`` data rows (default :data:`~hexcal.io.inputs.DEFAULT_MAX_ROWS`) while
reading it; :func:`iter_tables` reads a file of any length in blocks of rows, in bounded
memory. Numbers are converted a block at a time with numpy (``float`` semantics, digit
separators ``_`` refused); a table keeps its data lines as text until then.

Writing is in :mod:`hexcal.io.table_writing` (re-exported here).
"""

from __future__ import annotations

import csv
import io
import os
import warnings
from collections.abc import Iterator, Sequence
from typing import IO

import numpy as np
from numpy.typing import NDArray

from hexcal.errors import InputError, InputWarning
from hexcal.io.inputs import DEFAULT_MAX_ROWS, open_input, read_text, row_limit, too_many_rows

#: Rows converted (or read, by :func:`iter_tables`) at a time.
BLOCK_ROWS = 16_384

_CHUNK_CHARS = 1 << 22
_BOM = "\ufeff"


def _split(path: str, lineno: int, line: str) -> list[str]:
    """The fields of one line (the csv module only when the line has quotes)."""
    if '"' not in line:
        return line.split(",")
    try:
        return next(csv.reader([line]))
    except csv.Error as exc:
        raise InputError(f"{path}: line {lineno}: cannot read the fields ({exc})") from None


class Table:
    """A parsed CSV table: column names, data lines as text and their physical line numbers.

    Attributes
    ----------
    path : str
    columns : tuple of str
    rows : tuple of tuple of str
        The cells, stripped of surrounding blanks (built on first use).
    lines : tuple of int
        Physical line number (from 1) of each row.
    """

    def __init__(self, path: str, columns: tuple[str, ...], records: list[str], lines: Sequence[int]) -> None:
        self.path = path
        self.columns = columns
        self._records = records
        self._lines = np.asarray(lines, dtype=np.int64)
        self._rows: tuple[tuple[str, ...], ...] | None = None
        self._numbers: dict[str, NDArray[np.float64]] = {}
        self._id_cells: list[str] | None = None

    @classmethod
    def from_rows(
        cls, path: str, columns: tuple[str, ...], rows: Sequence[Sequence[str]], lines: Sequence[int]
    ) -> Table:
        """A table of already split cells (e.g. an export read with another delimiter)."""
        buffer = io.StringIO()
        csv.writer(buffer, lineterminator="\n").writerows(rows)
        return cls(path, columns, buffer.getvalue().splitlines(), lines)

    def __len__(self) -> int:
        return len(self._records)

    @property
    def lines(self) -> tuple[int, ...]:
        return tuple(self._lines.tolist())

    @property
    def rows(self) -> tuple[tuple[str, ...], ...]:
        if self._rows is None:
            self._rows = tuple(
                tuple(f.strip() for f in _split(self.path, int(n), r))
                for r, n in zip(self._records, self._lines, strict=True)
            )
        return self._rows

    def line(self, k: int) -> int:
        """Physical line number of row ``k``."""
        return int(self._lines[k])

    def has(self, name: str) -> bool:
        return name in self.columns

    def _block_columns(self, start: int, stop: int, ks: Sequence[int]) -> dict[int, list[str]]:
        """The cells of columns ``ks`` in rows ``start:stop`` (each line split once)."""
        block = self._records[start:stop]
        joined = ",".join(block)
        if '"' not in joined:  # every line has exactly len(columns) fields (checked when read)
            flat = joined.split(",")
            width = len(self.columns)
            return {k: flat[k::width] for k in ks}
        fields = [_split(self.path, self.line(start + i), r) for i, r in enumerate(block)]
        return {k: [f[k] for f in fields] for k in ks}

    def numbers(self, names: Sequence[str]) -> NDArray[np.float64]:
        """Numeric values of the named columns, shape ``(rows, len(names))``.

        Columns are converted once (a block of rows at a time, each line split once for all
        the columns asked together) and kept; ask for every column needed in one call.
        """
        for name in names:
            if name not in self.columns:
                raise InputError(f"{self.path}: missing column '{name}'")
        todo = [n for n in dict.fromkeys(names) if n not in self._numbers]
        if todo:
            self._convert(todo)
        if not names:
            return np.empty((len(self), 0))
        return np.column_stack([self._numbers[n] for n in names])

    def _convert(self, names: list[str]) -> None:
        idx = [self.columns.index(n) for n in names]
        id_col = self.columns.index("id") if "id" in self.columns and self._id_cells is None else None
        id_cells: list[str] = []
        out = np.empty((len(self), len(names)))
        for start in range(0, len(self), BLOCK_ROWS):
            stop = min(start + BLOCK_ROWS, len(self))
            values = out[start:stop]
            fast = self._fast_block(start, stop, idx)
            if fast is not None:
                values[:] = fast
                if id_col is not None:
                    k = id_col
                    id_cells.extend(r.split(",", k + 1)[k] for r in self._records[start:stop])
                if np.all(np.isfinite(fast)):
                    continue
            cells = self._block_columns(start, stop, idx + ([id_col] if id_col is not None else []))
            if id_col is not None and fast is None:
                id_cells.extend(cells[id_col])
            try:
                for c, k in enumerate(idx):
                    if "_" in "".join(cells[k]):  # float() accepts digit separators; a CSV number has none
                        raise ValueError
                    values[:, c] = np.array(cells[k], dtype=float)
            except ValueError:
                values[:] = self._locate(cells, start, idx, names)
            bad = np.flatnonzero(~np.isfinite(values).ravel())
            if bad.size:
                r, c = divmod(int(bad[0]), len(idx))
                raise InputError(
                    f"{self.path}: line {self.line(start + r)}, column '{names[c]}': "
                    f"{cells[idx[c]][r].strip()} is not a finite number"
                )
        for c, name in enumerate(names):
            self._numbers[name] = out[:, c].copy()
        if id_col is not None:
            self._id_cells = id_cells

    def _fast_block(self, start: int, stop: int, idx: list[int]) -> NDArray[np.float64] | None:
        """The block's numbers by numpy's C parser, or None (quotes, or a cell it refuses).

        ``np.loadtxt`` accepts a subset of what ``float`` accepts (no ``_``, no non-ASCII
        digits) and rounds alike; a block it refuses goes the cell-by-cell way, which
        decides and names the first bad cell.
        """
        text = "\n".join(self._records[start:stop])
        if '"' in text:
            return None
        try:
            values = np.loadtxt(
                io.StringIO(text),
                delimiter=",",
                usecols=idx,
                dtype=float,
                comments=None,
                quotechar=None,
                ndmin=2,
            )
        except ValueError:
            return None
        return values.reshape(stop - start, len(idx))

    def _locate(
        self, cells: dict[int, list[str]], start: int, idx: list[int], names: Sequence[str]
    ) -> NDArray[np.float64]:
        """Convert a block cell by cell: the error of the first bad cell, in reading order."""
        rows = len(cells[idx[0]])
        out = np.empty((rows, len(idx)))
        for r in range(rows):
            for c, (k, name) in enumerate(zip(idx, names, strict=True)):
                text = cells[k][r].strip()
                try:
                    if "_" in text:
                        raise ValueError(text)
                    value = float(text)
                except ValueError:
                    raise InputError(
                        f"{self.path}: line {self.line(start + r)}, column '{name}': not a number: {text!r}"
                    ) from None
                if not np.isfinite(value):
                    raise InputError(
                        f"{self.path}: line {self.line(start + r)}, column '{name}': "
                        f"{text} is not a finite number"
                    )
                out[r, c] = value
        return out

    def ids(self, seen: dict[str, int] | None = None, first: int = 1) -> tuple[str, ...]:
        """The ``id`` column, or the row numbers ``first, first + 1, ...`` when there is none.

        ``seen`` (id -> line) carries the ids of earlier blocks of the same file.
        """
        if "id" not in self.columns:
            return tuple(str(first + k) for k in range(len(self)))
        if self._id_cells is None:
            k = self.columns.index("id")
            self._id_cells = [
                cell
                for start in range(0, len(self), BLOCK_ROWS)
                for cell in self._block_columns(start, min(start + BLOCK_ROWS, len(self)), [k])[k]
            ]
        ids = [c.strip() for c in self._id_cells]
        known = {} if seen is None else seen
        fresh = dict(zip(ids, self._lines.tolist(), strict=True))
        clash = len(fresh) != len(ids) or not known.keys().isdisjoint(fresh)
        if clash or "" in fresh or any(i[:1] == "#" for i in fresh):
            self._id_error(ids, dict(known))
        if seen is not None:
            seen.update(fresh)
        return tuple(ids)

    def _id_error(self, ids: list[str], seen: dict[str, int]) -> None:
        """Raise the error of the first bad id, in reading order."""
        for k, value in enumerate(ids):
            line = self.line(k)
            if value == "":
                raise InputError(f"{self.path}: line {line}, column 'id': empty id")
            if value.startswith("#"):
                raise InputError(
                    f"{self.path}: line {line}, column 'id': id {value!r} starts with '#', "
                    "which marks comments; rename it"
                )
            if value in seen:
                raise InputError(
                    f"{self.path}: line {line}, column 'id': id {value!r} repeats line {seen[value]}"
                )
            seen[value] = line


def _physical_lines(fh: IO[str]) -> Iterator[tuple[int, list[str], bool]]:
    """Lines as ``str.splitlines`` gives them, read in chunks.

    Yields ``(number of the first line, lines, whether the chunk has a double quote)``.
    """
    lineno = 1
    rest = ""
    while True:
        chunk = fh.read(_CHUNK_CHARS)
        if not chunk:
            break
        text = rest + chunk
        parts = text.splitlines()
        rest = ""
        if text[-1] == "\r":  # may be the first half of \r\n
            rest = parts.pop() + "\r"
        elif text.splitlines(keepends=True)[-1] == parts[-1]:  # no line break at the end
            rest = parts.pop()
        if parts:
            yield lineno, parts, '"' in text
            lineno += len(parts)
    if rest:
        yield lineno, rest.splitlines(), '"' in rest


class _Scanner:
    """The header and the data records of one CSV file (comments and blank lines skipped)."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = os.fspath(path)
        self.header: tuple[str, ...] | None = None
        self.header_line = 0

    def records(self) -> Iterator[tuple[list[str], list[int]]]:
        """Data lines and their numbers, a chunk of the file at a time."""
        name = self.path
        try:
            with open_input(name, encoding="utf-8-sig") as fh:
                for first, parts, quoted in _physical_lines(fh):
                    if first == 1 and parts[0].startswith(_BOM):
                        parts[0] = parts[0].lstrip(_BOM)
                        warnings.warn(
                            f"{name}: line 1 starts with a second byte order mark (U+FEFF); ignored",
                            InputWarning,
                            stacklevel=4,
                        )
                    if self.header is not None and not quoted:
                        fast = self._plain(first, parts)
                        if fast is not None:
                            yield fast
                            continue
                    yield self._slow(first, parts)
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(f"{name}: cannot read: {exc}") from None
        if self.header is None:
            raise InputError(f"{name}: empty file (no header row)")

    def _plain(self, first: int, parts: list[str]) -> tuple[list[str], list[int]] | None:
        """A chunk of data lines only, without quotes (the common case), or None."""
        assert self.header is not None
        commas = len(self.header) - 1
        if not all(p[:1] not in ("", "#") and not p[0].isspace() and p.count(",") == commas for p in parts):
            return None
        return parts, list(range(first, first + len(parts)))

    def _slow(self, first: int, parts: list[str]) -> tuple[list[str], list[int]]:
        name = self.path
        records, numbers = [], []
        for lineno, line in enumerate(parts, start=first):
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            if self.header is None:
                self._set_header(lineno, line)
                continue
            n = len(_split(name, lineno, line)) if '"' in line else line.count(",") + 1
            if n != len(self.header):
                raise InputError(f"{name}: line {lineno}: {n} fields, but the header has {len(self.header)}")
            records.append(line)
            numbers.append(lineno)
        return records, numbers

    def _set_header(self, lineno: int, line: str) -> None:
        name = self.path
        header = tuple(f.strip() for f in _split(name, lineno, line))
        for k, col in enumerate(header):
            if col == "":
                raise InputError(f"{name}: line {lineno}: column {k + 1} of the header has no name")
            if _BOM in col:
                raise InputError(f"{name}: line {lineno}: column {k + 1} of the header holds a U+FEFF mark")
            if col in header[:k]:
                raise InputError(f"{name}: line {lineno}: column '{col}' appears twice in the header")
        self.header, self.header_line = header, lineno


def read_table(path: str | os.PathLike[str], max_rows: int | None = DEFAULT_MAX_ROWS) -> Table:
    """Read a whole CSV table with a header row (rules in the module docstring).

    Parameters
    ----------
    path : str or path-like
        A regular file.
    max_rows : int or None
        More rows are refused before they are converted (``None``: no limit; ``--max-rows``
        replaces it, :func:`~hexcal.io.inputs.row_limit`)."""
    max_rows = row_limit(max_rows)
    scanner = _Scanner(path)
    records: list[str] = []
    lines: list[int] = []
    for chunk, numbers in scanner.records():
        records.extend(chunk)
        lines.extend(numbers)
        if max_rows is not None and len(records) > max_rows:
            raise too_many_rows(scanner.path, max_rows)
    assert scanner.header is not None
    if not records:
        raise InputError(f"{scanner.path}: the header has no data rows")
    return Table(scanner.path, scanner.header, records, lines)


def iter_tables(path: str | os.PathLike[str], block_rows: int = BLOCK_ROWS) -> Iterator[Table]:
    """The rows of a CSV table in blocks of ``block_rows`` (memory bounded by one block).

    Every block is a :class:`Table` with the same columns; a file without data rows is
    refused (after reading it). Errors name the file and the physical line, as
    :func:`read_table` does.
    """
    if block_rows < 1:
        raise ValueError(f"block_rows must be >= 1, got {block_rows}")
    scanner = _Scanner(path)
    records: list[str] = []
    lines: list[int] = []
    count = 0
    for chunk, numbers in scanner.records():
        records.extend(chunk)
        lines.extend(numbers)
        while len(records) >= block_rows:
            assert scanner.header is not None
            count += block_rows
            yield Table(scanner.path, scanner.header, records[:block_rows], lines[:block_rows])
            records, lines = records[block_rows:], lines[block_rows:]
    assert scanner.header is not None
    if records:
        count += len(records)
        yield Table(scanner.path, scanner.header, records, lines)
    if count == 0:
        raise InputError(f"{scanner.path}: the header has no data rows")


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
            raise InputError(f"{name}: line {lineno}: not a row of numbers: {line.strip()!r}") from None
        if len(values) != shape[1]:
            raise InputError(f"{name}: line {lineno}: {len(values)} numbers, expected {shape[1]}")
        if not all(np.isfinite(v) for v in values):
            raise InputError(f"{name}: line {lineno}: NaN or inf")
        rows.append(values)
    if len(rows) != shape[0]:
        raise InputError(f"{name}: {len(rows)} rows, expected {shape[0]}")
    return np.array(rows)


# writing lives in its own module; these names stay importable from here
from hexcal.io.table_writing import TableWriter, write_table, write_table_blocks  # noqa: E402

__all__ = [
    "BLOCK_ROWS",
    "Table",
    "TableWriter",
    "iter_tables",
    "read_matrix",
    "read_table",
    "write_table",
    "write_table_blocks",
]
