"""Pose, measurement and leg files (FORMATS.md) on top of :mod:`hexcal.io.tables`."""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hexcal.errors import InputError, InputWarning
from hexcal.instruments.pose import Measurements
from hexcal.io.inputs import DEFAULT_MAX_ROWS, MEASUREMENT_MAX_ROWS
from hexcal.io.outputs import OutputSet
from hexcal.io.tables import BLOCK_ROWS, Table, iter_tables, read_table, write_table

#: A quaternion whose norm differs from 1 by more than this is refused (others are
#: normalised). 1e-3 admits instruments that print 4 decimals and catches a wrong column.
QUATERNION_NORM_TOLERANCE = 1e-3

#: Radian angle columns beyond this magnitude draw a warning that they may be degrees.
DEGREE_SUSPICION = math.pi / 2

ORIENTATION_GROUPS = {
    "rad": ("a", "b", "c"),
    "deg": ("a_deg", "b_deg", "c_deg"),
    "quat": ("qx", "qy", "qz", "qw"),
}
LEG_LENGTH_COLUMNS = tuple(f"l{i}" for i in range(1, 7))
LEG_READING_COLUMNS = tuple(f"dl{i}" for i in range(1, 7))


def _orientation_group(table: Table) -> str:
    present = [g for g, cols in ORIENTATION_GROUPS.items() if any(table.has(c) for c in cols)]
    if not present:
        raise InputError(
            f"{table.path}: missing orientation columns: give a, b, c (rad), "
            "a_deg, b_deg, c_deg, or qx, qy, qz, qw"
        )
    if len(present) > 1:
        names = " and ".join(", ".join(ORIENTATION_GROUPS[g]) for g in present)
        raise InputError(f"{table.path}: two orientation groups at once ({names}); keep one")
    return present[0]


def table_poses(table: Table, euler: str) -> NDArray[np.float64]:
    """Poses ``(m, 6)`` in mm and rad from a table's pose columns (FORMATS.md)."""
    group = _orientation_group(table)
    both = table.numbers(("x", "y", "z", *ORIENTATION_GROUPS[group]))  # each line split once
    position, values = both[:, :3], both[:, 3:]
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
            raise InputError(
                f"{table.path}: line {table.line(int(k))}, columns 'qx, qy, qz, qw': quaternion norm "
                f"{norms[k]:.6g} is not 1 (tolerance {QUATERNION_NORM_TOLERANCE:g})"
            )
        from scipy.spatial.transform import Rotation  # deferred: slow to import

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # gimbal lock: angles still valid
            angles = Rotation.from_quat(values / norms[:, None]).as_euler(euler)
    return np.concatenate([position, angles], axis=1)


def read_poses(
    path: str | os.PathLike[str], euler: str, max_rows: int | None = DEFAULT_MAX_ROWS
) -> tuple[NDArray[np.float64], tuple[str, ...]]:
    """A pose file: poses ``(m, 6)`` (mm, rad, in ``euler``) and their ids (``max_rows``: see
    :func:`~hexcal.io.tables.read_table`)."""
    table = read_table(path, max_rows)
    return table_poses(table, euler), table.ids()


def read_measurements(
    path: str | os.PathLike[str], euler: str, max_rows: int | None = MEASUREMENT_MAX_ROWS
) -> Measurements:
    """A measurement file: measured poses, leg readings ``dl1..dl6`` and ids.

    More than ``max_rows`` rows (default :data:`~hexcal.io.inputs.MEASUREMENT_MAX_ROWS`,
    100,000) are refused while reading, before conversion, with a message naming the limit
    and ``--max-rows``.
    """
    table = read_table(path, max_rows)
    group = ORIENTATION_GROUPS[_orientation_group(table)]
    table.numbers(("x", "y", "z", *group, *LEG_READING_COLUMNS))  # converted in one pass, kept
    poses = table_poses(table, euler)
    readings = table.numbers(LEG_READING_COLUMNS)
    return Measurements(poses, readings, table.ids())


@dataclass(frozen=True)
class LegData:
    """A leg file: absolute lengths and/or readings, and ids."""

    lengths: NDArray[np.float64] | None
    readings: NDArray[np.float64] | None
    ids: tuple[str, ...]


