"""Writing CSV tables, whole or block by block, through the command's output set; pose, leg
and measurement files.

A table with no rows, or with a NaN or infinity, is refused before anything is written,
because hexcal could not read it back; so is an id that is empty, starts with ``#`` or holds
a line break. Numbers are written with 15 significant digits, exactly as ``format(v,
".15g")`` writes them; cells with commas or quotes are quoted as the csv module does.

The numbers are formatted by numpy, a few thousand rows at a time, without a Python call
per number (issue 20: ``%``-formatting 12 numbers a row was most of ``ik``'s time): each
value's 15 significant digits come from the exact product of the value and a power of ten
(Dekker's error-free product, so the rounding is the correctly rounded one), its characters
are laid out in a fixed slot of :data:`SLOT` bytes by masks that depend only on its sign,
exponent and last significant digit, and the unused bytes of the slots are dropped at the
end. Values whose exponent is outside ``[-8, 14]``, and exact ties, are formatted by Python.
"""

from __future__ import annotations

import io
import os
from collections.abc import Iterable, Sequence
from typing import IO

import numpy as np
from numpy.typing import NDArray

from hexcal.core.text import printable
from hexcal.instruments.covariates import Covariates
from hexcal.instruments.pose import Measurements
from hexcal.io.files import atomic_write
from hexcal.io.outputs import OutputError, OutputSet
from hexcal.io.tables import (
    FORMULA_MARKS,
    LEG_LENGTH_COLUMNS,
    LEG_READING_COLUMNS,
    NUMBER_TEXT,
    ORIENTATION_GROUPS,
)

#: Bytes of one value's slot, in 4-byte words: separator and sign; "0" and the 15 digits; the
#: point and the zeros of ``0.000d``; the 15 digits again; the exponent (``e-05``). NUL bytes
#: are dropped when written; a block keeps only the words its values use.
SLOT = 44

#: Rows formatted at a time (temporaries of ``SLOT`` bytes per value stay in the cache).
FORMAT_ROWS = 1024
#: Rows whose ids are checked and laid out as bytes at a time.
IDS_ROWS = 16 * FORMAT_ROWS

_E_MIN, _E_MAX = -8, 14  # decimal exponents formatted by numpy (10**(14 - e) is exact)
_POW = 10.0 ** np.arange(_E_MAX - _E_MIN + 1)
_CODES = 2 * (_E_MAX - _E_MIN + 1) * 15  # sign x exponent x last significant digit
_ZERO, _EMPTY, _PYTHON = _CODES, _CODES + 2, _CODES + 3  # zero, -0; an empty cell; by Python
_DIGITS4 = np.frombuffer("".join(f"{k:04d}" for k in range(10_000)).encode(), dtype=np.uint32)
_ZEROS4 = np.array([4] + [len(s) - len(s.rstrip("0")) for s in (f"{k:04d}" for k in range(1, 10_000))])
_SIGN, _FIRST, _POINT, _SECOND, _EXPONENT = 3, 4, 20, 24, 40  # byte offsets in the slot


def _layouts() -> tuple[NDArray[np.uint32], NDArray[np.uint32]]:
    """Per code, the mask of the digit bytes kept and the constant bytes, as 4-byte words.

    A value keeps its integer digits from the first copy of the digits and its fraction
    digits from the second, so that the point and the zeros of ``0.00d`` never move.
    """
    keep = np.zeros((_CODES + 4, SLOT), np.uint8)
    const = np.zeros((_CODES + 4, SLOT), np.uint8)
    for neg in (0, 1):
        const[_ZERO + neg, _SIGN] = ord("-") if neg else 0
        const[_ZERO + neg, _FIRST] = ord("0")
        for e in range(_E_MIN, _E_MAX + 1):
            for last in range(15):
                code = (neg * (_E_MAX - _E_MIN + 1) + e - _E_MIN) * 15 + last
                const[code, _SIGN] = ord("-") if neg else 0
                if -4 <= e < 0:  # 0.000ddd: the "0" of the first copy, then the digits of the second
                    keep[code, _FIRST] = 255
                    const[code, _POINT : _POINT + 1 - e - 1] = np.frombuffer(b".000"[:-e], np.uint8)
                    keep[code, _SECOND + 1 : _SECOND + 2 + last] = 255
                    continue
                whole = max(e, 0) if e >= -4 else 0  # index of the last integer digit
                keep[code, _FIRST + 1 : _FIRST + 2 + whole] = 255
                if last > whole:
                    const[code, _POINT] = ord(".")
                    keep[code, _SECOND + 2 + whole : _SECOND + 2 + last] = 255
                if e < -4:  # scientific notation: d.ddde-0X
                    const[code, _EXPONENT : _EXPONENT + 4] = np.frombuffer(f"e-{-e:02d}".encode(), np.uint8)
    return keep.view(np.uint32), const.view(np.uint32)


