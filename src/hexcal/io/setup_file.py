"""Setup files (YAML, FORMATS.md "Measurement setup file"): read, validate, write."""

from __future__ import annotations

import os
from pathlib import Path

import yaml

from hexcal.errors import InputError
from hexcal.instruments.setup import Setup
from hexcal.io.files import atomic_write, plain


def load_setup(path: str | os.PathLike[str]) -> Setup:
    """A setup from a YAML file; every problem is one :class:`InputError` line naming the file."""
    path = Path(path)
    try:
        with open(path, encoding="utf-8") as fh:
            data = yaml.safe_load(fh)
    except FileNotFoundError:
        raise InputError(f"{path}: no such setup file") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a folder, not a setup file") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}: " if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise InputError(f"{path}: {where}not valid YAML ({problem})") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read: {exc}") from None
    try:
        return Setup.from_dict(data)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None


def save_setup(setup: Setup, path: str | os.PathLike[str]) -> None:
    """Write a setup (a calibrated one with its ``calibration`` mapping) as YAML, atomically."""
    text = yaml.safe_dump(plain(setup.to_dict()), sort_keys=False, default_flow_style=None)
    with atomic_write(path) as fh:
        fh.write(text)
