"""Setup files (YAML, docs/formats.md "Setup file"): read, validate, write."""

from __future__ import annotations

import os
from pathlib import Path

import yaml

from hexcal.errors import InputError, UsageError
from hexcal.instruments.ballbar_setup import BallbarSetup
from hexcal.instruments.setup import Setup
from hexcal.io.files import atomic_write, plain
from hexcal.io.inputs import load_yaml
from hexcal.io.tables import check_column_map


def load_setup(path: str | os.PathLike[str]) -> Setup | BallbarSetup:
    """A setup from a YAML file; every problem is one :class:`InputError` line naming the file.

    Read like a geometry file, with :func:`hexcal.io.inputs.load_yaml`: regular files only,
    safe tags, a size limit, limits on nesting and on aliases (an alias bomb fails at once),
    and no key given twice in a mapping. A ``columns`` mapping (how the instrument's data files
    name their columns) must use hexcal's column names, each file column once. A mapping with
    a ``ballbar`` key is a ballbar setup (:class:`~hexcal.instruments.BallbarSetup`, docs/ballbar.md).
    """
    path = Path(path)
    if not os.path.lexists(path):
        raise InputError(f"{path}: no such setup file")
    if path.is_dir():
        raise InputError(f"{path}: is a folder, not a setup file")
    data = load_yaml(path, "YAML")
    try:
        if isinstance(data, dict) and "ballbar" in data:
            setup: Setup | BallbarSetup = BallbarSetup.from_dict(data)
        else:
            setup = Setup.from_dict(data)
        check_column_map(setup.columns)
    except (InputError, UsageError) as exc:
        text = str(exc).replace("column map: ", "columns: ", 1)
        raise InputError(f"{path}: {text}") from None
    return setup


def save_setup(setup: Setup | BallbarSetup, path: str | os.PathLike[str]) -> None:
    """Write a setup (a calibrated one with its ``calibration`` mapping) as YAML, atomically."""
    text = yaml.safe_dump(plain(setup.to_dict()), sort_keys=False, default_flow_style=None)
    with atomic_write(path) as fh:
        fh.write(text)
