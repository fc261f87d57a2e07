"""Setup files (YAML, docs/formats.md "Setup file"): read, validate, write."""

from __future__ import annotations

import os
from pathlib import Path

import yaml

from hexcal.errors import InputError
from hexcal.instruments.setup import Setup
from hexcal.io.files import atomic_write, plain
from hexcal.io.inputs import load_yaml


def load_setup(path: str | os.PathLike[str]) -> Setup:
    """A setup from a YAML file; every problem is one :class:`InputError` line naming the file.

    Read like a geometry file, with :func:`hexcal.io.inputs.load_yaml`: regular files only,
    safe tags, a size limit, limits on nesting and on aliases (an alias bomb fails at once),
    and no key given twice in a mapping.
    """
    path = Path(path)
    if not os.path.lexists(path):
        raise InputError(f"{path}: no such setup file")
    if path.is_dir():
        raise InputError(f"{path}: is a folder, not a setup file")
    data = load_yaml(path, "YAML")
    try:
        return Setup.from_dict(data)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None


def save_setup(setup: Setup, path: str | os.PathLike[str]) -> None:
    """Write a setup (a calibrated one with its ``calibration`` mapping) as YAML, atomically."""
    text = yaml.safe_dump(plain(setup.to_dict()), sort_keys=False, default_flow_style=None)
    with atomic_write(path) as fh:
        fh.write(text)
