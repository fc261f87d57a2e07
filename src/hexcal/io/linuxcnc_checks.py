"""What ``import linuxcnc`` checks of compensation tables, by the rules of what will read the
geometry it writes (:mod:`hexcal.io.linuxcnc_import`): tables that describe a leg, a
``HEXCAL_STROKE`` that covers them, and a fitted stroke model that ``ik``, ``fk`` and
``export`` accept and that gives LinuxCNC's trims. Each refusal is one
:class:`~hexcal.io.linuxcnc.LinuxCNCFormatError` line naming the file.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from hexcal.core.geometry import Geometry
from hexcal.errors import GeometryError
from hexcal.io.linuxcnc import LinuxCNCFormatError

#: How far (mm) the imported leg model may miss a compensation table's trim before the tables
#: are refused as not describing it: the tables' own trims are a few tenths of a millimetre; a
#: model that misses by a millimetre makes LinuxCNC and hexcal disagree on every move there.
TABLE_MISS_LIMIT = 1.0


def comp_file_tables(ini: Any, read: Callable[[str], str] | None) -> list[tuple[str, Any]]:
    """``(file name, table)`` of each joint's ``COMP_FILE`` (none when a joint lacks one or no
    reader is given: :func:`hexcal.io.linuxcnc_comp.import_comp_tables` says why)."""
    from hexcal.io.linuxcnc_comp import parse_comp_table

    files = [ini.get(f"JOINT_{n}", "COMP_FILE") for n in range(6)]
    if read is None or any(f is None for f in files):
        return []
    out = []
    for n, (value, _) in enumerate(files):  # type: ignore[misc]
        kind = ini.number(f"JOINT_{n}", "COMP_FILE_TYPE")
        kind = 0 if kind is None else kind
        if kind not in (0, 1):
            return []  # refused by the import, naming the key
        out.append((value.strip(), parse_comp_table(read(value.strip()), value.strip(), int(kind))))
    return out


def check_comp_tables(ini: Any, tables: list[tuple[str, Any]], geometry: Geometry) -> None:
    """Refuse (one line) compensation tables that describe no leg, before a model is fitted:

    - a trim larger than the leg's travel (its joint limits' range, else the table's span);
    - motor positions (joint position + trim) that do not increase with the joint position:
      a leg's reading grows with its length;
    - a ``HEXCAL_STROKE`` that does not cover the table's readings (the export widens the
      stroke only to the home switch's reading 0).

    ``geometry`` gives the joints' ``HOME_OFFSET`` (its ``l0``, reading 0) and gains.
    """
    limits = geometry.leg_length_limits
    for n, (name, table) in enumerate(tables):
        travel = (limits[1] - limits[0]) if limits is not None else float(np.ptp(table.nominal))
        big = np.flatnonzero(np.abs(table.trim) > travel)
        if big.size:
            k = int(big[0])
            raise LinuxCNCFormatError(
                f"{name}: entry {k + 1} (joint position {table.nominal[k]:g}): a trim of "
                f"{table.trim[k]:g} mm, more than the leg's whole travel ({travel:g} mm): the table does "
                "not describe a leg (check COMP_FILE_TYPE: 0 positions reached, 1 trims)"
            )
        motor = table.nominal + table.trim
        back = np.flatnonzero(np.diff(motor) <= 0)
        if back.size:
            k = int(back[0])
            raise LinuxCNCFormatError(
                f"{name}: entries {k + 1} and {k + 2} (joint positions {table.nominal[k]:g}, "
                f"{table.nominal[k + 1]:g}): the motor would go back from {motor[k]:g} to "
                f"{motor[k + 1]:g} mm while the joint extends; the table does not describe a leg"
            )
        given = ini.numbers(f"JOINT_{n}", "HEXCAL_STROKE")
        if given is not None and len(given) == 2:
            home = geometry.initial_leg_lengths[n]  # HOME_OFFSET: the joint position at reading 0
            readings = (motor - home - np.interp(home, table.nominal, table.trim)) / geometry.leg_gains[n]
            low, high = min(given[0], 0.0), given[1]
            slack = 1e-6 * (1.0 + abs(high - low))
            if readings.min() < low - slack or readings.max() > high + slack:
                raise LinuxCNCFormatError(
                    f"{ini.name}: [JOINT_{n}] HEXCAL_STROKE = {given[0]:g} {given[1]:g} does not cover the "
                    f"readings of {name} ({readings.min():.6g} to {readings.max():.6g}): give the stroke the "
                    "table was made from (and check COMP_FILE_TYPE: 0 positions reached, 1 trims)"
                )


def check_imported_model(geometry: Geometry, ini_name: str, tables: list[tuple[str, Any]]) -> None:
    """Refuse (one line) a leg model fitted to compensation tables that the commands reading the
    geometry would refuse (``ik``, ``fk``, ``export``: a length without a reading on a leg's
    limits), or that misses, at an entry within the limits, the trim LinuxCNC applies there by
    more than :data:`TABLE_MISS_LIMIT`."""
    model, block = geometry.leg_model, geometry.leg_block()
    limits = geometry.leg_length_limits
    for n, (name, table) in enumerate(tables):
        inside = table.nominal
        if limits is not None:
            inside = inside[(inside >= limits[0]) & (inside <= limits[1])]
        if not inside.size:
            continue
        full = np.tile(geometry.initial_leg_lengths, (len(inside), 1))
        full[:, n] = inside
        try:
            dl = model.readings(block, full)[:, n]
        except GeometryError as exc:
            raise LinuxCNCFormatError(
                f"{ini_name}: the COMP_FILE tables do not describe a leg: under the stroke model fitted to "
                f"them, {exc} (check COMP_FILE_TYPE: 0 positions reached, 1 trims)"
            ) from None
        trim = geometry.initial_leg_lengths[n] + geometry.leg_gains[n] * dl - inside
        want = np.interp(inside, table.nominal, table.trim)
        miss = np.abs(trim - want)
        k = int(np.argmax(miss))
        if miss[k] > TABLE_MISS_LIMIT:
            raise LinuxCNCFormatError(
                f"{name}: at joint position {inside[k]:g} LinuxCNC applies the trim {want[k]:g} mm, the "
                f"stroke model fitted to the tables {trim[k]:.6g} mm: the tables do not describe a leg of "
                "this model (check COMP_FILE_TYPE and HEXCAL_STROKE_DEGREE)"
            )
