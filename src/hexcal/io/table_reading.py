"""Reading table files: the one reader of every table hexcal reads.

:func:`read_table` and :func:`iter_tables` read every table hexcal reads (docs/formats.md
"Tables"; * marks extensions); :mod:`hexcal.io.tables` holds the rows and converts the numbers. One
line is one record; blank lines and ``#`` comments (before the header and, *, after it) are
skipped, and one (*, or two) UTF-8 byte order marks. The delimiter is ``;`` if the header
holds one, else a tab if it holds one, else ``,`` (or ``delimiter=``); the decimal mark is
detected or given (``decimal=``). A unit row right under the header (``mm``, ``[mm]``, ``(rad)``,
``deg``...) needs a cell for every column and is skipped: lengths (``x y z``, ``l1..l6``,
``dl1..dl6``, ``t1.x``, ``payload_x``...) in mm, ``a b c`` in rad, ``a_deg b_deg c_deg`` in deg,
quaternions without unit, ``time`` in s, temperatures in °C, ``payload_kg`` in kg. A field
over :data:`~hexcal.io.tables.MAX_FIELD_CHARS` characters and more than ``max_rows`` rows
(``--max-rows``) are refused at once, while reading. ``columns=`` maps
hexcal's column names to the file's (``{"x": "position_x"}``). Chunks of plain rows (no
quotes, comments, blank or indented lines, non-ASCII text) are kept as they are, checked by
the number parser; others are read line by line. Every file kind takes the same options.
"""

from __future__ import annotations

import os
import re
import warnings
from collections.abc import Iterator, Mapping

import numpy as np

from hexcal.errors import InputError, InputWarning
from hexcal.io import tables
from hexcal.io.inputs import DEFAULT_MAX_ROWS, open_input, row_limit, too_many_rows
from hexcal.io.tables import BLOCK_ROWS, Table

Path = str | os.PathLike[str]
Columns = Mapping[str, str] | None
#: Characters a line may have before its line break (bounds the memory of one line).
MAX_LINE_CHARS = 1 << 24
_CHUNK_BYTES = 1 << 22
_BOM = "\ufeff"


_LINE_BREAK = re.compile(r"\r\n|\r|\n")
_BYTE_BREAK = re.compile(rb"\r\n|\r|\n")


def _lines(text: str) -> list[str]:
    """The lines of ``text``, broken only at CR, LF and CRLF: a Unicode line separator (U+2028,
    U+0085...) inside a field stays in it (and is refused there, or read as the text it is)."""
    parts = _LINE_BREAK.split(text)
    return parts[:-1] if parts and parts[-1] == "" else parts


