"""LinuxCNC joint compensation tables (``[JOINT_N] COMP_FILE``) of a stroke-dependent leg model.

genhexkins commands each strut's length ``L`` as the joint position. With the joint's scale
corrected by its gain and ``HOME_OFFSET = l0`` (:mod:`hexcal.io.linuxcnc`), a motor position
``M`` is the reading ``dl = (M - l0) / g``, and a leg whose length follows a curve of its
reading (:class:`hexcal.core.stroke_legs.StrokeLegs`) is then ``l(dl) = l0 + g dl + c(dl)``
long, not ``M``. LinuxCNC's joint compensation adds a trim to the commanded position before
it goes to the motor: ``motor = L + trim(L)``, the trim interpolated linearly between the
table's entries. The trim that brings the leg to ``L`` is

    trim(L) = l0 + g dl(L) - L,   dl(L) the reading whose length is L  (the model's inverse),

so each table entry is the pair ``(L_k, trim_k)`` of a reading ``dl_k`` on the leg's stroke:
``L_k = l(dl_k)``, ``trim_k = l0 + g dl_k - L_k = -c(dl_k)``: exact at the entries, no inverse
needed. :func:`comp_tables` spaces the readings evenly over the stroke, its ends the first and
last entries, and doubles their number until the linear interpolation is within a tolerance
everywhere on the stroke (at most :data:`MAX_ENTRIES`, LinuxCNC's ``EMCMOT_COMP_SIZE``).

Beyond its first and last entries LinuxCNC holds the end trims: its table starts with an entry
at ``-DBL_MAX`` whose trim is set to the first entry's with slope 0, and the last entry keeps
slope 0 (``EMCMOT_SET_JOINT_COMP`` in ``src/emc/motion/command.c``, ``compute_screw_comp`` in
``src/emc/motion/control.c``). A held trim ``-c(end)`` is the stroke model's own continuation,
the curve held at its end value (``l = l0 + g dl + c(end)``), so the table agrees with the
model at every joint position, the home switch (reading 0) included wherever it lies: no
entry beyond the stroke is needed.

Homing sets the joint position to ``HOME_OFFSET`` at the switch (reading 0) with the trim
there, so the motor's travel from the switch is ``L + trim(L) - HOME_OFFSET - trim(HOME_OFFSET)``;
that is ``g dl(L)`` for every ``L`` when ``HOME_OFFSET = l(0)``, the model's length at reading 0
(``l0`` for linear legs), which the export writes.

The file (``COMP_FILE_TYPE = 1``): one line per entry, ``nominal forward_trim reverse_trim``
(mm), the same trim both ways (no backlash is modelled). LinuxCNC reads lines while they hold
three numbers and stops at the first that does not (``usrmotLoadComp`` in
``src/emc/motion/usrmotintf.cc``), so the file holds numbers only: what it is, and the model,
are said in the INI's comments. ``COMP_FILE_TYPE = 0`` files (``nominal forward reverse``,
the positions reached, trim = nominal - position) are read too. The nominal positions must
increase (LinuxCNC refuses the entry otherwise).

:func:`stroke_from_tables` reads tables back into the leg model: each entry is a point
``(dl_k, c_k)`` of the curve, ``dl_k = (L_k + trim_k - l0) / g``, ``c_k = -trim_k``, and the
model's terms are the least-squares fit of its series to them (exact, to rounding, for a table
written here).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.stroke_legs import StrokeLegs, legendre_values
from hexcal.errors import LinuxCNCFormatError

#: The per-joint table files ``export linuxcnc`` writes beside the INI (joint ``N`` = leg ``N+1``).
COMP_FILES = tuple(f"hexcal-comp-{n}.tbl" for n in range(6))

#: LinuxCNC keeps at most this many entries per joint (``EMCMOT_COMP_SIZE`` in motion.h).
MAX_ENTRIES = 256

#: Default largest error of the table's linear interpolation on the stroke, mm (1 µm).
TABLE_TOLERANCE = 1e-3

#: Readings per leg at which the interpolation error is checked.
_CHECK_POINTS = 4097


@dataclass(frozen=True)
class CompTable:
    """One joint's table: ``nominal`` joint positions (strut lengths, mm, increasing) and the
    ``trim`` (mm) LinuxCNC adds there; ``max_error`` is the largest error of its interpolation
    on the stroke (mm; NaN for a table read from a file)."""

    nominal: NDArray[np.float64]
    trim: NDArray[np.float64]
    max_error: float = float("nan")


def _entries(geometry: Geometry, low: NDArray, high: NDArray, count: int) -> tuple[NDArray, NDArray]:
    """Lengths and trims ``(count, 6)`` at ``count`` readings spread evenly over each stroke."""
    dl = low + np.linspace(0.0, 1.0, count)[:, None] * (high - low)
    lengths = geometry.leg_model.lengths(geometry.leg_block(), dl)
    return lengths, geometry.initial_leg_lengths + geometry.leg_gains * dl - lengths


def comp_tables(geometry: Geometry, tolerance: float = TABLE_TOLERANCE) -> list[CompTable]:
    """The six joints' compensation tables of a geometry whose leg model has a stroke.

    Raises
    ------
    GeometryError
        If the model's length does not grow with the reading on a leg's stroke (no table
        can describe it).
    ValueError
        If the geometry's leg model has no stroke (linear legs need no table).
    """
    model = geometry.leg_model
    ranges = model.stroke_range()
    if ranges is None:
        raise ValueError(f"the {model.name} leg model has no stroke to tabulate")
    model.check_invertible(geometry.leg_block())
    # the stroke's ends are the table's: beyond them LinuxCNC holds the end trims, which is the
    # model's own continuation (the curve held), so no entry beyond the stroke is needed
    low, high = ranges
    fine_l, fine_t = _entries(geometry, low, high, _CHECK_POINTS)
    tables: list[CompTable | None] = [None] * 6
    count = 9
    while any(t is None for t in tables):
        nominal, trim = _entries(geometry, low, high, count)
        for leg in range(6):
            if tables[leg] is not None:
                continue
            between = np.interp(fine_l[:, leg], nominal[:, leg], trim[:, leg])
            error = float(np.max(np.abs(between - fine_t[:, leg])))
            if error <= tolerance or count >= MAX_ENTRIES:
                tables[leg] = CompTable(nominal[:, leg].copy(), trim[:, leg].copy(), error)
        count = min(2 * count - 1, MAX_ENTRIES)
    return [t for t in tables if t is not None]


def _num(value: float) -> str:
    return repr(float(value))


def format_comp_table(table: CompTable) -> str:
    """The ``COMP_FILE_TYPE = 1`` text of a table: numbers only, one entry per line."""
    return "".join(f"{_num(n)} {_num(t)} {_num(t)}\n" for n, t in zip(table.nominal, table.trim, strict=True))


def parse_comp_table(text: str, name: str, file_type: int = 0) -> CompTable:
    """A table from a LinuxCNC compensation file (``file_type`` its ``COMP_FILE_TYPE``).

    Every non-blank line must hold three finite numbers (LinuxCNC would silently stop at the
    first that does not, dropping the rest of the table): otherwise
    :class:`~hexcal.io.linuxcnc.LinuxCNCFormatError` names the file and line. Forward and
    reverse trims must agree (hexcal models no backlash), the nominal positions increase.
    """
    if file_type not in (0, 1):
        raise LinuxCNCFormatError(f"{name}: COMP_FILE_TYPE must be 0 or 1, got {file_type}")
    rows = []
    for lineno, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        parts = line.split()
        try:
            values = [float(p) for p in parts]
        except ValueError:
            values = []
        if len(values) != 3 or not all(np.isfinite(values)):
            raise LinuxCNCFormatError(
                f"{name}: line {lineno}: not three numbers 'nominal forward reverse' (LinuxCNC would stop "
                "reading the table here)"
            )
        rows.append((lineno, *values))
    if not rows:
        raise LinuxCNCFormatError(f"{name}: no table entry")
    if len(rows) > MAX_ENTRIES:
        raise LinuxCNCFormatError(f"{name}: {len(rows)} entries; LinuxCNC keeps at most {MAX_ENTRIES}")
    data = np.array(rows)
    nominal = data[:, 1]
    if file_type == 1:
        forward, reverse = data[:, 2], data[:, 3]
    else:  # the positions reached: LinuxCNC's trim is nominal - position
        forward, reverse = nominal - data[:, 2], nominal - data[:, 3]
    drop = np.flatnonzero(np.diff(nominal) <= 0)
    if drop.size:
        raise LinuxCNCFormatError(
            f"{name}: line {int(data[drop[0] + 1, 0])}: the nominal positions must increase (LinuxCNC "
            "refuses this entry)"
        )
    apart = np.flatnonzero(np.abs(forward - reverse) > 1e-9 * (1 + np.abs(nominal)))
    if apart.size:
        raise LinuxCNCFormatError(
            f"{name}: line {int(data[apart[0], 0])}: forward and reverse differ (backlash): hexcal's leg "
            "models have none"
        )
    return CompTable(nominal, forward)


def stroke_from_tables(
    geometry: Geometry, tables: list[CompTable], degree: int, low: NDArray, high: NDArray
) -> tuple[Geometry, float]:
    """``geometry`` (linear legs, its ``l0`` and gains those of the tables' machine) with the
    stroke model of ``degree`` over ``[low, high]`` fitted to the tables' points on the stroke,
    and the largest residual of the model at all the points (mm; those beyond the stroke are
    held there, as LinuxCNC holds a table's end trims)."""
    model = StrokeLegs(degree, low, high)
    terms = np.zeros((6, len(model.terms)))
    worst = 0.0
    l0, gains = geometry.initial_leg_lengths, geometry.leg_gains
    for leg, table in enumerate(tables):
        dl = (table.nominal + table.trim - l0[leg]) / gains[leg]
        curve = -table.trim
        x = (2 * dl - low[leg] - high[leg]) / (high[leg] - low[leg])
        basis = legendre_values(np.clip(x, -1.0, 1.0), degree)[0][:, 2:]
        on = np.abs(x) <= 1 + 1e-9  # a table of another stroke: its points on this one decide
        if np.sum(on) < basis.shape[1]:
            raise LinuxCNCFormatError(
                f"joint {leg}: {int(np.sum(on))} table entries on the stroke [{low[leg]:g}, {high[leg]:g}] "
                f"cannot determine the {basis.shape[1]} stroke terms"
            )
        terms[leg], *_ = np.linalg.lstsq(basis[on], curve[on], rcond=None)
        worst = max(worst, float(np.max(np.abs(basis @ terms[leg] - curve))))
    return geometry.replace(leg_model=model, leg_terms=terms), worst


#: Degree of the stroke model fitted to tables without ``HEXCAL_STROKE_DEGREE``.
DEFAULT_IMPORT_DEGREE = 3


def import_comp_tables(
    geometry: Geometry, ini: Any, read: Callable[[str], str] | None, warnings: list[str]
) -> Geometry:
    """``geometry`` with the leg model of the INI's ``[JOINT_N] COMP_FILE`` tables (unchanged
    when no joint has one). ``read`` gives a ``COMP_FILE`` value's text (the files sit beside
    the INI); the stroke and degree are ``HEXCAL_STROKE`` and ``HEXCAL_STROKE_DEGREE``, else the
    tables' reading range and :data:`DEFAULT_IMPORT_DEGREE` (said in ``warnings``)."""
    files = [ini.get(f"JOINT_{n}", "COMP_FILE") for n in range(6)]
    named = [n for n, f in enumerate(files) if f is not None]
    if not named:
        return geometry
    if len(named) < 6:
        missing = ", ".join(str(n) for n in range(6) if n not in named)
        raise LinuxCNCFormatError(
            f"{ini.name}: joints {', '.join(map(str, named))} have a COMP_FILE and joint(s) {missing} none: "
            "a leg model holds for every leg; give each joint its table"
        )
    if read is None:
        raise LinuxCNCFormatError(f"{ini.name}: joints with COMP_FILE tables: give a reader of their files")
    tables, degrees, strokes = [], set(), []
    for n, (value, _) in enumerate(files):  # type: ignore[misc]
        kind = ini.number(f"JOINT_{n}", "COMP_FILE_TYPE")
        kind = 0 if kind is None else kind
        if kind not in (0, 1):
            raise LinuxCNCFormatError(f"{ini.name}: [JOINT_{n}] COMP_FILE_TYPE must be 0 or 1, got {kind:g}")
        tables.append(parse_comp_table(read(value.strip()), value.strip(), int(kind)))
        degree = ini.number(f"JOINT_{n}", "HEXCAL_STROKE_DEGREE")
        degrees.add(DEFAULT_IMPORT_DEGREE if degree is None else degree)
        strokes.append(ini.numbers(f"JOINT_{n}", "HEXCAL_STROKE"))
    if len(degrees) > 1:
        raise LinuxCNCFormatError(f"{ini.name}: the joints' HEXCAL_STROKE_DEGREE differ ({sorted(degrees)})")
    degree = degrees.pop()
    if degree != int(degree):
        raise LinuxCNCFormatError(f"{ini.name}: HEXCAL_STROKE_DEGREE must be an integer, got {degree:g}")
    # HOME_OFFSET is the strut length at reading 0, l0 + c(0), and trim(HOME_OFFSET) = -c(0)
    home, gains = geometry.initial_leg_lengths, geometry.leg_gains
    l0 = home + np.array([np.interp(home[n], t.nominal, t.trim) for n, t in enumerate(tables)])
    if all(s is not None and len(s) == 2 for s in strokes):
        low, high = np.array([s[0] for s in strokes]), np.array([s[1] for s in strokes])  # type: ignore[index]
    else:
        reach = [(t.nominal + t.trim - l0[n]) / gains[n] for n, t in enumerate(tables)]
        low, high = np.array([r.min() for r in reach]), np.array([r.max() for r in reach])
        warnings.append(
            f"{ini.name}: no HEXCAL_STROKE: each leg's stroke is its table's range of readings, "
            f"degree {degree:g}"
        )
    for _ in range(3):  # l0 with the curve's own value at reading 0 (exact, not interpolated)
        start = geometry.replace(initial_leg_lengths=l0)
        fitted, worst = stroke_from_tables(start, tables, int(degree), low, high)
        l0 = home - (fitted.leg_model.lengths(fitted.leg_block(), np.zeros(6)) - l0)
    if worst > 1e-6:
        warnings.append(
            f"{ini.name}: the stroke model of degree {degree:g} follows the tables within {worst:.3g} mm"
        )
    return fitted
