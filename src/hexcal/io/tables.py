"""CSV tables: the table model behind hexcal's one reader of every table (docs/formats.md "Tables").

A :class:`Table` holds a file's data rows as text, block by block (:class:`TableBlock`),
with their physical line numbers, the file's :class:`Dialect` (delimiter and decimal mark)
and hexcal's names of its columns (a column map renames the file's; messages name the
file's own column). Numbers are converted on demand, all the columns asked together, by
numpy's C parsers on a block's text (:mod:`hexcal.io.table_fast`); a block they refuse is
converted cell by cell, which names the first bad cell in reading order. The rules of every cell:

- the decimal mark is the file's: a comma-separated file has decimal points; otherwise the
  first block whose numbers show a mark decides (``12,5`` against ``12.5``), unless
  ``decimal=`` gives it; a given mark the numbers contradict draws an
  :class:`~hexcal.errors.InputWarning`;
- a number is never guessed: one with both marks (``1.234,5``, ``1,234.5``: a thousands
  separator) or with the other mark than the file's is refused, naming the cell;
- ``nan``, ``inf``, Python's digit separators (``1_0``) and empty cells are refused
  (empty cells are NaN where a value may be missing: lost targets).

Reading files (the scanner: chunks, comments, the header, the unit row, row and field
limits) is :func:`hexcal.io.measurement_files.read_table` / ``iter_tables``; hexcal's
column names and column maps are here (:data:`COLUMN_NAMES`, :func:`check_column_map`).
"""

from __future__ import annotations

import csv
import itertools
import re
import warnings
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from hexcal.errors import InputError, InputWarning, UsageError
from hexcal.instruments.covariates import COVARIATE_COLUMNS
from hexcal.io.table_fast import TableBlock, block_numbers, loadtxt_numbers, strictly_increasing

#: Rows converted (or read, by ``iter_tables``) at a time.
BLOCK_ROWS = 16_384
#: Characters a field may have (the csv module's default limit); longer is refused.
MAX_FIELD_CHARS = 131_072
DELIMITERS = {",": "comma", ";": "semicolon", "\t": "tab"}
#: First characters that make a spreadsheet read a cell as a formula (an id starting with one
#: is refused unless it is a plain number such as ``-1``; tab and CR cannot start a stripped id).
FORMULA_MARKS = "=+-@"
#: The text of a number, with either decimal mark.
NUMBER_TEXT = re.compile(r"^[+-]?(\d+([.,]\d*)?|[.,]\d+)([eE][+-]?\d+)?$")

ORIENTATION_GROUPS = {
    "rad": ("a", "b", "c"),
    "deg": ("a_deg", "b_deg", "c_deg"),
    "quat": ("qx", "qy", "qz", "qw"),
}
LEG_LENGTH_COLUMNS = tuple(f"l{i}" for i in range(1, 7))
LEG_READING_COLUMNS = tuple(f"dl{i}" for i in range(1, 7))
#: hexcal's column names, the keys of a column map (and target columns ``t1.x``, ``t2.y``, ...).
COLUMN_NAMES = ("id", "x", "y", "z", *(c for g in ORIENTATION_GROUPS.values() for c in g))
COLUMN_NAMES += LEG_LENGTH_COLUMNS + LEG_READING_COLUMNS + COVARIATE_COLUMNS
TARGET_COLUMN = re.compile(r"^(t[0-9]+)\.([xyz])$")

#: Words a unit row may hold (brackets and case ignored); only some are accepted per column.
UNIT_WORDS = {"mm", "rad", "deg", "°", "-", "", "1"}
KNOWN_UNITS = UNIT_WORDS | {"m", "cm", "dm", "um", "µm", "μm", "nm", "in", "inch", "ft", "mrad", "urad"}
KNOWN_UNITS |= {"µrad", "degree", "degrees", "grad", "gon", "rev", "revolutions", "turns"}
KNOWN_UNITS |= {"s", "ms", "min", "h", "kg", "g", "lb", "°c", "degc", "celsius", "k", "kelvin", "°f", "degf"}
_LENGTHS = re.compile(r"^(x|y|z|d|d?l[1-6]|t[0-9]+\.[xyz]|payload_[xyz])$")
_UNITS = {  # per column kind: the units accepted, and how to say so
    "temperature": ({"°c", "degc", "celsius", ""}, "°C here"),
    "time": ({"s", ""}, "s here"),
    "mass": ({"kg", ""}, "kg here"),
    "length": ({"mm", ""}, "mm here"),
    "rad": ({"rad", ""}, "rad here (name the columns a_deg, b_deg, c_deg for degrees)"),
    "deg": ({"deg", "°", "degree", "degrees", ""}, "deg here"),
    "none": ({"", "-", "1"}, "no unit here (quaternions)"),
}


