"""Table blocks (data lines as one text) and their fast path: numbers and ids by whole-block calls.

:class:`hexcal.io.tables.Table` converts a block of plain rows here first (issue 20, item 4:
``ik``, ``fk`` and ``compensate`` on 10^6 rows were dominated by reading). One pass over
the block's bytes finds the delimiters and proves that every row has the header's number of
fields; ``np.loadtxt`` converts the cells of the columns wanted at once (its C reader: a
quarter less time than ``np.fromstring`` on a block of pose rows, 10.5 against 13.5 ms for
16,000 rows, and it skips the cells of the other columns); the ids are
gathered into one string and split, and checked as byte arrays. Whatever this path cannot
judge exactly returns None, and the table converts the block the careful way (``np.loadtxt``
with the delimiters counted, then cell by cell), which names the first bad cell: the results,
errors and warnings are the same, only their cost differs.

What ``np.loadtxt`` accepts is a subset of what ``float`` accepts, rounded alike (correctly
rounded, on ASCII text: no ``_``, no non-ASCII digits; a blank field raises); ``nan`` and
``inf`` are read and then sent to the careful path, which refuses them naming the cell.
Tab-delimited files are left to the careful path.
"""

from __future__ import annotations

import io
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray


class TableBlock:
    """Data lines of a table as one text: each row ends with ``\\n`` at ``ends[k]``.

    The text is kept as the scanner read it: ASCII bytes for a chunk of plain rows (decoded only
    if the careful path needs it), or a ``str`` for rows read line by line.
    """

    def __init__(
        self, text: str | bytes, lines: NDArray[np.int64], ends: NDArray[np.int64], checked: bool
    ) -> None:
        self._text, self._raw = (None, text) if isinstance(text, bytes) else (text, None)
        self.lines, self.ends, self.checked = lines, ends, checked

    @property
    def text(self) -> str:
        if self._text is None:
            assert self._raw is not None
            self._text = self._raw.decode("ascii")
        return self._text

    @property
    def raw(self) -> bytes:
        """The text as bytes (UTF-8; the positions ``ends`` are those of the bytes when ASCII)."""
        if self._raw is None:
            assert self._text is not None
            self._raw = self._text.encode("utf-8")
        return self._raw

    @classmethod
    def of(cls, records: Sequence[str], lines: Sequence[int]) -> TableBlock:
        ends = np.cumsum(np.fromiter(map(len, records), np.int64, len(records)) + 1) - 1
        return cls("".join(f"{r}\n" for r in records), np.asarray(lines, np.int64), ends, True)

    def __len__(self) -> int:
        return len(self.lines)

    def cut(self, k: int) -> tuple[TableBlock, TableBlock]:
        at = int(self.ends[k - 1]) + 1
        whole = self._text if self._text is not None else self.raw
        head = TableBlock(whole[:at], self.lines[:k], self.ends[:k], self.checked)
        return head, TableBlock(whole[at:], self.lines[k:], self.ends[k:] - at, self.checked)


#: The first bytes of an id that the careful checks must judge: blank, ``#`` and formula marks.
_ODD_FIRST = np.zeros(256, bool)
_ODD_FIRST[: ord(" ") + 1] = True
_ODD_FIRST[[ord(c) for c in "#=+-@"]] = True


def _cell_bounds(
    data: NDArray[np.uint8], ends: NDArray[np.int64], delimiter: str, width: int
) -> NDArray[np.int64] | None:
    """The delimiters of every row ``(rows, width - 1)``, or None when some row has another count."""
    rows = len(ends)
    cuts = np.flatnonzero(data == ord(delimiter))
    if len(cuts) != rows * (width - 1):
        return None
    cuts = cuts.reshape(rows, width - 1)
    if width > 1:
        starts = np.empty_like(ends)
        starts[0], starts[1:] = 0, ends[:-1] + 1
        # the k-th group of width - 1 delimiters lies inside line k for every k exactly when
        # each line holds width - 1 (the delimiters are sorted and the lines disjoint)
        if not (np.all(cuts[:, 0] >= starts) and np.all(cuts[:, -1] < ends)):
            return None
    return cuts


