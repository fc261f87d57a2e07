"""Setup files (YAML, docs/formats.md "Setup file"): read, validate, write."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import yaml

from hexcal.errors import InputError, UsageError
from hexcal.instruments.registry import setup_class_for
from hexcal.io.files import atomic_write, plain
from hexcal.io.inputs import load_yaml
from hexcal.io.tables import check_column_map


def load_setup(path: str | os.PathLike[str]) -> Any:
    """A setup from a YAML file; every problem is one :class:`InputError` line naming the file.

    Read like a geometry file, with :func:`hexcal.io.inputs.load_yaml`: regular files only,
    safe tags, a size limit, limits on nesting and on aliases (an alias bomb fails at once),
    and no key given twice in a mapping. A ``columns`` mapping (how the instrument's data files
    name their columns) must use hexcal's column names, each file column once. A mapping with
    the key of a registered instrument kind (:attr:`~hexcal.instruments.InstrumentKind.setup_key`:
    ``ballbar``, docs/ballbar.md) is that kind's setup; any other a
    :class:`~hexcal.instruments.Setup` (targets or a tool).
    """
    path = Path(path)
    if not os.path.lexists(path):
        raise InputError(f"{path}: no such setup file")
    if path.is_dir():
        raise InputError(f"{path}: is a folder, not a setup file")
    data = load_yaml(path, "YAML")
    try:
        setup = setup_class_for(data).from_dict(data)
        check_column_map(getattr(setup, "columns", None))
    except (InputError, UsageError) as exc:
        text = str(exc).replace("column map: ", "columns: ", 1)
        raise InputError(f"{path}: {text}") from None
    return setup


def save_setup(setup: Any, path: str | os.PathLike[str]) -> None:
    """Write a setup (a calibrated one with its ``calibration`` mapping) as YAML, atomically."""
    text = yaml.safe_dump(plain(setup.to_dict()), sort_keys=False, default_flow_style=None)
    with atomic_write(path) as fh:
        fh.write(text)
