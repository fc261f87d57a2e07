"""Writing files safely: atomic replacement, and values made plain for YAML and JSON.

Every output of hexcal is staged in a temporary file in the target's folder and renamed by
:class:`hexcal.io.outputs.OutputSet`, so that an output file is either complete or absent.
Input files are only ever opened for reading.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from typing import IO, Any

import numpy as np

from hexcal.io.outputs import OutputError, OutputSet, output_file


def plain(value: Any) -> Any:
    """Convert numpy scalars and arrays inside ``value`` to plain Python for YAML/JSON."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


@contextmanager
def atomic_write(path: str | os.PathLike[str], outputs: OutputSet | None = None) -> Iterator[IO[str]]:
    """A text handle (UTF-8) on a staged copy of ``path``, put in place only on success.

    Goes through :func:`hexcal.io.outputs.output_file`: inside a command's
    ``with OutputSet(...)`` block (or with ``outputs``) the file is committed with the
    command's other outputs; alone, it is committed when the ``with`` block ends. Every
    rule of :class:`~hexcal.io.outputs.OutputSet` applies (no special files, modes kept,
    symbolic links written through, read-only and hard-linked files refused).
    """
    with output_file(path, "w", outputs) as fh:
        yield fh


def _non_finite(value: Any, where: str = "") -> str | None:
    """The key path of the first NaN or infinity inside ``value`` (plain data), or None."""
    if isinstance(value, float) and not math.isfinite(value):
        return where or "the value"
    if isinstance(value, dict):
        items: Iterable[tuple[str, Any]] = (
            (f"{where}.{k}" if where else str(k), v) for k, v in value.items()
        )
    elif isinstance(value, list):
        items = ((f"{where}[{k}]", v) for k, v in enumerate(value))
    else:
        return None
    for key, item in items:
        found = _non_finite(item, key)
        if found is not None:
            return found
    return None


def write_json(path: str | os.PathLike[str], data: Any, outputs: OutputSet | None = None) -> None:
    """Write ``data`` as strict JSON (indent 2); NaN or infinity is refused, naming its key.

    Strict JSON has no NaN: a reader of hexcal's JSON must not meet one. The caller turns
    an undefined value into ``None`` (``null``) if it means "not available".
    """
    data = plain(data)
    bad = _non_finite(data)
    if bad is not None:
        raise OutputError(f"{path}: {bad} is not a finite number; strict JSON cannot hold it")
    text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    with atomic_write(path, outputs) as fh:
        fh.write(text)


def write_text(path: str | os.PathLike[str], text: str, outputs: OutputSet | None = None) -> None:
    """Write ``text`` (UTF-8) through the output set; ``-`` is standard output."""
    with atomic_write(path, outputs) as fh:
        fh.write(text)
