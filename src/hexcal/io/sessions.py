"""Sessions from files: a data file and the setup that says which instrument recorded it.

A session is read from a data file and, optionally, a setup file (without one the file is
a measurement file of the full pose in the base frame) or the instrument itself. The setup's
kind names the instrument (:func:`hexcal.instruments.instrument_for`), and the instrument's
name the reader and writer of its data files here (:data:`READERS`, :data:`WRITERS`): a new
instrument's files are one reader and one writer added to these (by a line here, or
``READERS[name] = reader`` from its own module); its instrument is then given as such, since
a setup file describes targets, a tool or a ballbar.

Column maps: a setup's ``columns`` says how the files of its instrument name their columns;
a map given to :func:`read_session` (the command line's ``--columns``) is merged with it, the
given map winning name by name (:func:`merge_columns`, which warns once of what it replaced).
"""

from __future__ import annotations

import inspect
import os
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from hexcal.errors import InputError, InputWarning, UsageError
from hexcal.instruments.ballbar_setup import BallbarSetup
from hexcal.instruments.base import MeasurementModel, Session
from hexcal.instruments.registry import instrument_for
from hexcal.instruments.setup import Setup
from hexcal.io.ballbar_files import ballbar_reader, write_ballbar_measurements
from hexcal.io.measurement_files import read_measurements, write_measurements
from hexcal.io.setup_file import load_setup
from hexcal.io.tables import check_column_map
from hexcal.io.target_files import read_target_measurements, read_tool_measurements, write_target_measurements

#: Options a reader takes: the instrument, the Euler sequence, the delimiter and decimal mark,
#: and, as the keyword ``columns``, a column map (passed only when there is one: a reader
#: without that keyword reads files with hexcal's own column names only).
Reader = Callable[..., Any]
Writer = Callable[..., None]
Columns = Mapping[str, str] | None


def _full_pose(
    path: Any, instrument: Any, euler: str, delimiter: Any, decimal: Any, columns: Columns = None
) -> Any:
    return read_measurements(path, euler, delimiter=delimiter, decimal=decimal, columns=columns)


def _tool(
    path: Any, instrument: Any, euler: str, delimiter: Any, decimal: Any, columns: Columns = None
) -> Any:
    return read_tool_measurements(path, euler, delimiter, decimal, columns)


def _targets(
    path: Any, instrument: Any, euler: str, delimiter: Any, decimal: Any, columns: Columns = None
) -> Any:
    return read_target_measurements(path, instrument.setup, delimiter, decimal, columns)


#: The data reader of each instrument, by its registry name.
READERS: dict[str, Reader] = {
    "pose": _full_pose,
    "tool": _tool,
    "targets": _targets,
    "ballbar": ballbar_reader,
}


def merge_columns(setup: Columns, given: Columns, where: str = "--columns") -> dict[str, str] | None:
    """A setup's column map with ``given`` merged in (``given`` wins for a name in both).

    A replaced entry draws one :class:`~hexcal.errors.InputWarning` line naming them; the merged
    map is checked again (two names for one file column are refused, naming ``where``).

    >>> merge_columns({"x": "X", "y": "Y"}, {"z": "Z"})
    {'x': 'X', 'y': 'Y', 'z': 'Z'}
    """
    if not setup or not given:
        return dict(given or setup) if (given or setup) else None
    merged = {**setup, **given}
    replaced = [f"{k}={setup[k]} by {k}={given[k]}" for k in given if k in setup and setup[k] != given[k]]
    if replaced:
        warnings.warn(
            f"{where} replaces the setup's columns: {', '.join(replaced)}", InputWarning, stacklevel=3
        )
    try:
        check_column_map(merged)
    except UsageError as exc:
        raise InputError(
            f"{where} with the setup's columns: {str(exc).removeprefix('column map: ')}"
        ) from None
    return merged


def _write_poses(
    path: Any, data: Any, euler: str, orientation: str = "rad", comment: str | None = None
) -> None:
    write_measurements(path, data, euler, orientation, comment=comment)


