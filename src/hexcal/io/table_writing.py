"""Writing CSV tables, whole or block by block, through the command's output set.

A table with no rows, or with a NaN or infinity, is refused before anything is written,
because hexcal could not read it back; so is an id that is empty, starts with ``#`` or holds
a line break. Numbers are written with 15 significant digits (``%.15g``), one ``%`` call per
block of rows; cells with commas or quotes are quoted as the csv module does.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from typing import IO

import numpy as np
from numpy.typing import NDArray

from hexcal.io.files import atomic_write
from hexcal.io.outputs import OutputError, OutputSet


def _quote(cell: str) -> str:
    if any(c in cell for c in ',"\r\n'):
        return '"' + cell.replace('"', '""') + '"'
    return cell


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
        self._template = ",".join(["%.15g"] * len(self.columns)) + "\n"
        if comment:
            fh.write("".join(f"# {line}\n" for line in comment.splitlines()))
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
        if self.missing and np.isnan(data).any():  # an empty cell: a value that does not exist
            text = "".join(
                ",".join("" if np.isnan(v) else format(v, ".15g") for v in row) + "\n" for row in data
            )
        else:
            text = (self._template * len(data)) % tuple(data.ravel().tolist())  # one call per block
        if ids is not None:
            ids = [str(value) for value in ids]
            wrong = [t for t in ids if not t.strip() or t.lstrip()[:1] == "#" or "\n" in t or "\r" in t]
            if wrong:
                raise OutputError(
                    f"{self.name}: id {wrong[0]!r} cannot be written (empty, '#' or a line break)"
                )
            joined = "\x00".join(ids)
            if '"' in joined or "," in joined:
                ids = [_quote(t) for t in ids]
            rows = text.split("\n")
            text = "\n".join([f"{i},{r}" for i, r in zip(ids, rows, strict=False)]) + "\n"
        self.fh.write(text)
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
