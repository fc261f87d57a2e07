"""Geometry files (YAML, FORMATS.md) and presets by name."""

from __future__ import annotations

import os
from pathlib import Path

import yaml

from hexcal.core.geometry import Geometry
from hexcal.core.presets import PRESETS, preset
from hexcal.errors import GeometryError, InputError
from hexcal.io.files import atomic_write, plain


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


def save_geometry(geometry: Geometry, path: str | os.PathLike[str]) -> None:
    """Write a geometry as YAML (atomically)."""
    text = yaml.safe_dump(plain(geometry.to_dict()), sort_keys=False, default_flow_style=None)
    with atomic_write(path) as fh:
        fh.write(text)