def _write_targets(
    path: Any, data: Any, euler: str, orientation: str = "rad", comment: str | None = None
) -> None:
    if orientation != "rad":
        raise InputError(f"--orientation {orientation}: target positions have no orientation")
    write_target_measurements(path, data, comment=comment)


def _write_ballbar(
    path: Any, data: Any, euler: str, orientation: str = "rad", comment: str | None = None
) -> None:
    if orientation != "rad":
        raise InputError(f"--orientation {orientation}: ballbar readings have no orientation")
    write_ballbar_measurements(path, data, comment=comment)


#: The data writer of each instrument, by its registry name.
WRITERS: dict[str, Writer] = {
    "pose": _write_poses,
    "tool": _write_poses,
    "targets": _write_targets,
    "ballbar": _write_ballbar,
}


def load_instrument(
    setup: str | os.PathLike[str] | Setup | MeasurementModel | None, euler: str
) -> MeasurementModel:
    """The instrument of a setup file or setup (None: the full pose in the base frame), its
    angles in the Euler sequence ``euler``; an instrument is returned as it is."""
    if isinstance(setup, MeasurementModel):
        return setup
    if setup is not None and not isinstance(setup, Setup | BallbarSetup):
        setup = load_setup(setup)
    return instrument_for(None if setup is None else setup.in_euler(euler))


def read_session(
    data: str | os.PathLike[str],
    setup: Setup | str | os.PathLike[str] | MeasurementModel | None,
    euler: str,
    delimiter: str | None = None,
    decimal: str | None = None,
    label: str | None = None,
    columns: Columns = None,
) -> Session:
    """The session of a data file and its setup (a :class:`Setup`, a setup file or the
    instrument; None for the full pose in the base frame), angles in the Euler sequence
    ``euler``; ``columns`` (hexcal's name -> the file's) merged with the setup's own
    (:func:`merge_columns`)."""
    instrument = load_instrument(setup, euler)
    try:
        reader = READERS[instrument.name]
    except KeyError:
        raise InputError(f"no reader of {instrument.name} data files") from None
    own = getattr(getattr(instrument, "setup", None), "columns", None)
    merged = merge_columns(own, columns)
    try:
        if merged is None:
            values = reader(data, instrument, euler, delimiter, decimal)
        elif "columns" in inspect.signature(reader).parameters:
            values = reader(data, instrument, euler, delimiter, decimal, columns=merged)
        else:
            raise InputError(f"{data}: the reader of {instrument.name} data files takes no column map")
    except InputError as exc:
        if setup is None and "missing" in str(exc):  # read as the full pose: another instrument's?
            hint = _setup_missing(data, delimiter, decimal, merged)
            if hint:
                raise InputError(hint) from None
        raise
    return Session(values, instrument, label or Path(data).name)


def _setup_missing(
    data: str | os.PathLike[str], delimiter: str | None, decimal: str | None, columns: Columns
) -> str | None:
    """The line for a file read as the full pose (no setup) whose columns are another
    instrument's data: target coordinates (``NAME.x``, ``NAME.y``, ``NAME.z``) or a bar's
    reading (``d``) beside the legs, and no pose; None otherwise."""
    from hexcal.io.table_reading import read_table

    try:
        names = set(read_table(data, delimiter=delimiter, decimal=decimal, columns=columns).columns)
    except (InputError, OSError):
        return None
    if {"x", "y", "z"} <= names:
        return None
    targets = sorted({n[:-2] for n in names if n.endswith(".x") and {n[:-2] + ".y", n[:-2] + ".z"} <= names})
    if targets:
        return (
            f"{data}: the file looks like target positions ({', '.join(t + '.x/y/z' for t in targets[:4])}"
            f"{', ...' if len(targets) > 4 else ''}), not poses: --setup is missing (a setup with "
            "instrument_frame and targets for this file)"
        )
    if "d" in names:
        return (
            f"{data}: the file looks like ballbar readings (column d), not poses: --setup is missing "
            "(a ballbar setup)"
        )
    return None


