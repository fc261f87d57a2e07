"""Pose, measurement and leg files (FORMATS.md) on top of :mod:`hexcal.io.tables`."""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hexcal.errors import InputError, InputWarning
from hexcal.io.tables import Table, read_table, write_table
from hexcal.models.pose import Measurements

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
    position = table.numbers(("x", "y", "z"))
    values = table.numbers(ORIENTATION_GROUPS[group])
    if group == "rad":
        big = np.flatnonzero(np.any(np.abs(values) > DEGREE_SUSPICION, axis=1))
        if big.size:
            warnings.warn(
                f"{table.path}: line {table.lines[big[0]]}: angles a, b, c are in radians, but "
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
                f"{table.path}: line {table.lines[k]}, columns 'qx, qy, qz, qw': quaternion norm "
                f"{norms[k]:.6g} is not 1 (tolerance {QUATERNION_NORM_TOLERANCE:g})"
            )
        from scipy.spatial.transform import Rotation  # deferred: slow to import

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # gimbal lock: angles still valid
            angles = Rotation.from_quat(values / norms[:, None]).as_euler(euler)
    return np.concatenate([position, angles], axis=1)


def read_poses(path: str | os.PathLike[str], euler: str) -> tuple[NDArray[np.float64], tuple[str, ...]]:
    """A pose file: poses ``(m, 6)`` (mm, rad, in ``euler``) and their ids."""
    table = read_table(path)
    return table_poses(table, euler), table.ids()


def read_measurements(path: str | os.PathLike[str], euler: str) -> Measurements:
    """A measurement file: measured poses, leg readings ``dl1..dl6`` and ids."""
    table = read_table(path)
    poses = table_poses(table, euler)
    readings = table.numbers(LEG_READING_COLUMNS)
    return Measurements(poses, readings, table.ids())


@dataclass(frozen=True)
class LegData:
    """A leg file: absolute lengths and/or readings, and ids."""

    lengths: NDArray[np.float64] | None
    readings: NDArray[np.float64] | None
    ids: tuple[str, ...]


def read_legs(path: str | os.PathLike[str]) -> LegData:
    """A leg file with ``l1..l6`` and/or ``dl1..dl6`` (at least one group complete)."""
    table = read_table(path)
    has_l = any(table.has(c) for c in LEG_LENGTH_COLUMNS)
    has_dl = any(table.has(c) for c in LEG_READING_COLUMNS)
    if not (has_l or has_dl):
        raise InputError(f"{table.path}: missing leg columns: give l1..l6 or dl1..dl6")
    lengths = table.numbers(LEG_LENGTH_COLUMNS) if has_l else None
    readings = table.numbers(LEG_READING_COLUMNS) if has_dl else None
    return LegData(lengths, readings, table.ids())


def write_poses(
    path: str | os.PathLike[str],
    poses: NDArray[np.float64],
    ids: Sequence[str] | None = None,
    comment: str | None = None,
) -> None:
    """Write a pose file with angles in radians (columns ``x, y, z, a, b, c``)."""
    write_table(path, ("x", "y", "z", "a", "b", "c"), poses, ids, comment)


def write_legs(
    path: str | os.PathLike[str],
    lengths: NDArray[np.float64],
    readings: NDArray[np.float64],
    ids: Sequence[str] | None = None,
    comment: str | None = None,
) -> None:
    """Write a leg file with ``l1..l6`` and ``dl1..dl6``."""
    write_table(
        path,
        LEG_LENGTH_COLUMNS + LEG_READING_COLUMNS,
        np.concatenate([lengths, readings], axis=1),
        ids,
        comment,
    )


def write_measurements(
    path: str | os.PathLike[str],
    measurements: Measurements,
    euler: str,
    orientation: str = "rad",
    comment: str | None = None,
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
    write_table(path, columns, data, measurements.ids, comment)