class _Scanner:
    """The header, the unit row and the data blocks of one CSV file, a chunk at a time."""

    def __init__(self, path: Path, delimiter: str | None, decimal: str | None, columns: Columns) -> None:
        self.path = os.fspath(path)
        self.asked, self.map = (delimiter, decimal), tables.check_column_map(columns) or {}
        self.header: tuple[str, ...] | None = None  # the file's names
        self.names: tuple[str, ...] = ()  # hexcal's names
        self.dialect: tables.Dialect | None = None
        self.units_next = True

    def table(self, blocks: list[tables.TableBlock]) -> Table:
        assert self.header is not None and self.dialect is not None
        return Table.of_blocks(self.path, self.names, self.header, self.dialect, blocks)

    def blocks(self) -> Iterator[tables.TableBlock]:
        """Data blocks in reading order (a chunk of plain rows, or the data lines of an irregular one)."""
        name, lineno, rest = self.path, 1, b""
        with open_input(name) as fh:
            raw = fh.buffer
            try:
                while True:
                    data = raw.read(_CHUNK_BYTES)
                    if lineno == 1 and not rest and data.startswith(b"\xef\xbb\xbf"):
                        data = data[3:]
                        if data.startswith(b"\xef\xbb\xbf"):
                            data = data[3:]
                            warnings.warn(
                                f"{name}: line 1 starts with a second byte order mark (U+FEFF); ignored",
                                InputWarning,
                                stacklevel=4,
                            )
                    if not data:
                        break
                    # the last line break of the chunk (a CR at its end may be half a CRLF)
                    cut = max(data.rfind(b"\n"), data.rfind(b"\r", 0, len(data) - 1)) + 1
                    if cut:  # the piece in one copy (rest + data, then a slice of it, were two)
                        piece, rest = b"".join((rest, memoryview(data)[:cut])), data[cut:]
                    else:
                        buf = rest + data
                        cut = max(buf.rfind(b"\n"), buf.rfind(b"\r", 0, len(buf) - 1)) + 1
                        if cut == 0:  # no whole line yet
                            rest = buf
                            if len(rest) > MAX_LINE_CHARS:
                                raise InputError(f"{name}: line {lineno}: over {MAX_LINE_CHARS:,} characters")
                            continue
                        piece, rest = buf[:cut], buf[cut:]
                    found, count = self._piece(lineno, piece)
                    lineno += count
                    yield from (block for block in found if len(block))
            except OSError as exc:
                raise InputError(f"{name}: cannot read: {exc}") from None
        if rest:
            found, _ = self._piece(lineno, rest)
            yield from (block for block in found if len(block))
        if self.header is None:
            raise InputError(f"{name}: empty file (no header row)")

    def _piece(self, lineno: int, piece: bytes) -> tuple[list[tables.TableBlock], int]:
        """The data rows of whole lines ``piece`` (from line ``lineno``) and its number of lines.

        The lines up to the first data line (comments, the header, the unit row) are read one
        at a time, so that the rest of the first chunk can be a block of plain rows too.
        """
        if self.header is not None and not self.units_next:
            block, count = self._rows(lineno, piece)
            return [block], count
        at = count = 0
        heads = []
        while at < len(piece) and (self.header is None or self.units_next):
            found = _BYTE_BREAK.search(piece, at)
            after = found.end() if found else len(piece)
            head, n = self._rows(lineno + count, piece[at:after])
            heads.append(head)
            at, count = after, count + n
        block, n = self._rows(lineno + count, piece[at:])
        return [*heads, block], count + n

    def _rows(self, lineno: int, piece: bytes) -> tuple[tables.TableBlock, int]:
        """The data rows of whole lines ``piece`` (from line ``lineno``) and its number of lines."""
        plain = piece[-1:] == b"\n" and piece.isascii() and b'"' not in piece and b"#" not in piece
        if plain and self.header is not None and not self.units_next and len(self.header) > 1:
            cr = piece.count(b"\r") if b"\r" in piece else 0
            if not cr or cr == piece.count(b"\r\n"):
                data = np.frombuffer(piece, np.uint8)
                ends = np.flatnonzero(data == 10)
                # no blank line, none led by a blank or a control character (read line by line,
                # they would be skipped or stripped)
                firsts = data[np.concatenate([[0], ends[:-1] + 1])]
                longest = np.diff(ends, prepend=-1).max()
                if np.all(firsts > 32) and longest <= tables.MAX_FIELD_CHARS:
                    lines = np.arange(lineno, lineno + len(ends), dtype=np.int64)
                    return tables.TableBlock(piece, lines, ends, False), len(ends)
        try:
            parts = _lines(piece.decode("utf-8"))
        except UnicodeDecodeError as exc:
            raise InputError(f"{self.path}: line {lineno} or after: cannot read: {exc}") from None
        records, numbers = [], []
        for k, line in enumerate(parts, start=lineno):
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            if self.header is None:
                self._set_header(k, line)
                continue
            if not self._checked(k, line):  # the unit row
                continue
            records.append(line)
            numbers.append(k)
        return tables.TableBlock.of(records, numbers), len(parts)

    def _checked(self, lineno: int, line: str) -> list[str]:
        """The fields of a data line (or of the unit row): their number and lengths checked."""
        assert self.header is not None and self.dialect is not None
        fields = tables.split_fields(self.path, lineno, line, self.dialect.delimiter)
        if len(line) > tables.MAX_FIELD_CHARS:
            for k, field in enumerate(fields):
                if len(field) > tables.MAX_FIELD_CHARS:
                    col = f"column '{self.header[k]}'" if k < len(self.header) else f"field {k + 1}"
                    raise InputError(
                        f"{self.path}: line {lineno}, {col}: a field of {len(field):,} "
                        f"characters, over the limit of {tables.MAX_FIELD_CHARS:,}"
                    )
        units, self.units_next = self.units_next and self._unit_row(lineno, fields), False
        if len(fields) != len(self.header):
            width, delimiter = len(self.header), self.dialect.delimiter
            if units:
                raise InputError(
                    f"{self.path}: line {lineno}: the unit row has {len(fields)} fields, but "
                    f"the header has {width}; give a unit (or none) for every column"
                )
            raise tables.field_count_error(self.path, lineno, fields, width, delimiter)
        return [] if units else fields

    def _set_header(self, lineno: int, line: str) -> None:
        name = self.path
        if len(line) > tables.MAX_FIELD_CHARS:
            raise InputError(f"{name}: line {lineno}: a header of {len(line):,} characters, over the limit")
        self.dialect = tables.Dialect(name, line, *self.asked)
        header = tuple(f.strip() for f in tables.split_fields(name, lineno, line, self.dialect.delimiter))
        for k, col in enumerate(header):
            if col == "":
                raise InputError(f"{name}: line {lineno}: column {k + 1} of the header has no name")
            if _BOM in col:
                raise InputError(f"{name}: line {lineno}: column {k + 1} of the header holds a U+FEFF mark")
            if col in header[:k]:
                raise InputError(f"{name}: line {lineno}: column '{col}' appears twice in the header")
        given = {file: ours for ours, file in self.map.items()}
        for ours, file in self.map.items():
            if file not in header:
                raise InputError(f"{name}: line {lineno}: no column '{file}' (the column map's {ours})")
            if ours in header and ours != file:
                raise InputError(
                    f"{name}: line {lineno}: columns '{ours}' and '{file}' would both be {ours} "
                    f"(the column map gives {ours}={file}); map only one"
                )
        self.header, self.names = header, tuple(given.get(c, c) for c in header)

    def _unit_row(self, lineno: int, cells: list[str]) -> bool:
        """Whether the first data line is a unit row (its units checked here), or data."""
        units = [c.strip().strip("[]()").strip().lower() for c in cells]
        if not any(u in tables.KNOWN_UNITS - {"", "-", "1"} for u in units):
            return False
        if not all(u in tables.KNOWN_UNITS or not tables.NUMBER_TEXT.match(u) for u in units):
            return False
        for ours, col, unit, cell in zip(self.names, self.header or (), units, cells, strict=False):
            accepted = tables.unit_refused(ours, unit)
            if accepted is not None:
                where = f"{self.path}: line {lineno}, column '{col}'"
                raise InputError(f"{where}: unit {cell.strip()!r}; only {accepted}")
        return True


