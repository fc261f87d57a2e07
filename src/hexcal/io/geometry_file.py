"""Geometry files (YAML, docs/formats.md "Geometry file") and presets by name."""

from __future__ import annotations

import os
from pathlib import Path

import yaml

from hexcal.core.geometry import Geometry
from hexcal.core.presets import PRESETS, preset
from hexcal.errors import GeometryError, InputError
from hexcal.io.files import atomic_write, plain
from hexcal.io.inputs import load_yaml, parse_yaml
from hexcal.io.outputs import OutputSet


def load_geometry(spec: str | os.PathLike[str]) -> Geometry:
    """A geometry from a preset name or a YAML file (docs/formats.md "Geometry file").

    The file must be a regular file; it is read with :func:`hexcal.io.inputs.load_yaml`
    (safe tags only, limits on nesting and on aliases), validated by :class:`Geometry` and
    :meth:`Geometry.check_plausible` (distinct joints, home pose inside the limits).
    """
    if isinstance(spec, str) and spec in PRESETS:
        return preset(spec)
    path = Path(spec)
    if not os.path.lexists(path):
        raise InputError(f"{path}: no such geometry file (and not a preset: {', '.join(PRESETS)})")
    data = load_yaml(path, "YAML")
    try:
        geometry = Geometry.from_dict(data)
        geometry.check_plausible()
        return geometry
    except GeometryError as exc:
        raise InputError(f"{path}: {exc}") from None


def save_geometry(geometry: Geometry, path: str | os.PathLike[str], outputs: OutputSet | None = None) -> None:
    """Write a geometry as YAML (staged in ``outputs`` or the active output set, or atomically).

    The text is checked first with the rules of :func:`load_geometry` (:func:`check_geometry_text`):
    hexcal never writes a geometry file it would refuse to read.
    """
    text = yaml.safe_dump(plain(geometry.to_dict()), sort_keys=False, default_flow_style=None)
    check_geometry_text(text, os.fspath(path))
    with atomic_write(path, outputs) as fh:
        fh.write(text)


def check_geometry_text(text: str, name: str) -> Geometry:
    """The geometry of a YAML text, read and checked as :func:`load_geometry` reads a file;
    :class:`GeometryError` naming ``name`` (the file about to be written) otherwise."""
    try:
        geometry = Geometry.from_dict(parse_yaml(text, name))
        geometry.check_plausible()
    except (GeometryError, InputError) as exc:
        reason = str(exc).removeprefix(f"{name}: ")
        raise GeometryError(
            f"{name}: not written: hexcal would refuse to read this geometry ({reason})"
        ) from None
    return geometry
