"""Ballbar data files (docs/ballbar.md): ``id`` (optional), ``dl1 .. dl6``, ``d``, mm.

One row per pose: the six leg readings and the bar's reading ``d`` (its length is the
setup's ``length + d``), and optional covariate columns (``time``, leg temperatures, payload:
:mod:`hexcal.io.covariate_columns`). Read by hexcal's one table reader (:func:`hexcal.io.read_table`:
the delimiter and decimal mark detected or given, a unit row checked, the row limit
``--max-rows``), written by its one table writer, staged in the command's output set.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from hexcal.instruments.ballbar_setup import BallbarMeasurements
from hexcal.io.covariate_columns import covariate_columns, table_covariates
from hexcal.io.inputs import MEASUREMENT_MAX_ROWS
from hexcal.io.table_reading import read_table
from hexcal.io.table_writing import write_table
from hexcal.io.tables import LEG_READING_COLUMNS

#: The columns of a ballbar data file (besides an optional ``id``).
BALLBAR_COLUMNS = (*LEG_READING_COLUMNS, "d")


def read_ballbar_measurements(
    path: str | os.PathLike[str],
    delimiter: str | None = None,
    decimal: str | None = None,
    max_rows: int | None = MEASUREMENT_MAX_ROWS,
) -> BallbarMeasurements:
    """A ballbar data file: leg readings and bar readings (mm), ids (row numbers without),
    covariates (none present without their columns)."""
    table = read_table(path, max_rows, delimiter, decimal)
    found = covariate_columns(table)
    values = table.numbers((*BALLBAR_COLUMNS, *found))
    return BallbarMeasurements(values[:, :6], values[:, 6], table.ids(), table_covariates(table, found))


def write_ballbar_measurements(
    path: str | os.PathLike[str], data: BallbarMeasurements, comment: str | None = None
) -> None:
    """Write a ballbar data file (standard CSV, 15 digits; the covariates after ``d``), staged."""
    extra = data.covariates.to_columns()
    values = np.column_stack([data.readings, data.d, *extra.values()])
    write_table(path, (*BALLBAR_COLUMNS, *extra), values, data.ids, comment)


def ballbar_reader(
    path: Any, instrument: Any, euler: str, delimiter: Any, decimal: Any
) -> BallbarMeasurements:
    """The session reader of :data:`hexcal.io.sessions.READERS` (no column map)."""
    return read_ballbar_measurements(path, delimiter, decimal)