def read_sessions(
    data: Sequence[str | os.PathLike[str]],
    setups: Sequence[str | os.PathLike[str] | Setup | MeasurementModel | None],
    euler: str,
    delimiter: str | None = None,
    decimal: str | None = None,
    columns: Columns = None,
) -> list[Session]:
    """Sessions of data files paired in order with setups: one setup for all files, one per
    file, or none (the full pose); labels are the file names, made unique; ``columns`` for
    every file (merged with each setup's own, :func:`merge_columns`)."""
    data = list(data)
    setups = list(setups)
    if not setups:
        setups = [None] * len(data)
    elif len(setups) == 1:
        setups = setups * len(data)
    elif len(setups) != len(data):
        raise InputError(
            f"{len(data)} data files and {len(setups)} setups: give one setup for all, or one per data file"
        )
    refuse_repeated_files(data)
    loaded: dict[Any, Any] = {}
    sessions = []
    for k, (path, setup) in enumerate(zip(data, setups, strict=True)):
        key = str(setup)
        if setup is not None and not isinstance(setup, Setup | BallbarSetup | MeasurementModel):
            if key not in loaded:
                loaded[key] = load_setup(setup)
            setup = loaded[key]
        label = Path(path).name
        if any(s.label == label for s in sessions):
            label = f"{label} ({k + 1})"
        sessions.append(read_session(path, setup, euler, delimiter, decimal, label, columns))
    return sessions


def refuse_repeated_files(paths: Sequence[str | os.PathLike[str]]) -> None:
    """Refuse a data file given twice (:class:`InputError` naming both): the same path, a link
    to it, or another file with the same bytes. A session counted twice makes every standard
    error and prediction √2 too optimistic."""
    import hashlib

    seen_paths: dict[str, str] = {}
    seen_bytes: dict[tuple[int, str], str] = {}
    for path in paths:
        name = str(path)
        try:
            real = os.path.realpath(path)
            size = os.path.getsize(real)
        except OSError:
            continue  # the reader says what is wrong with it
        if real in seen_paths:
            first = seen_paths[real]
            how = (
                f"{name} given twice"
                if first == name
                else f"{name} is a link to {first}"
                if os.path.islink(name)
                else f"{first} and {name} are one file"
            )
            raise InputError(f"the same session twice ({how}): each session counts once; give it once")
        seen_paths[real] = name
        digest = hashlib.sha256()
        try:
            with open(real, "rb") as fh:
                for chunk in iter(lambda: fh.read(1 << 20), b""):
                    digest.update(chunk)
        except OSError:
            continue
        key = (size, digest.hexdigest())
        if key in seen_bytes:
            raise InputError(
                f"the same session twice ({seen_bytes[key]} and {name} have the same bytes): each session "
                "counts once; give it once"
            )
        seen_bytes[key] = name


def save_setup_dict(setup: dict[str, Any] | None, path: str | os.PathLike[str]) -> None:
    """Write an instrument's setup mapping (:meth:`MeasurementModel.setup_dict`) as YAML,
    staged in the command's output set (or atomically)."""
    import yaml

    from hexcal.io.files import atomic_write, plain

    if setup is None:
        raise InputError(f"{path}: this instrument has no setup to write")
    text = yaml.safe_dump(plain(setup), sort_keys=False, default_flow_style=None)
    with atomic_write(path) as fh:
        fh.write(text)


def write_session_data(
    path: str | os.PathLike[str],
    session: Session,
    euler: str,
    orientation: str = "rad",
    comment: str | None = None,
) -> None:
    """Write a session's data in its instrument's file format, atomically."""
    try:
        writer = WRITERS[session.instrument.name]
    except KeyError:
        raise InputError(f"no writer of {session.instrument.name} data files") from None
    writer(path, session.data, euler, orientation, comment)