def read_legs(path: str | os.PathLike[str], max_rows: int | None = DEFAULT_MAX_ROWS) -> LegData:
    """A leg file with ``l1..l6`` and/or ``dl1..dl6`` (at least one group complete)."""
    return table_legs(read_table(path, max_rows))


def table_legs(table: Table, ids: tuple[str, ...] | None = None) -> LegData:
    """Leg lengths and/or readings of a table (``ids``: already read, for blocks)."""
    has_l = any(table.has(c) for c in LEG_LENGTH_COLUMNS)
    has_dl = any(table.has(c) for c in LEG_READING_COLUMNS)
    if not (has_l or has_dl):
        raise InputError(f"{table.path}: missing leg columns: give l1..l6 or dl1..dl6")
    table.numbers((LEG_LENGTH_COLUMNS if has_l else ()) + (LEG_READING_COLUMNS if has_dl else ()))
    lengths = table.numbers(LEG_LENGTH_COLUMNS) if has_l else None
    readings = table.numbers(LEG_READING_COLUMNS) if has_dl else None
    return LegData(lengths, readings, table.ids() if ids is None else ids)


class _BlockIds:
    """Ids across the blocks of one file (repeats found across blocks)."""

    def __init__(self) -> None:
        self.seen: dict[str, int] = {}
        self.count = 0

    def __call__(self, table: Table) -> tuple[str, ...]:
        ids = table.ids(self.seen if table.has("id") else None, first=self.count + 1)
        self.count += len(ids)
        return ids


def iter_poses(
    path: str | os.PathLike[str], euler: str, block_rows: int = BLOCK_ROWS
) -> Iterator[tuple[NDArray[np.float64], tuple[str, ...]]]:
    """A pose file in blocks: ``(poses (k, 6), ids)`` per block of ``block_rows`` rows.

    Memory is bounded by one block (and the ids seen, to refuse repeats), whatever the
    length of the file; the radians-look-like-degrees warning is given once.
    """
    ids = _BlockIds()
    warned = False
    for table in iter_tables(path, block_rows):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", InputWarning)
            poses = table_poses(table, euler)
        for item in caught:
            if not warned:
                warnings.warn(item.message, item.category, stacklevel=2)
                warned = True
        yield poses, ids(table)


def iter_legs(path: str | os.PathLike[str], block_rows: int = BLOCK_ROWS) -> Iterator[LegData]:
    """A leg file in blocks of ``block_rows`` rows (memory bounded by one block)."""
    ids = _BlockIds()
    for table in iter_tables(path, block_rows):
        yield table_legs(table, ids(table))


def write_poses(
    path: str | os.PathLike[str],
    poses: NDArray[np.float64],
    ids: Sequence[str] | None = None,
    comment: str | None = None,
    outputs: OutputSet | None = None,
) -> None:
    """Write a pose file with angles in radians (columns ``x, y, z, a, b, c``)."""
    write_table(path, ("x", "y", "z", "a", "b", "c"), poses, ids, comment, outputs)


def write_legs(
    path: str | os.PathLike[str],
    lengths: NDArray[np.float64],
    readings: NDArray[np.float64],
    ids: Sequence[str] | None = None,
    comment: str | None = None,
    outputs: OutputSet | None = None,
) -> None:
    """Write a leg file with ``l1..l6`` and ``dl1..dl6``."""
    write_table(
        path,
        LEG_LENGTH_COLUMNS + LEG_READING_COLUMNS,
        np.concatenate([lengths, readings], axis=1),
        ids,
        comment,
        outputs,
    )


def write_measurements(
    path: str | os.PathLike[str],
    measurements: Measurements,
    euler: str,
    orientation: str = "rad",
    comment: str | None = None,
    outputs: OutputSet | None = None,
) -> None:
    """Write a measurement file with orientations as ``rad``, ``deg`` or ``quat``."""
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
    columns = LEG_READING_COLUMNS + ("x", "y", "z") + ORIENTATION_GROUPS[orientation]
    data = np.concatenate([measurements.readings, poses[:, :3], angles], axis=1)
    write_table(path, columns, data, measurements.ids, comment, outputs)
