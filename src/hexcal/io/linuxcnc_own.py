"""What ``import linuxcnc`` reads back of hexcal's own export beyond LinuxCNC's keys: the
geometry's name (a header comment), and for a geometry whose angles are not G-code's A B C,
its sequence (a header comment) and its angle box (``[AXIS_A..C] HEXCAL_MIN_LIMIT`` and
``HEXCAL_MAX_LIMIT``, which LinuxCNC ignores): :func:`hexcal.io.linuxcnc.export_linuxcnc`
writes them.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.io.linuxcnc import LINUXCNC_EULER

_NAME = re.compile(r"^# source geometry: .* \(name (?P<name>[^()\n]+)\)$", re.MULTILINE)
_EULER = re.compile(
    r"^#   NOTE: this geometry's poses use the sequence '(?P<euler>[xyzXYZ]{3})'", re.MULTILINE
)


def exported_name(hal_text: str, ini_text: str | None) -> str | None:
    """The geometry's name in the header of hexcal's export (the INI's, else the HAL's)."""
    found = _NAME.search(ini_text or "") or _NAME.search(hal_text)
    return found["name"] if found else None


def exported_sequence(
    ini_text: str | None, ini: Any, scale: float
) -> tuple[str, NDArray[np.float64] | None] | None:
    """``(sequence, workspace)`` of hexcal's export of a geometry whose angles are in another
    sequence than G-code's (None otherwise): the workspace from ``[AXIS_X..Z] MIN_LIMIT``,
    ``MAX_LIMIT`` (machine units, times ``scale``) and ``[AXIS_A..C] HEXCAL_MIN_LIMIT``,
    ``HEXCAL_MAX_LIMIT`` (degrees of that sequence), None when one is missing."""
    found = _EULER.search(ini_text or "")
    if found is None or found["euler"] == LINUXCNC_EULER:
        return None
    if ini is None:
        return found["euler"], None
    box = []
    for axis in "XYZABC":
        prefix = "" if axis in "XYZ" else "HEXCAL_"
        section = f"AXIS_{axis}"
        lo, hi = ini.number(section, prefix + "MIN_LIMIT"), ini.number(section, prefix + "MAX_LIMIT")
        if lo is None or hi is None or lo > hi:
            return found["euler"], None
        box.append((lo, hi))
    arr = np.array(box, dtype=float)
    arr[:3] *= scale
    arr[3:] = np.deg2rad(arr[3:])
    return found["euler"], arr
