"""Pose, measurement and leg files (docs/formats.md), read with :mod:`hexcal.io.table_reading`.

Orientation columns are one of ``a, b, c`` (rad), ``a_deg, b_deg, c_deg`` or ``qx, qy, qz, qw``
(a unit quaternion, scalar last); leg files hold ``l1..l6`` and/or ``dl1..dl6``. Each file may
have covariate columns (``time``, leg temperatures, payload: :mod:`hexcal.io.covariate_columns`),
read and checked with the rest and carried with the rows.
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Callable, Iterator, Mapping
from typing import Literal, overload

import numpy as np
from numpy.typing import NDArray

from hexcal.errors import InputError, InputWarning
from hexcal.instruments.covariates import NO_COVARIATES, Covariates
from hexcal.instruments.pose import Measurements
from hexcal.io.covariate_columns import BlockCovariates, covariate_columns, table_covariates
from hexcal.io.inputs import DEFAULT_MAX_ROWS, MEASUREMENT_MAX_ROWS
from hexcal.io.table_fast import strictly_increasing
from hexcal.io.table_reading import iter_tables, read_table
from hexcal.io.table_writing import write_legs, write_measurements, write_poses
from hexcal.io.tables import BLOCK_ROWS, LEG_LENGTH_COLUMNS, LEG_READING_COLUMNS, ORIENTATION_GROUPS, Table

__all__ = ["iter_tables", "read_table", "write_legs", "write_measurements", "write_poses"]  # as before

Path = str | os.PathLike[str]
Columns = Mapping[str, str] | None


#: A quaternion whose norm differs from 1 by more than this is refused (others are
#: normalised). 1e-3 admits instruments that print 4 decimals and catches a wrong column.
QUATERNION_NORM_TOLERANCE = 1e-3

#: Radian angle columns beyond this magnitude draw a warning that they may be degrees (beyond π
#: they are refused: no Euler angle in radians exceeds it); an instrument frame turned further
#: than a quarter turn draws it too, and the warning says how to silence a real mistake.
DEGREE_SUSPICION = math.pi / 2


def _orientation_group(table: Table) -> str:
    present = [g for g, cols in ORIENTATION_GROUPS.items() if any(table.has(c) for c in cols)]
    if not present:
        raise InputError(
            f"{table.path}: missing orientation columns: give a, b, c (rad), "
            f"a_deg, b_deg, c_deg, or qx, qy, qz, qw{table.unmapped_hint()}"
        )
    if len(present) > 1:
        names = " and ".join(", ".join(ORIENTATION_GROUPS[g]) for g in present)
        raise InputError(f"{table.path}: two orientation groups at once ({names}); keep one")
    return present[0]


def _check_half_turn(table: Table, group: str, values: NDArray[np.float64], half: float) -> None:
    """Refuse an angle beyond ±180° (the angles of a pose are defined within it, as the
    workspace's are): ``a_deg = 360`` is a typing error or another convention, never read."""
    over = np.argwhere(np.abs(values) > half * (1 + 1e-12))
    if over.size:
        k, j = over[0]
        col = table.label(ORIENTATION_GROUPS[group][j])
        where = f"{table.path}: line {table.line(int(k))}, column '{col}': {values[k, j]:g} is beyond ±180°"
        if group == "deg":
            raise InputError(f"{where}; give every angle within ±180°")
        raise InputError(
            f"{where} (±π rad): the angles look like degrees in radian columns; name the columns "
            "a_deg, b_deg, c_deg"
        )


def table_poses(table: Table, euler: str) -> NDArray[np.float64]:
    """Poses ``(m, 6)`` in mm and rad from a table's pose columns (docs/formats.md "Pose file")."""
    group = _orientation_group(table)
    both = table.numbers(("x", "y", "z", *ORIENTATION_GROUPS[group]))  # each line split once
    position, values = both[:, :3], both[:, 3:]
    if group != "quat":
        _check_half_turn(table, group, values, 180.0 if group == "deg" else np.pi)
    if group == "rad":
        big = np.flatnonzero(np.any(np.abs(values) > DEGREE_SUSPICION, axis=1))
        if big.size:
            warnings.warn(
                f"{table.path}: line {table.line(int(big[0]))}: angles a, b, c are in radians, but "
                f"{big.size} row(s) exceed ±π/2; if they are degrees, name the columns "
                "a_deg, b_deg, c_deg",
                InputWarning,
                stacklevel=2,
            )
        angles = values
    elif group == "deg":
        angles = np.deg2rad(values)
    else:
        norms = np.linalg.norm(values, axis=1)
        bad = np.flatnonzero(np.abs(norms - 1.0) > QUATERNION_NORM_TOLERANCE)
        if bad.size:
            k = bad[0]
            names = ", ".join(table.label(c) for c in ORIENTATION_GROUPS["quat"])
            raise InputError(
                f"{table.path}: line {table.line(int(k))}, columns '{names}': quaternion norm "
                f"{norms[k]:.6g} is not 1 (tolerance {QUATERNION_NORM_TOLERANCE:g})"
            )
        from scipy.spatial.transform import Rotation  # deferred: slow to import

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # gimbal lock: angles still valid
            angles = Rotation.from_quat(values / norms[:, None]).as_euler(euler)
    return np.concatenate([position, angles], axis=1)


PoseRows = tuple[NDArray[np.float64], tuple[str, ...]]
PoseRowsWithCovariates = tuple[NDArray[np.float64], tuple[str, ...], Covariates]


def _pose_numbers(table: Table) -> tuple[str, ...]:
    """Convert a pose table's numbers in one pass (the pose and covariate columns); the
    covariate columns, their set checked."""
    found = covariate_columns(table)
    if found:
        group = ORIENTATION_GROUPS[_orientation_group(table)]
        table.numbers(("x", "y", "z", *group, *found))
    return found


@overload
def read_poses(path: Path, euler: str, max_rows: int | None = ..., delimiter: str | None = ...,
               decimal: str | None = ..., columns: Columns = ..., *,
               covariates: Literal[False] = ...) -> PoseRows: ...  # fmt: skip
@overload
def read_poses(path: Path, euler: str, max_rows: int | None = ..., delimiter: str | None = ...,
               decimal: str | None = ..., columns: Columns = ..., *,
               covariates: Literal[True]) -> PoseRowsWithCovariates: ...  # fmt: skip
def read_poses(
    path: Path,
    euler: str,
    max_rows: int | None = DEFAULT_MAX_ROWS,
    delimiter: str | None = None,
    decimal: str | None = None,
    columns: Columns = None,
    *,
    covariates: bool = False,
) -> PoseRows | PoseRowsWithCovariates:
    """A pose file: poses ``(m, 6)`` (mm, rad, in ``euler``) and their ids (``max_rows``,
    ``delimiter``, ``decimal``, ``columns``: see :func:`read_table`).

    Covariate columns are read and checked in any case; ``covariates=True`` returns them as a
    third value (a :class:`~hexcal.instruments.Covariates`, none present without the columns).
    """
    table = read_table(path, max_rows, delimiter, decimal, columns)
    found = _pose_numbers(table)
    poses, cov = table_poses(table, euler), table_covariates(table, found)
    return (poses, table.ids(), cov) if covariates else (poses, table.ids())


def read_measurements(
    path: Path,
    euler: str,
    max_rows: int | None = MEASUREMENT_MAX_ROWS,
    delimiter: str | None = None,
    decimal: str | None = None,
    columns: Columns = None,
) -> Measurements:
    """A measurement file: measured poses, leg readings ``dl1..dl6`` and ids.

    More than ``max_rows`` rows (default :data:`~hexcal.io.inputs.MEASUREMENT_MAX_ROWS`,
    100,000) are refused while reading, naming the limit and ``--max-rows``; ``delimiter``,
    ``decimal``, ``columns``: see :func:`read_table`.
    """
    table = read_table(path, max_rows, delimiter, decimal, columns)
    group = ORIENTATION_GROUPS[_orientation_group(table)]
    found = covariate_columns(table)
    table.numbers(("x", "y", "z", *group, *LEG_READING_COLUMNS, *found))  # converted in one pass, kept
    poses = table_poses(table, euler)
    readings = table.numbers(LEG_READING_COLUMNS)
    return Measurements(poses, readings, table.ids(), table_covariates(table, found))


class LegData:
    """A leg file: absolute lengths and/or readings, ids and covariates (none present without
    the columns).

    When the file has both, ``lengths`` is converted when first used (``fk`` uses only the
    readings); ``has_lengths`` says whether the file has them without converting.
    """

    def __init__(
        self,
        lengths: NDArray[np.float64] | None,
        readings: NDArray[np.float64] | None,
        ids: tuple[str, ...],
        table: Table | None = None,
        covariates: Covariates | None = None,
    ) -> None:
        self._lengths, self.readings, self.ids, self._table = lengths, readings, ids, table
        self.has_lengths = lengths is not None or table is not None
        self.covariates = NO_COVARIATES if covariates is None else covariates

    @property
    def lengths(self) -> NDArray[np.float64] | None:
        if self._lengths is None and self._table is not None:
            self._lengths, self._table = self._table.numbers(LEG_LENGTH_COLUMNS), None
        return self._lengths


def read_legs(
    path: Path,
    max_rows: int | None = DEFAULT_MAX_ROWS,
    delimiter: str | None = None,
    decimal: str | None = None,
    columns: Columns = None,
) -> LegData:
    """A leg file with ``l1..l6`` and/or ``dl1..dl6`` (at least one group complete)."""
    return table_legs(read_table(path, max_rows, delimiter, decimal, columns))


def table_legs(table: Table, ids: tuple[str, ...] | None = None) -> LegData:
    """Leg lengths and/or readings of a table (``ids``: already read, for blocks)."""
    return _legs(table, lambda: table.ids() if ids is None else ids, table_covariates)


def _legs(table: Table, ids: Callable[[], tuple[str, ...]], covariates: Callable[..., Covariates]) -> LegData:
    """Leg data of a table, its ids read after the numbers (read with them, in one pass), and
    its covariates (``covariates(table, columns)``)."""
    has_l = any(table.has(c) for c in LEG_LENGTH_COLUMNS)
    has_dl = any(table.has(c) for c in LEG_READING_COLUMNS)
    if not (has_l or has_dl):
        raise InputError(f"{table.path}: missing leg columns: give l1..l6 or dl1..dl6{table.unmapped_hint()}")
    if has_l:
        table.numbers([c for c in LEG_LENGTH_COLUMNS if not table.has(c)][:1])  # a missing one: named now
    found = covariate_columns(table)
    legs = LEG_READING_COLUMNS if has_dl else LEG_LENGTH_COLUMNS
    if found:  # the legs' and the covariates' numbers in one pass
        table.numbers((*legs, *found))
    readings = table.numbers(LEG_READING_COLUMNS) if has_dl else None
    lengths = table.numbers(LEG_LENGTH_COLUMNS) if has_l and not has_dl else None
    cov = covariates(table, found)
    return LegData(lengths, readings, ids(), table if has_l and has_dl else None, cov)


class _BlockIds:
    """Ids across the blocks of one file: repeats refused, naming the line of the first one.

    While the ids run in strictly increasing order (:func:`~hexcal.io.table_fast.strictly_increasing`,
    each block's first after the last one before it), they are distinct without a set: a set of
    10^6 ids cost more than reading them. From the first block out of order, a set keeps the ids
    seen (those of the ordered blocks before it read from the file again; a dict of their lines
    would cost several times more); the line of an earlier id is looked up by reading the file
    again, only when one repeats.
    """

    def __init__(self, blocks: Callable[[], Iterator[Table]]) -> None:
        self.seen: set[str] = set()
        self.count, self.again = 0, blocks
        self.last: str | None = None  # the last id while every block so far was in order
        self.ordered = True

    def __call__(self, table: Table) -> tuple[str, ...]:
        if table.has("id"):
            ids = table.ids(repeats=False)  # every check but for repeats, which the set shows
            if self.ordered and ids:
                if strictly_increasing(ids if self.last is None else (self.last, *ids)):
                    self.last = ids[-1]
                    self.count += len(ids)
                    return ids
                self.ordered = False
                self.seen = set(self._earlier(None, table.line(0)))
            before = len(self.seen)
            self.seen.update(ids)
            if len(self.seen) != before + len(ids):  # a repeat inside the block, or of an earlier one
                table.ids()  # the one inside the block is refused first, as always
                table.ids(self._earlier(set(ids), table.line(0)))
        else:
            ids = table.ids(first=self.count + 1)
        self.count += len(ids)
        return ids

    def _earlier(self, ids: set[str] | None, stop: int) -> dict[str, int]:
        """The first line of each of ``ids`` (None: of every id) before line ``stop`` (read from
        the file again)."""
        found: dict[str, int] = {}
        for block in self.again():
            for value, line in zip(block.cells("id"), block.lines, strict=True):
                if line >= stop:
                    return found
                if ids is None or value in ids:
                    found.setdefault(value, line)
        return found


def iter_poses(
    path: Path,
    euler: str,
    block_rows: int = BLOCK_ROWS,
    delimiter: str | None = None,
    decimal: str | None = None,
    columns: Columns = None,
    *,
    covariates: bool = False,
) -> Iterator[PoseRows | PoseRowsWithCovariates]:
    """A pose file in blocks: ``(poses (k, 6), ids)`` per block of ``block_rows`` rows, and
    with ``covariates=True`` the block's :class:`~hexcal.instruments.Covariates` third (read
    and checked in any case; the time increasing across blocks).

    Memory is bounded by one block (and the ids seen, to refuse repeats), whatever the
    length of the file; the radians-look-like-degrees warning is given once.
    """
    ids = _BlockIds(lambda: iter_tables(path, block_rows, delimiter, decimal, columns))
    times = BlockCovariates()
    said: set[str] = set()
    for table in iter_tables(path, block_rows, delimiter, decimal, columns):
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", InputWarning)
                found = _pose_numbers(table)
                poses = table_poses(table, euler)
        finally:  # each warning once a file (the degrees one names its first block only)
            for item in caught:
                key = "degrees" if "±π/2" in str(item.message) else str(item.message)
                if key not in said:
                    warnings.warn(item.message, item.category, stacklevel=2)
                    said.add(key)
        cov = times(table, found)
        yield (poses, ids(table), cov) if covariates else (poses, ids(table))


def iter_legs(
    path: Path,
    block_rows: int = BLOCK_ROWS,
    delimiter: str | None = None,
    decimal: str | None = None,
    columns: Columns = None,
) -> Iterator[LegData]:
    """A leg file in blocks of ``block_rows`` rows (memory bounded by one block; the time of
    the covariates increasing across blocks)."""
    ids = _BlockIds(lambda: iter_tables(path, block_rows, delimiter, decimal, columns))
    times = BlockCovariates()
    for table in iter_tables(path, block_rows, delimiter, decimal, columns):
        yield _legs(table, lambda table=table: ids(table), times)