def _spans(first: NDArray[np.int64], stop: NDArray[np.int64]) -> NDArray[np.intp]:
    """The positions ``first[k] <= p < stop[k]`` of every ``k``, in order (spans in increasing order).

    One running sum: 1 from a position to the next inside a span, the jump to the next span's
    first position at its start (``np.repeat`` of the offsets costs four times more).
    """
    lengths = stop - first
    some = lengths > 0
    if not some.all():
        first, stop, lengths = first[some], stop[some], lengths[some]
    if not len(lengths):
        return np.empty(0, np.intp)
    steps = np.ones(int(lengths.sum()), np.intp)
    jumps = np.empty(len(first), np.intp)
    jumps[0], jumps[1:] = first[0], first[1:] - (stop[:-1] - 1)
    steps[np.cumsum(lengths) - lengths] = jumps
    return np.cumsum(steps, out=steps)


def block_numbers(
    text: bytes, ends: NDArray[np.int64], delimiter: str, width: int, id_column: int | None, wanted: list[int]
) -> tuple[NDArray[np.float64], list[str] | None, bool] | None:
    """The numbers of the columns ``wanted`` ``(rows, len(wanted))``, the id cells and whether
    they are plain, or None when the block needs the careful path.

    ``text`` holds whole rows of ASCII bytes (no quotes, the decimal mark a point), each ended by
    ``\\n`` at ``ends``. The id cells (``id_column``, never wanted) are returned as they are in
    the file; they are *plain* when each is non-empty, without blanks around it, without control
    characters, and starts with neither ``#`` nor a formula mark (``= + - @``): then they need
    no other check than for repeats. ``np.loadtxt`` converts the columns wanted (``usecols``:
    the other cells are not converted).
    """
    if delimiter == "\t" or not len(ends) or not text.isascii() or id_column in wanted:
        return None
    data = np.frombuffer(text, np.uint8)
    cuts = _cell_bounds(data, ends, delimiter, width)
    if cuts is None:
        return None
    starts = np.empty_like(ends)
    starts[0], starts[1:] = 0, ends[:-1] + 1
    ids, plain = None, False
    if id_column is not None:
        first = starts if id_column == 0 else cuts[:, id_column - 1] + 1
        stop = cuts[:, id_column] if id_column < width - 1 else ends
        taken = _spans(first, stop + 1)  # each cell and the byte after it (a delimiter or \n)
        ids = data[taken].tobytes().decode("ascii").split(chr(data[stop[0]]))[:-1]
        if len(ids) != len(ends):  # pragma: no cover - the delimiters were counted
            return None
        inner = data[_spans(first, stop)]
        plain = bool(
            np.all(stop > first)
            and not _ODD_FIRST[data[first]].any()
            and np.all(data[stop - 1] > ord(" "))
            and not np.any((inner < ord(" ")) | (inner > ord("~")))
        )
    if not wanted:
        return np.empty((len(ends), 0)), ids, plain
    # every row has the header's fields (the delimiters counted): numpy's C reader converts
    # only the columns wanted (a quarter faster than np.fromstring of them)
    use = sorted(wanted)
    try:
        values = np.loadtxt(io.BytesIO(text), delimiter=delimiter, usecols=use, dtype=float,
                            comments=None, quotechar=None, ndmin=2)  # fmt: skip
    except ValueError:
        return None
    if values.shape[0] != len(ends) or not np.isfinite(values).all():
        return None
    return (values if use == wanted else values[:, [use.index(k) for k in wanted]]), ids, plain