def read_table(
    path: Path,
    max_rows: int | None = DEFAULT_MAX_ROWS,
    delimiter: str | None = None,
    decimal: str | None = None,
    columns: Columns = None,
) -> Table:
    """Read a whole CSV table with a header row (rules in the module docstring).

    ``max_rows``: more rows are refused while reading (``None``: no limit; ``--max-rows``
    replaces it, :func:`~hexcal.io.inputs.row_limit`). ``delimiter`` (``","``, ``";"``,
    ``"\\t"``) and ``decimal`` (``"."``, ``","``) are detected when not given. ``columns``:
    hexcal's column name -> the file's (:func:`~hexcal.io.target_files.parse_column_map`).
    """
    max_rows = row_limit(max_rows)
    scanner = _Scanner(path, delimiter, decimal, columns)
    blocks, count = [], 0
    for block in scanner.blocks():
        blocks.append(block)
        count += len(block)
        if max_rows is not None and count > max_rows:
            raise too_many_rows(scanner.path, max_rows)
    if not count:
        raise InputError(f"{scanner.path}: the header has no data rows")
    return scanner.table(blocks)


def iter_tables(
    path: Path,
    block_rows: int = BLOCK_ROWS,
    delimiter: str | None = None,
    decimal: str | None = None,
    columns: Columns = None,
) -> Iterator[Table]:
    """The rows of a CSV table in blocks of ``block_rows`` (memory bounded by one block).

    Every block is a :class:`Table` with the same columns; a file without data rows is
    refused (after reading it). Errors and options are those of :func:`read_table`.
    """
    if block_rows < 1:
        raise ValueError(f"block_rows must be >= 1, got {block_rows}")
    scanner = _Scanner(path, delimiter, decimal, columns)
    pending: list[tables.TableBlock] = []
    have = count = 0
    for block in scanner.blocks():
        pending.append(block)
        have += len(block)
        while have >= block_rows:
            taken, need = [], block_rows
            while need:
                head = pending.pop(0)
                if len(head) > need:
                    head, tail = head.cut(need)
                    pending.insert(0, tail)
                taken.append(head)
                need -= len(head)
            have, count = have - block_rows, count + block_rows
            yield scanner.table(taken)
    if have:
        count += have
        yield scanner.table(pending)
    if count == 0:
        raise InputError(f"{scanner.path}: the header has no data rows")
