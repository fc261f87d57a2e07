"""Reading and writing hexcal's files (FORMATS.md): geometry YAML and CSV tables.

Every reader validates strictly and raises :class:`InputError` with one line that
names the file, the line and the column of the problem. Every writer writes to a
temporary file in the target's folder and renames it, so that an output file is
either complete or absent. Input files are only ever opened for reading.
"""

from __future__ import annotations

import contextlib
import csv
import math
import os
import tempfile
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np
import yaml
from numpy.typing import NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.presets import PRESETS, preset
from hexcal.errors import GeometryError, InputError, InputWarning
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


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask






# -- geometry -------------------------------------------------------------------


def load_geometry(spec: str | os.PathLike[str]) -> Geometry:
    """A geometry from a preset name or a YAML file (FORMATS.md)."""
    if isinstance(spec, str) and spec in PRESETS:
        return preset(spec)
    path = Path(spec)
    if not path.exists():
        raise InputError(f"{path}: no such geometry file (and not a preset: {', '.join(PRESETS)})")
    try:
        with open(path, encoding="utf-8") as fh:
            data = yaml.safe_load(fh)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}: " if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise InputError(f"{path}: {where}not valid YAML ({problem})") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read: {exc}") from None
    try:
        return Geometry.from_dict(data)
    except GeometryError as exc:
        raise InputError(f"{path}: {exc}") from None


def _plain(value: Any) -> Any:
    """Convert numpy scalars and arrays inside ``value`` to plain Python for YAML/JSON."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


def save_geometry(geometry: Geometry, path: str | os.PathLike[str]) -> None:
    """Write a geometry as YAML (atomically)."""
    text = yaml.safe_dump(_plain(geometry.to_dict()), sort_keys=False, default_flow_style=None)
    with atomic_write(path) as fh:
        fh.write(text)


@contextmanager
def atomic_write(path: str | os.PathLike[str]) -> Iterator[IO[str]]:
    """Open a temporary file beside ``path``; rename it to ``path`` only on success."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"{path}: the folder {folder} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as fh:
            yield fh
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual mode
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


# -- CSV tables -------------------------------------------------------------------


@dataclass(frozen=True)
class Table:
    """A parsed CSV table: column names, string cells and their physical line numbers."""

    path: str
    columns: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    lines: tuple[int, ...]

    def has(self, name: str) -> bool:
        return name in self.columns

    def numbers(self, names: Sequence[str]) -> NDArray[np.float64]:
        """Numeric values of the named columns, shape ``(rows, len(names))``."""
        for name in names:
            if name not in self.columns:
                raise InputError(f"{self.path}: missing column '{name}'")
        idx = [self.columns.index(n) for n in names]
        out = np.empty((len(self.rows), len(names)))
        for r, (row, line) in enumerate(zip(self.rows, self.lines, strict=True)):
            for c, (k, name) in enumerate(zip(idx, names, strict=True)):
                text = row[k]
                try:
                    if "_" in text:  # float() accepts digit separators; a CSV number has none
                        raise ValueError(text)
                    value = float(text)
                except ValueError:
                    raise InputError(
                        f"{self.path}: line {line}, column '{name}': not a number: {text!r}"
                    ) from None
                if not math.isfinite(value):
                    raise InputError(
                        f"{self.path}: line {line}, column '{name}': {text} is not a finite number"
                    )
                out[r, c] = value
        return out

    def ids(self) -> tuple[str, ...]:
        """The ``id`` column, or the row numbers 1, 2, ... when there is none."""
        if "id" not in self.columns:
            return tuple(str(k + 1) for k in range(len(self.rows)))
        k = self.columns.index("id")
        ids = tuple(row[k] for row in self.rows)
        seen: dict[str, int] = {}
        for value, line in zip(ids, self.lines, strict=True):
            if value == "":
                raise InputError(f"{self.path}: line {line}, column 'id': empty id")
            if value in seen:
                raise InputError(
                    f"{self.path}: line {line}, column 'id': id {value!r} repeats line {seen[value]}"
                )
            seen[value] = line
        return ids


def read_table(path: str | os.PathLike[str]) -> Table:
    """Read a CSV table with a header row; ``#`` lines before the header are comments."""
    name = str(path)
    try:
        with open(path, encoding="utf-8-sig", newline="") as fh:
            text = fh.read()
    except FileNotFoundError:
        raise InputError(f"{name}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{name}: is a folder, not a file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{name}: cannot read: {exc}") from None
    header: tuple[str, ...] | None = None
    rows: list[tuple[str, ...]] = []
    lines: list[int] = []
    # one physical line is one record: comments are skipped before the csv module sees
    # them (an unbalanced quote in a comment must not swallow the header)
    for lineno, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        if header is None and line.lstrip().startswith("#"):
            continue
        fields = next(csv.reader([line]))
        if header is None:
            header = tuple(f.strip() for f in fields)
            for k, col in enumerate(header):
                if col == "":
                    raise InputError(f"{name}: line {lineno}: column {k + 1} of the header has no name")
                if col in header[:k]:
                    raise InputError(f"{name}: line {lineno}: column '{col}' appears twice in the header")
            continue
        if len(fields) != len(header):
            raise InputError(f"{name}: line {lineno}: {len(fields)} fields, but the header has {len(header)}")
        rows.append(tuple(f.strip() for f in fields))
        lines.append(lineno)
    if header is None:
        raise InputError(f"{name}: empty file (no header row)")
    if not rows:
        raise InputError(f"{name}: the header has no data rows")
    return Table(name, header, tuple(rows), tuple(lines))


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


def _format(value: float) -> str:
    return format(float(value), ".15g")


def write_table(
    path: str | os.PathLike[str],
    columns: Sequence[str],
    data: NDArray[np.float64],
    ids: Sequence[str] | None = None,
    comment: str | None = None,
) -> None:
    """Write a CSV table (with an ``id`` column when ``ids`` is given), atomically."""
    data = np.asarray(data, dtype=float)
    with atomic_write(path) as fh:
        if comment:
            for line in comment.splitlines():
                fh.write(f"# {line}\n")
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow((["id"] if ids is not None else []) + list(columns))
        for k, row in enumerate(data):
            cells = [_format(v) for v in row]
            writer.writerow(([ids[k]] if ids is not None else []) + cells)


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


def read_matrix(path: str | os.PathLike[str], shape: tuple[int, int]) -> NDArray[np.float64]:
    """A small numeric matrix: rows of numbers separated by commas or blanks; ``#`` comments."""
    name = str(path)
    try:
        with open(path, encoding="utf-8") as fh:
            lines = fh.read().splitlines()
    except FileNotFoundError:
        raise InputError(f"{name}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{name}: cannot read: {exc}") from None
    rows = []
    for lineno, line in enumerate(lines, start=1):
        text = line.split("#", 1)[0].replace(",", " ").split()
        if not text:
            continue
        try:
            if any("_" in v for v in text):  # float() accepts digit separators
                raise ValueError
            values = [float(v) for v in text]
        except ValueError:
            raise InputError(f"{name}: line {lineno}: not a row of numbers: {line.strip()!r}") from None
        if len(values) != shape[1]:
            raise InputError(f"{name}: line {lineno}: {len(values)} numbers, expected {shape[1]}")
        if not all(math.isfinite(v) for v in values):
            raise InputError(f"{name}: line {lineno}: NaN or inf")
        rows.append(values)
    if len(rows) != shape[0]:
        raise InputError(f"{name}: {len(rows)} rows, expected {shape[0]}")
    return np.array(rows)