def unit_refused(name: str, unit: str) -> str | None:
    """What column ``name`` (hexcal's name) accepts when a unit row gives it ``unit``, or None."""
    kinds = {c: group if group != "quat" else "none" for group, cs in ORIENTATION_GROUPS.items() for c in cs}
    kinds |= {"time": "time", "payload_kg": "mass"} | dict.fromkeys(COVARIATE_COLUMNS[1:8], "temperature")
    kind = "length" if _LENGTHS.match(name) else kinds.get(name)
    if kind is None or unit in _UNITS[kind][0]:
        return None
    return _UNITS[kind][1]


def check_column_map(columns: Mapping[str, str] | None) -> dict[str, str] | None:
    """A column map (hexcal name -> file column) checked: known names, each file column once
    (else a one-line :class:`~hexcal.errors.UsageError`)."""
    if columns is None:
        return None
    seen: dict[str, str] = {}
    for ours, theirs in columns.items():
        if ours not in COLUMN_NAMES and not TARGET_COLUMN.match(str(ours)):
            raise UsageError(
                f"column map: unknown hexcal column {ours!r} (known: {', '.join(COLUMN_NAMES)}, t1.x ...)"
            )
        if not isinstance(theirs, str) or not theirs.strip():
            raise UsageError(f"column map: {ours} needs a file column name, got {theirs!r}")
        if theirs in seen:
            raise UsageError(f"column map: file column {theirs!r} is mapped twice ({seen[theirs]}, {ours})")
        seen[theirs] = ours
    return dict(columns)


def _shown(text: str) -> str:
    """A cell for a message: quoted, and cut to 40 characters."""
    return repr(text) if len(text) <= 40 else f"{text[:40]!r}... ({len(text):,} characters)"


class Dialect:
    """A file's delimiter and decimal mark, shared by its blocks (the first that shows decides)."""

    def __init__(self, path: str, header: str, delimiter: str | None, decimal: str | None) -> None:
        looks = ";" if ";" in header else "\t" if "\t" in header else ","
        if delimiter is not None and delimiter not in DELIMITERS:
            raise InputError(f"delimiter must be one of ',', ';', tab, got {delimiter!r}")
        if decimal is not None and decimal not in (",", "."):
            raise InputError(f"decimal mark must be ',' or '.', got {decimal!r}")
        if delimiter is not None and delimiter not in header:
            raise InputError(
                f"{path}: the delimiter {DELIMITERS[delimiter]} was given (--delimiter), but the header "
                f"holds none; the file looks {DELIMITERS[looks]}-separated: leave --delimiter out"
            )
        if delimiter is not None and delimiter != looks:
            warnings.warn(
                f"{path}: the header looks {DELIMITERS[looks]}-separated, but the file is read "
                f"{DELIMITERS[delimiter]}-separated as asked",
                InputWarning,
                stacklevel=5,
            )
        self.path, self.delimiter, self.asked = path, delimiter or looks, decimal
        if self.delimiter == "," and decimal == ",":
            raise InputError(f"{path}: a comma cannot be both the delimiter and the decimal mark")
        self.decimal: str | None = "." if self.delimiter == "," else None

    def decide(self, text: str, cells: list[list[str]] | None) -> None:
        """Settle the decimal mark from a block's text (and its numeric cells, if both marks show)."""
        if self.decimal is not None or ("," not in text and "." not in text):
            return
        if "." not in text:
            looks = ","
        elif "," not in text:
            looks = "."
        else:
            shapes = [c.strip() for row in cells or [] for c in row if NUMBER_TEXT.match(c.strip())]
            looks = "," if sum("," in c for c in shapes) > sum("." in c for c in shapes) else "."
        self.decimal = self.asked or looks
        if self.decimal != looks:
            warnings.warn(
                f"{self.path}: the numbers look like decimal {'commas' if looks == ',' else 'points'}, but "
                f"they are read with a decimal {'comma' if self.decimal == ',' else 'point'} as asked",
                InputWarning,
                stacklevel=6,
            )