_KEEP, _CONST = _layouts()
_TABLES: dict[tuple[int, ...], tuple[NDArray[np.uint32], NDArray[np.uint32]]] = {}


def _tables(words: tuple[int, ...]) -> tuple[NDArray[np.uint32], NDArray[np.uint32]]:
    """The masks and constants of the words a block uses (contiguous, kept for the next block)."""
    if words not in _TABLES:
        _TABLES[words] = (np.ascontiguousarray(_KEEP[:, words]), np.ascontiguousarray(_CONST[:, words]))
    return _TABLES[words]


def _split(x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Veltkamp's split: ``x = hi + lo`` exactly, each with at most 26 significant bits."""
    c = 134217729.0 * x
    hi = c - (c - x)
    return hi, x - hi


_POW_HI, _POW_LO = _split(_POW)


def _round_scaled(
    a: NDArray[np.float64], k: NDArray[np.intp]
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """``a * 10**k`` rounded to the nearest integer, exactly; and where it is an exact tie."""
    p = a * _POW[k]
    r = np.rint(p)
    f = p - r  # exact
    near = np.flatnonzero(np.abs(f) > 0.4375)  # elsewhere the product's error (< 1/16) cannot matter
    tie = np.zeros(a.shape, bool)
    if near.size:
        an, kn, pn = a[near], k[near], p[near]
        hi, lo = _split(an)
        err = ((hi * _POW_HI[kn] - pn) + hi * _POW_LO[kn] + lo * _POW_HI[kn]) + lo * _POW_LO[kn]
        d = f[near] + err  # the exact product is r + d (d's rounding cannot cross +-0.5)
        r[near] += (d > 0.5).astype(float) - (d < -0.5)
        tie[near] = np.abs(d) == 0.5
    return r, tie


def _significand(
    a: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.bool_]]:
    """15 significant digits ``10**14 <= m < 10**15`` and exponent ``e`` of ``a > 0``, and where
    numpy cannot format (exponent out of range, an exact tie)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        e = np.floor(np.log10(a))
    bad = np.zeros(a.shape, bool)
    if not (e.min() >= _E_MIN and e.max() <= _E_MAX):
        bad = ~((e >= _E_MIN) & (e <= _E_MAX))
        e[bad] = 0
        a = np.where(bad, 1.0, a)
    e = e.astype(np.int64)
    m, tie = _round_scaled(a, (14 - e).astype(np.intp))
    if not (m.min() >= 1e14 and m.max() < 1e15):  # log10 one off at a power of ten
        off = np.flatnonzero(~bad & ((m >= 1e15) | (m < 1e14)))
        e[off] += np.where(m[off] >= 1e15, 1, -1)
        bad[off] |= (e[off] < _E_MIN) | (e[off] > _E_MAX)
        m[off], tie[off] = _round_scaled(a[off], np.clip(14 - e[off], 0, _E_MAX - _E_MIN))
        top = m == 1e15  # rounded up to the next power of ten
        m[top] = 1e14
        e[top] += 1
        bad |= e > _E_MAX
    return m, e, bad | tie


def _words(e: NDArray[np.int64], last: NDArray[np.int64], python: bool) -> tuple[int, ...]:
    """The words of the slot that some value of the block may use (all when Python formats some)."""
    if python:
        return tuple(range(SLOT // 4))
    low, high = int(e.min()), int(e.max())
    first = tuple(range(1, 2 + (1 + max(high, 0)) // 4))  # "0" and the integer digits
    second = tuple(range(6 + (1 + (0 if low < 0 else low + 1)) // 4, 7 + (1 + int(last.max())) // 4))
    return (0, *first, 5, *second) + ((10,) if low < -4 else ())


def format_values(values: NDArray[np.float64], missing: bool = False) -> NDArray[np.uint8]:
    """The text of finite ``values`` (NaN: an empty cell when ``missing``) as ``(n, width)`` bytes.

    Each row, once its NUL bytes are dropped, is ``format(v, ".15g")``; its byte 0 is left
    (NUL) for a separator. ``width`` (at most :data:`SLOT`) is what the values need.
    """
    v = np.ascontiguousarray(values, dtype=float).ravel()
    a = np.abs(v)
    zero = ~(a > 0)  # and NaN
    m, e, python = _significand(np.where(zero, 1.0, a) if zero.any() else a)
    hi = np.floor(m / 1e8)
    lo = m - hi * 1e8
    g0, g2 = np.floor(hi / 1e4), np.floor(lo / 1e4)
    groups = np.empty((4, v.size), np.intp)  # the digits in groups of four
    groups[0], groups[1], groups[2], groups[3] = g0, hi - g0 * 1e4, g2, lo - g2 * 1e4
    chars = np.take(_DIGITS4, groups)  # "0" and the 15 digits, four to a word
    zeros = np.take(_ZEROS4, groups[3])
    for k in (2, 1, 0):  # trailing zeros beyond the last group of four
        more = np.flatnonzero(zeros == 4 * (3 - k))
        if not more.size:
            break
        zeros[more] += np.take(_ZEROS4, groups[k, more])
    last = 14 - np.minimum(zeros, 14)
    code = (np.signbit(v) * (_E_MAX - _E_MIN + 1) + (e - _E_MIN)) * 15 + last
    if zero.any():
        code[zero] = _ZERO + np.signbit(v[zero])
        code[np.isnan(v) if missing else ~np.isfinite(v)] = _EMPTY
    some_python = bool(python.any())
    code[python] = _PYTHON
    words = _words(e, last, some_python)
    out = np.empty((v.size, len(words)), np.uint32)
    for k, word in enumerate(words):
        if 1 <= word <= 4 or 6 <= word <= 9:
            out[:, k] = chars[(word - 1) % 5]
    keep, const = _tables(words)
    out &= np.take(keep, code, axis=0)
    out |= np.take(const, code, axis=0)
    text = out.view(np.uint8)
    for k in np.flatnonzero(python):
        cell = format(float(v[k]), ".15g").encode("ascii")
        text[k, _FIRST : _FIRST + len(cell)] = np.frombuffer(cell, np.uint8)
    return text


def _quote(cell: str) -> str:
    if any(c in cell for c in ',"\r\n'):
        return '"' + cell.replace('"', '""') + '"'
    return cell


def _plain_ids(ids: list[str]) -> NDArray[np.uint8] | None:
    """The ids as NUL-padded ASCII bytes ``(k, width)``, or None (to be checked and quoted one by one)."""
    joined = "\n".join(ids)
    if not joined.isascii() or any(c in joined for c in '\x00,"\r') or joined.count("\n") != len(ids) - 1:
        return None
    text = np.frombuffer(joined.encode("ascii") + b"\n", np.uint8)
    ends = np.flatnonzero(text == 10)
    starts = np.empty_like(ends)
    starts[0], starts[1:] = 0, ends[:-1] + 1
    lengths = ends - starts
    width = int(lengths.max()) if len(ids) else 0
    if width == 0:
        return None
    # each id's bytes, then NULs: text[starts + j] while j < length (the \n at ends, masked, never beyond)
    at = starts[:, None] + np.arange(width)
    table = np.where(np.arange(width) < lengths[:, None], text[np.minimum(at, len(text) - 1)], 0)
    table = table.astype(np.uint8)
    first = table[:, 0]
    marks = np.isin(first, np.frombuffer(FORMULA_MARKS.encode(), np.uint8))
    control = ((table > 0) & (table < 32)) | (table == 127)
    if np.any((first == 0) | (first == ord("#")) | (first <= 32) | marks) or control.any():
        return None  # empty, a comment mark or a blank first: the exact checks below
    return table


def _checked_ids(name: str, ids: list[str]) -> list[str]:
    wrong = [
        t
        for t in ids
        if not t.strip()
        or t.lstrip()[0] == "#"
        or not t.isprintable()
        or (t[0] in FORMULA_MARKS and not NUMBER_TEXT.match(t))
    ]
    if wrong:
        raise OutputError(
            f"{name}: id {wrong[0]!r} cannot be written (empty, '#', a control "
            "character or a spreadsheet formula mark first)"
        )
    joined = "\x00".join(ids)
    return [_quote(t) for t in ids] if '"' in joined or "," in joined else ids


def format_rows(
    name: str,
    data: NDArray[np.float64],
    ids: Sequence[str] | None = None,
    missing: bool = False,
    plain: NDArray[np.uint8] | None = None,
) -> bytes:
    """The CSV lines (UTF-8) of the rows ``data`` (finite; NaN an empty cell when ``missing``) and ids.

    ``plain``: the ids as :func:`_plain_ids` gives them, if already made (for a larger block).
    """
    rows, width = data.shape
    flat = format_values(data, missing)
    slots = flat.reshape(rows, width, flat.shape[1])
    slots[:, 1:, 0] = ord(",")  # each value's separator, before it
    cells = list(map(str, ids)) if ids is not None else None
    if plain is None and cells is not None:
        plain = _plain_ids(cells)
    slots[:, 0, 0] = ord(",") if plain is not None else 0
    ends = np.full((rows, 1), ord("\n"), np.uint8)
    parts = [slots.reshape(rows, -1), ends] if plain is None else [plain, slots.reshape(rows, -1), ends]
    text = np.concatenate(parts, axis=1).tobytes().translate(None, b"\x00")
    if cells is None or plain is not None:
        return text
    lines = text.decode("ascii").split("\n")
    return "".join(f"{i},{r}\n" for i, r in zip(_checked_ids(name, cells), lines, strict=False)).encode()


class TableWriter:
    """Writes a CSV table block by block on an open text handle (see :func:`write_table_blocks`)."""

    def __init__(
        self,
        fh: IO[str],
        name: str,
        columns: Sequence[str],
        with_ids: bool,
        comment: str | None = None,
        missing: bool = False,
    ) -> None:
        self.fh, self.name, self.columns, self.with_ids = fh, name, tuple(columns), with_ids
        self.missing = missing
        self.rows = 0
        if not self.columns:
            raise ValueError("a table needs at least one column")
        if comment:
            fh.write("".join(f"# {printable(line)}\n" for line in comment.rstrip("\n").split("\n")))
        fh.write(",".join((["id"] if with_ids else []) + [_quote(c) for c in self.columns]) + "\n")

    def write(self, data: NDArray[np.float64], ids: Sequence[str] | None = None) -> None:
        """Append rows ``data`` ``(k, len(columns))`` (and their ids); NaN or inf is refused."""
        data = np.asarray(data, dtype=float)
        if data.ndim != 2 or data.shape[1] != len(self.columns):
            raise ValueError(f"data must have shape (k, {len(self.columns)}), got {data.shape}")
        if self.with_ids != (ids is not None) or (ids is not None and len(ids) != len(data)):
            raise ValueError("give one id per row exactly when the table has ids")
        bad = np.argwhere(np.isinf(data) if self.missing else ~np.isfinite(data))
        if bad.size:
            r, c = bad[0]
            label = f"id {ids[r]!r}" if ids is not None else f"row {self.rows + r + 1}"
            raise OutputError(
                f"{self.name}: {label}, column '{self.columns[c]}' is {data[r, c]}; "
                "hexcal writes only finite numbers (nothing was written)"
            )
        if len(data) == 0:
            return
        raw = None
        if type(self.fh) is io.TextIOWrapper:  # a staged file: its bytes, without decoding them again
            self.fh.flush()
            raw = self.fh.buffer
        for outer in range(0, len(data), IDS_ROWS):  # the ids' bytes made for many rows at once
            cells = None if ids is None else list(map(str, ids[outer : outer + IDS_ROWS]))
            plain = None if cells is None else _plain_ids(cells)
            for start in range(0, min(IDS_ROWS, len(data) - outer), FORMAT_ROWS):
                stop = start + FORMAT_ROWS
                part = None if cells is None else cells[start:stop]
                some = None if plain is None else plain[start:stop]
                text = format_rows(self.name, data[outer + start : outer + stop], part, self.missing, some)
                if raw is not None:
                    raw.write(text)
                else:
                    self.fh.write(text.decode("utf-8"))
        self.rows += len(data)


def write_table_blocks(
    path: str | os.PathLike[str],
    columns: Sequence[str],
    blocks: Iterable[tuple[NDArray[np.float64], Sequence[str] | None]],
    comment: str | None = None,
    outputs: OutputSet | None = None,
    missing: bool = False,
) -> int:
    """Write a table from an iterable of ``(data, ids)`` blocks; returns the number of rows.

    With :func:`iter_tables` on the input side, a command such as ``ik`` works in bounded
    memory on a file of any length. No rows at all is refused (hexcal could not read
    a header-only file back); the file is staged, so nothing is written on any error.
    """
    name = os.fspath(path)
    with atomic_write(path, outputs) as fh:
        writer: TableWriter | None = None
        for data, ids in blocks:
            if writer is None:
                writer = TableWriter(fh, name, columns, ids is not None, comment, missing)
            writer.write(data, ids)
        if writer is None or writer.rows == 0:
            raise OutputError(f"{name}: no rows to write; hexcal does not write a table without rows")
        return writer.rows


def write_table(
    path: str | os.PathLike[str],
    columns: Sequence[str],
    data: NDArray[np.float64],
    ids: Sequence[str] | None = None,
    comment: str | None = None,
    outputs: OutputSet | None = None,
    missing: bool = False,
) -> None:
    """Write a CSV table (with an ``id`` column when ``ids`` is given), staged.

    Refused before anything is written: no rows, or a NaN or infinity (hexcal refuses to
    read them back). With ``missing``, NaN is a value that does not exist (a target not
    seen) and is written as an empty cell, as in a target measurement file.
    """
    write_table_blocks(path, columns, [(np.asarray(data, dtype=float), ids)], comment, outputs, missing)


def write_poses(
    path: str | os.PathLike[str],
    poses: NDArray[np.float64],
    ids: Sequence[str] | None = None,
    comment: str | None = None,
    outputs: OutputSet | None = None,
    covariates: Covariates | None = None,
) -> None:
    """Write a pose file with angles in radians (columns ``x, y, z, a, b, c``, then the covariates)."""
    extra = {} if covariates is None else covariates.to_columns()
    data = np.column_stack([poses, *extra.values()]) if extra else poses
    write_table(path, ("x", "y", "z", "a", "b", "c", *extra), data, ids, comment, outputs)


def write_legs(
    path: str | os.PathLike[str],
    lengths: NDArray[np.float64],
    readings: NDArray[np.float64],
    ids: Sequence[str] | None = None,
    comment: str | None = None,
    outputs: OutputSet | None = None,
    covariates: Covariates | None = None,
) -> None:
    """Write a leg file with ``l1..l6``, ``dl1..dl6`` (joined a block at a time) and the covariates."""
    lengths, readings = np.asarray(lengths, dtype=float), np.asarray(readings, dtype=float)
    if lengths.shape != readings.shape:
        raise ValueError(f"lengths {lengths.shape} and readings {readings.shape} differ")
    extra = {} if covariates is None else covariates.to_columns()
    parts = [lengths, readings, *(v[:, None] for v in extra.values())]
    blocks = (
        (np.concatenate([p[k : k + IDS_ROWS] for p in parts], axis=1),
         None if ids is None else ids[k : k + IDS_ROWS])
        for k in range(0, len(lengths), IDS_ROWS)
    )  # fmt: skip
    write_table_blocks(path, (*LEG_LENGTH_COLUMNS, *LEG_READING_COLUMNS, *extra), blocks, comment, outputs)


def write_measurements(
    path: str | os.PathLike[str],
    measurements: Measurements,
    euler: str,
    orientation: str = "rad",
    comment: str | None = None,
    outputs: OutputSet | None = None,
) -> None:
    """Write a measurement file with orientations as ``rad``, ``deg`` or ``quat`` (and the
    covariates of the measurements)."""
    poses = measurements.poses
    if orientation == "rad":
        angles = poses[:, 3:]
    elif orientation == "deg":
        angles = np.rad2deg(poses[:, 3:])
    elif orientation == "quat":
        from scipy.spatial.transform import Rotation

        angles = Rotation.from_euler(euler, poses[:, 3:]).as_quat()
    else:
        raise ValueError(f"orientation must be rad, deg or quat, got {orientation!r}")
    extra = measurements.covariates.to_columns()
    columns = LEG_READING_COLUMNS + ("x", "y", "z") + ORIENTATION_GROUPS[orientation] + tuple(extra)
    data = np.column_stack([measurements.readings, poses[:, :3], angles, *extra.values()])
    write_table(path, columns, data, measurements.ids, comment, outputs)