def loadtxt_numbers(
    text: str, rows: int, delimiter: str, width: int, idx: list[int], checked: bool, id_column: int | None
) -> tuple[NDArray[np.float64], list[str] | None, bool] | None:
    """The columns ``idx`` of a block by ``np.loadtxt``, the id cells (as in the file, never
    plain), or None when it refuses something.

    ``np.loadtxt`` accepts a subset of what ``float`` accepts (no ``_``, no non-ASCII digits)
    and rounds alike. The last column is always read (its text converted to 0 if not asked):
    with the total count of delimiters (unless the rows were ``checked``), that proves every
    row has the header's fields.
    """
    if not checked and text.count(delimiter) != rows * (width - 1):
        return None
    use = sorted({*idx, width - 1})
    converters = {k: (lambda s: 0.0) for k in use if k not in idx} or None  # text, not asked
    try:
        values = np.loadtxt(io.StringIO(text), delimiter=delimiter, usecols=use, converters=converters,
                            dtype=float, comments=None, quotechar=None, ndmin=2)  # fmt: skip
    except ValueError:
        return None
    if values.shape[0] != rows or not np.isfinite(values).all():
        return None
    ids = None
    if id_column is not None:  # the id cells from the lines (cheaper than a converter in loadtxt)
        lines, k = text.split("\n")[:-1], id_column
        ids = (
            [r.partition(delimiter)[0] for r in lines]
            if k == 0
            else [r.split(delimiter, k + 1)[k] for r in lines]
        )
    return values[:, [use.index(k) for k in idx]], ids, False


#: Ids longer than this are left to the set of ids seen.
ORDER_CHARS = 64
#: Ids checked for their order at a time (each part with the last id of the one before).
ORDER_ROWS = 16_384


def strictly_increasing(ids: Sequence[str]) -> bool:
    """Whether ``ids`` are ASCII in strictly increasing order of (length, bytes): then no two
    are equal, and a Python set of them is not needed to prove it.

    Row numbers (``1, 2, ..., 10, ...``), ``p0, p1, ...``, zero-padded counters and time stamps
    are in this order. False says only that this test cannot show the ids distinct (unordered,
    non-ASCII, or longer than :data:`ORDER_CHARS`). Vectorised over the ids; the loop is over
    their 8-byte words, on the pairs of equal length not decided yet.
    """
    if len(ids) > ORDER_ROWS:  # in parts (temporaries of a whole table cost more than a set)
        return all(
            strictly_increasing(ids[max(k - 1, 0) : k + ORDER_ROWS]) for k in range(0, len(ids), ORDER_ROWS)
        )
    if len(ids) < 2:
        return True
    joined = "\n".join(ids)
    if not joined.isascii():
        return False
    data = np.frombuffer(joined.encode("ascii") + b"\n", np.uint8)
    ends = np.flatnonzero(data == 10)
    if len(ends) != len(ids):  # an id with a line break
        return False
    starts = np.empty_like(ends)
    starts[0], starts[1:] = 0, ends[:-1] + 1
    lengths = ends - starts
    if np.any(lengths[1:] < lengths[:-1]) or lengths.max() > ORDER_CHARS:
        return False
    # the ids' bytes, NUL-padded to whole 8-byte words: for ids of one length, the order of
    # their bytes is that of the words read as big-endian integers, word after word
    width = -(-int(lengths.max()) // 8) * 8
    at = starts[:, None] + np.arange(width)
    padded = np.where(np.arange(width) < lengths[:, None], data[np.minimum(at, len(data) - 1)], 0)
    words = np.ascontiguousarray(padded, np.uint8).view(">u8")
    pairs = np.flatnonzero(lengths[1:] == lengths[:-1])  # ids k and k + 1 of the same length
    for j in range(words.shape[1]):
        a, b = words[pairs, j], words[pairs + 1, j]
        if np.any(a > b):
            return False
        pairs = pairs[a == b]
        if not len(pairs):
            return True
    return False  # equal in every word: a repeat