class Table:
    """A parsed CSV table: column names, data rows (kept as text) and their physical line numbers.

    Attributes
    ----------
    path : str
    columns : tuple of str
        hexcal's names of the columns (the file's, renamed by the column map).
    rows : tuple of tuple of str
        The cells, stripped of surrounding blanks (built on first use).
    lines : tuple of int
        Physical line number (from 1) of each row.
    """

    def __init__(
        self, path: str, columns: tuple[str, ...], records: Sequence[str], lines: Sequence[int]
    ) -> None:
        self.path, self.columns = path, tuple(columns)
        self._labels = dict(zip(self.columns, self.columns, strict=True))
        self._dialect = Dialect(path, ",", ",", None)
        self._blocks = [TableBlock.of(records, lines)] if len(records) else []
        self._numbers: dict[str, NDArray[np.float64]] = {}
        self._whole: dict[tuple[str, ...], NDArray[np.float64]] = {}  # the columns converted together
        self._id_cells: list[str] | None = None
        self._plain_ids = False  # the id cells are stripped and need only the check for repeats

    @classmethod
    def of_blocks(cls, path: str, columns: tuple[str, ...], labels: tuple[str, ...], dialect: Dialect,
            blocks: list[TableBlock]) -> Table:  # fmt: skip
        table = cls(path, columns, [], [])
        table._labels = dict(zip(columns, labels, strict=True))
        table._dialect, table._blocks = dialect, blocks
        return table

    def __len__(self) -> int:
        return sum(len(b) for b in self._blocks)

    @property
    def lines(self) -> tuple[int, ...]:
        return tuple(np.concatenate([b.lines for b in self._blocks]).tolist()) if self._blocks else ()

    @property
    def rows(self) -> tuple[tuple[str, ...], ...]:
        return tuple(tuple(f.strip() for f in row) for b in self._blocks for row in self._cells(b))

    def line(self, k: int) -> int:
        """Physical line number of row ``k``."""
        for block in self._blocks:
            if k < len(block):
                return int(block.lines[k])
            k -= len(block)
        raise IndexError(k)

    def has(self, name: str) -> bool:
        return name in self.columns

    def label(self, name: str) -> str:
        """The file's own name of column ``name`` (the name itself without a column map)."""
        return self._labels.get(name, name)

    def _cells(self, block: TableBlock) -> list[list[str]]:
        """The fields of every row of a block (field counts checked, the first wrong one named)."""
        d, width = self._dialect.delimiter, len(self.columns)
        rows = block.text.split("\n")[:-1]
        if '"' in block.text:
            fields = [split_fields(self.path, int(n), r, d) for r, n in zip(rows, block.lines, strict=True)]
        else:
            fields = [r.split(d) for r in rows]
        if not block.checked:
            for row, n in zip(fields, block.lines, strict=True):
                if len(row) != width:
                    raise field_count_error(self.path, int(n), row, width, d)
            block.checked = True
        return fields

    def unmapped_hint(self) -> str:
        """``""``, or when none of the columns has one of hexcal's names, a hint to map them."""
        if any(c in COLUMN_NAMES or TARGET_COLUMN.match(c) for c in self.columns):
            return ""
        shown = ", ".join(self.label(c) for c in self.columns[:3]) + (" ..." if len(self.columns) > 3 else "")
        where = "--columns, or columns: in the setup"
        return f"; none of the file's columns ({shown}) is a hexcal name: map them ({where})"

    def numbers(self, names: Sequence[str], empty: bool = False) -> NDArray[np.float64]:
        """Numeric values of the named columns, shape ``(rows, len(names))``.

        Columns are converted once (a block of rows at a time, all the columns asked together)
        and kept; ask for every column needed in one call. With ``empty``, an empty cell is
        NaN (a value not measured) instead of an error.
        """
        for name in names:
            if name not in self.columns:
                label = self.label(name)
                extra = f" (the column map's {name})" if label != name else self.unmapped_hint()
                raise InputError(f"{self.path}: missing column '{label}'{extra}")
        todo = [n for n in dict.fromkeys(names) if n not in self._numbers]
        if todo:
            self._convert(todo, empty)
        if not names:
            return np.empty((len(self), 0))
        whole = self._whole.get(tuple(names))
        if whole is not None:  # the columns as converted together: one copy of contiguous memory
            return whole.copy()
        return np.column_stack([self._numbers[n] for n in names])

    def _convert(self, names: list[str], empty: bool) -> None:
        idx = [self.columns.index(n) for n in names]
        want_ids = "id" in self.columns and self._id_cells is None
        id_cells: list[str] = []
        parts, plain = [], [True]
        for block in self._blocks:
            both = self._dialect.decimal is None and "," in block.text and "." in block.text
            cells = self._cells(block) if both else None
            if self._dialect.decimal is None:  # (then the text is not needed)
                self._dialect.decide(
                    block.text, None if cells is None else [[r[k] for k in idx] for r in cells]
                )
            fast = None if empty else self._fast(block, idx, id_cells if want_ids else None, plain)
            if fast is None:
                plain[0] = False
                cells = self._cells(block) if cells is None else cells
                fast = np.column_stack(
                    [self._column([r[k] for r in cells], block, names[c], empty) for c, k in enumerate(idx)]
                )
                if want_ids:
                    id_cells.extend(r[self.columns.index("id")] for r in cells)
            parts.append(fast)
        out = np.concatenate(parts) if parts else np.empty((0, len(names)))
        for c, name in enumerate(names):
            self._numbers[name] = out[:, c]  # views of one array (no copies of a whole table)
        self._whole[tuple(names)] = out
        if want_ids:
            self._id_cells, self._plain_ids = id_cells, plain[0]

    def _fast(
        self, block: TableBlock, idx: list[int], ids: list[str] | None, plain: list[bool]
    ) -> NDArray[np.float64] | None:
        """The block's numbers by numpy's C parsers (:mod:`hexcal.io.table_fast`: ``np.fromstring``
        of the whole block, else ``np.loadtxt``), or None (they refused something, or cannot judge)."""
        raw, d, width = block.raw, self._dialect.delimiter, len(self.columns)
        if b'"' in raw or (self._dialect.decimal == "," and b"." in raw):
            return None
        comma = self._dialect.decimal == ","
        kid = self.columns.index("id") if "id" in self.columns else None
        got = block_numbers(raw.replace(b",", b".") if comma else raw, block.ends, d, width, kid, idx)
        if got is not None:  # the numbers and ids at once
            values, cells, plain_cells = got
        else:
            text = block.text.replace(",", ".") if comma else block.text
            got = loadtxt_numbers(text, len(block), d, width, idx, block.checked, kid)
            if got is None:
                return None
            values, cells, plain_cells = got
        block.checked = True
        if ids is not None and cells is not None:
            ids.extend(cells)
            plain[0] = plain[0] and plain_cells
        return values

    def _column(self, cells: list[str], block: TableBlock, name: str, empty: bool) -> NDArray[np.float64]:
        """One column converted cell by cell (numpy on the texts; on failure the first bad cell named)."""
        cells = [c.strip() for c in cells]
        mark = self._dialect.decimal or "."
        joined = "\x1f".join(cells)
        if "_" not in joined and (mark == "," or "," not in joined) and (mark == "." or "." not in joined):
            texts = [c.replace(",", ".") for c in cells] if mark == "," else cells
            blank = np.array([c == "" for c in cells]) if empty else np.zeros(len(cells), bool)
            try:
                values = np.array(["0" if b else t for t, b in zip(texts, blank, strict=True)], dtype=float)
                values[blank] = np.nan
                if np.all(np.isfinite(values) | blank):
                    return values
            except ValueError:
                pass
        for text, line in zip(cells, block.lines, strict=True):
            if not (empty and text == ""):
                self._cell(text, int(line), name, mark)
        raise AssertionError("a cell was refused by numpy but not here")  # pragma: no cover

    def _cell(self, text: str, line: int, name: str, mark: str) -> float:
        where = f"{self.path}: line {line}, column '{self.label(name)}'"
        if "," in text and "." in text:
            raise InputError(f"{where}: {_shown(text)} has a thousands separator; remove it")
        other = "," if mark == "." else "."
        if other in text and NUMBER_TEXT.match(text):
            if other == ",":
                raise InputError(
                    f"{where}: {_shown(text)} has a decimal comma, but the numbers of this file "
                    "have decimal points (decimal=',', --decimal ',', reads decimal commas)"
                )
            raise InputError(
                f"{where}: {_shown(text)} has a point, but the numbers of this file have "
                "decimal commas (a thousands separator? remove it; decimal='.' reads points)"
            )
        try:
            if "_" in text:
                raise ValueError(text)
            value = float(text.replace(",", ".") if mark == "," else text)
        except ValueError:
            raise InputError(f"{where}: not a number: {_shown(text)}") from None
        if not np.isfinite(value):
            raise InputError(f"{where}: {text if len(text) <= 40 else _shown(text)} is not a finite number")
        return value

    def cells(self, name: str) -> list[str]:
        """The text of column ``name``, cell by cell, stripped of surrounding blanks."""
        if name == "id" and self._id_cells is not None:
            return list(map(str.strip, self._id_cells))
        k = self.columns.index(name)
        return [row[k].strip() for b in self._blocks for row in self._cells(b)]

    def ids(
        self, seen: dict[str, int] | None = None, first: int = 1, repeats: bool = True
    ) -> tuple[str, ...]:
        """The ``id`` column, or the row numbers ``first, first + 1, ...`` when there is none.

        ``seen`` (id -> line) carries ids of earlier rows of the same file, refused here;
        ``repeats=False`` leaves the repeats inside the table to the caller (every other check made).
        """
        if "id" not in self.columns:
            return tuple(str(first + k) for k in range(len(self)))
        plain = self._plain_ids and self._id_cells is not None  # checked as bytes while read
        ids = self._id_cells if plain and self._id_cells is not None else self.cells("id")
        if plain and seen is None and not repeats:
            return tuple(ids)
        # ids in strictly increasing order are distinct: no set of them needed (10^6 ids: 0.1 s)
        repeated = (not strictly_increasing(ids) and len(set(ids)) != len(ids)) or (
            seen is not None and not seen.keys().isdisjoint(ids)
        )
        joined = "" if plain else "\n" + "\n".join(ids)
        formula = any(f"\n{mark}" in joined for mark in FORMULA_MARKS)
        odd = not plain and ("" in ids or "\n#" in joined or formula or not "".join(ids).isprintable())
        if repeated or odd:
            self._id_error(ids, dict(seen or {}))
        if seen is not None:
            seen.update(zip(ids, self.lines, strict=True))
        return tuple(ids)

    def _id_error(self, ids: list[str], seen: dict[str, int]) -> None:
        """Raise the error of the first bad id, in reading order."""
        where = f"column '{self.label('id')}'"
        for k, value in enumerate(ids):
            line = self.line(k)
            if value == "":
                raise InputError(f"{self.path}: line {line}, {where}: empty id")
            if value.startswith("#"):
                raise InputError(
                    f"{self.path}: line {line}, {where}: id {_shown(value)} starts with '#', "
                    "which marks comments; rename it"
                )
            if not value.isprintable():
                raise InputError(
                    f"{self.path}: line {line}, {where}: id {_shown(value)} holds a control or "
                    "line-separator character; ids are written into other files: rename it"
                )
            if value[0] in FORMULA_MARKS and not NUMBER_TEXT.match(value):
                raise InputError(
                    f"{self.path}: line {line}, {where}: id {_shown(value)} starts with "
                    f"{value[0]!r}, which a spreadsheet opening hexcal's tables runs as a formula; rename it"
                )
            if value in seen:
                raise InputError(
                    f"{self.path}: line {line}, {where}: id {_shown(value)} repeats line {seen[value]}"
                )
            seen[value] = line


def split_fields(path: str, lineno: int, line: str, delimiter: str) -> list[str]:
    """The fields of one line (the csv module only when the line has quotes)."""
    if '"' not in line:
        return line.split(delimiter)
    try:
        return next(csv.reader([line], delimiter=delimiter))
    except csv.Error as exc:
        if "field limit" in str(exc):
            raise InputError(f"{path}: line {lineno}: a field over {MAX_FIELD_CHARS:,} characters") from None
        raise InputError(f"{path}: line {lineno}: cannot read the fields ({exc})") from None


def field_count_error(path: str, lineno: int, row: list[str], width: int, delimiter: str) -> InputError:
    hint = ""
    if (
        delimiter == ","
        and len(row) > width
        and any(
            re.match(r"^[+-]?\d*$", x.strip()) and re.match(r"^\d+([.eE]\S*)?$", y.strip())
            for x, y in itertools.pairwise(row)
        )
    ):
        hint = " (decimal commas in a comma-separated file, or thousands separators? export with ';')"
    return InputError(f"{path}: line {lineno}: {len(row)} fields, but the header has {width}{hint}")
