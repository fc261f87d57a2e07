"""The covariate columns of a table: ``time``, ``temp1 ... temp6`` or ``temp``, ``payload_kg`` and
``payload_x, payload_y, payload_z`` (docs/formats.md "Covariates").

Every reader of measurement, pose and leg files reads them here, with the checks of
:mod:`hexcal.instruments.covariates` (what is refused, and why, is decided there): each
refusal is one :class:`~hexcal.errors.InputError` line naming the file, the line and the file's
own column. A table without covariate columns costs a look at its header.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hexcal.errors import InputError, UsageError
from hexcal.instruments.covariates import NO_COVARIATES, TIME_COLUMN, Covariates, check_columns, value_problem
from hexcal.io.tables import Table

#: Lines named in a message beside the first one refused.
SHOWN_LINES = 3


def covariate_columns(table: Table) -> tuple[str, ...]:
    """The covariate columns of ``table`` (hexcal's names), their set checked (one line naming
    the file: ``temp`` with ``temp1``, some leg temperatures only, ...)."""
    if not any(c.startswith(("time", "temp", "payload_")) for c in table.columns):
        return ()
    try:
        return check_columns(table.columns, table.label)
    except UsageError as exc:
        raise InputError(f"{table.path}: {exc}") from None


def table_covariates(
    table: Table, columns: Sequence[str] | None = None, before: float | None = None
) -> Covariates:
    """The covariates of ``table``'s rows, every value checked (none present without the columns).

    ``columns``: :func:`covariate_columns` of the table, when already found (a reader asks for
    them with its other columns, converted in one pass). ``before``: the time of the row before
    the table's first (the block before it), which the first time must follow.
    """
    names = covariate_columns(table) if columns is None else tuple(columns)
    if not names:
        return NO_COVARIATES
    values = table.numbers(names)
    for k, name in enumerate(names):
        column = values[:, k]
        if name == TIME_COLUMN and before is not None:
            column = np.concatenate([[before], column])
        found = value_problem(name, column)
        if found is None:
            continue
        rows, why = found
        if name == TIME_COLUMN and before is not None:
            rows = rows - 1
        more = ""
        if len(rows) > 1:
            lines = ", ".join(str(table.line(int(r))) for r in rows[1 : 1 + SHOWN_LINES])
            etc = " ..." if len(rows) > 1 + SHOWN_LINES else ""
            more = f" (and {len(rows) - 1} more row(s): line {lines}{etc})"
        where = f"{table.path}: line {table.line(int(rows[0]))}, column '{table.label(name)}'"
        raise InputError(f"{where}: {why}{more}")
    return Covariates.from_columns(dict(zip(names, values.T, strict=True)))


class BlockCovariates:
    """The covariates of a file read in blocks: the time of each block's first row checked
    against the last of the block before."""

    def __init__(self) -> None:
        self.last: float | None = None

    def __call__(self, table: Table, columns: Sequence[str] | None = None) -> Covariates:
        found = table_covariates(table, columns, self.last)
        if found.time is not None and len(found.time):
            self.last = float(found.time[-1])
        return found
