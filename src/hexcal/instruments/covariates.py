"""Per-pose covariates: when each pose was measured, the legs' temperatures, the payload.

The optional columns of measurement, leg and pose files (docs/formats.md "Covariates"):
``time`` (s, any origin, strictly increasing: the rows are in acquisition order),
``temp1 ... temp6`` (each leg's temperature, °C) or ``temp`` (one temperature for every
leg), ``payload_kg`` (kg) and its centre of mass ``payload_x, payload_y, payload_z`` (mm,
platform frame). :class:`Covariates` holds them for the rows of one data set; every data
class carries one (none present by default), and a leg model that uses a covariate asks for
it with :meth:`Covariates.require`.

What is refused, and why, is decided here (:func:`check_columns`, :func:`value_problem`), for
the file readers (which name the file, line and column) and for data built in Python alike.
Imports :mod:`hexcal.errors` only.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Collection, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.errors import InputError, UsageError

TIME_COLUMN = "time"
ONE_TEMPERATURE_COLUMN = "temp"
TEMPERATURE_COLUMNS = tuple(f"temp{i}" for i in range(1, 7))
PAYLOAD_MASS_COLUMN = "payload_kg"
PAYLOAD_COM_COLUMNS = ("payload_x", "payload_y", "payload_z")
#: Every covariate column, in the order hexcal writes them.
COVARIATE_COLUMNS = (
    TIME_COLUMN,
    ONE_TEMPERATURE_COLUMN,
    *TEMPERATURE_COLUMNS,
    PAYLOAD_MASS_COLUMN,
    *PAYLOAD_COM_COLUMNS,
)

#: Temperatures (°C) outside this range are refused: no machine hall or running machine is
#: colder or hotter; a value of 213 to 473 is a plausible temperature in kelvin, and said so.
TEMPERATURE_RANGE = (-60.0, 200.0)
#: A payload heavier than this (kg) is refused: more than the largest motion-simulator
#: hexapods carry (about 15 t), so more likely grams than kilograms.
PAYLOAD_MAX_KG = 100_000.0

#: The quantities :meth:`Covariates.names` lists, and how a message names each.
QUANTITIES = {
    "time": "the time of each pose (column time, s)",
    "temperatures": "the legs' temperatures (columns temp1 ... temp6, or temp, °C)",
    "payload_kg": "the payload's mass (column payload_kg)",
    "payload_com": "the payload's centre of mass (columns payload_x, payload_y, payload_z, mm)",
}

_KELVIN = 273.15


def _listed(names: Iterable[str]) -> str:
    return ", ".join(names)


def check_columns(columns: Collection[str], label: Callable[[str], str] = str) -> tuple[str, ...]:
    """The covariate columns among ``columns`` (hexcal's names), in :data:`COVARIATE_COLUMNS`
    order; a set that cannot be read raises a one-line :class:`~hexcal.errors.UsageError`
    naming the columns by ``label`` (a file's own names under a column map).

    Refused: ``temp`` with any of ``temp1 ... temp6``; some of ``temp1 ... temp6`` but not
    all; some of ``payload_x, payload_y, payload_z`` but not all; a centre of mass without
    ``payload_kg``.

    >>> check_columns(["id", "x", "payload_kg", "time"])
    ('time', 'payload_kg')
    """
    present = tuple(c for c in COVARIATE_COLUMNS if c in columns)
    if not present:
        return ()
    temps = [c for c in TEMPERATURE_COLUMNS if c in present]
    if ONE_TEMPERATURE_COLUMN in present and temps:
        raise UsageError(
            f"columns '{label(ONE_TEMPERATURE_COLUMN)}' and '{label(temps[0])}' both give leg "
            "temperatures: give temp (one for every leg) or temp1 ... temp6, not both"
        )
    if temps and len(temps) < 6:
        missing = _listed(label(c) for c in TEMPERATURE_COLUMNS if c not in temps)
        raise UsageError(
            f"leg temperatures {_listed(label(c) for c in temps)} without {missing}: give all six "
            "(temp1 ... temp6), or one column temp for every leg"
        )
    com = [c for c in PAYLOAD_COM_COLUMNS if c in present]
    if com and len(com) < 3:
        missing = _listed(label(c) for c in PAYLOAD_COM_COLUMNS if c not in com)
        raise UsageError(
            f"the payload's centre of mass needs payload_x, payload_y and payload_z; {missing} missing"
        )
    if com and PAYLOAD_MASS_COLUMN not in present:
        raise UsageError(
            f"columns {_listed(label(c) for c in com)} give the payload's centre of mass, but there "
            f"is no column '{label(PAYLOAD_MASS_COLUMN)}' (its mass, kg)"
        )
    return present


def value_problem(name: str, values: ArrayLike) -> tuple[NDArray[np.intp], str] | None:
    """The rows of covariate column ``name`` whose values are refused (the first first) and
    why the first is, or None when every value is accepted.

    Refused: NaN or infinity; a temperature outside :data:`TEMPERATURE_RANGE` (kelvin said
    so); a negative payload mass or one beyond :data:`PAYLOAD_MAX_KG`; a ``time`` not after the
    row before's (the rows are in acquisition order).

    >>> rows, why = value_problem("time", [0.0, 1.0, 1.0, 3.0])
    >>> rows.tolist(), why
    ([2], "1 s is not after the row before's 1 s: rows are in acquisition order, time increasing")
    """
    v = np.asarray(values, dtype=float).reshape(-1)
    bad = np.flatnonzero(~np.isfinite(v))
    if bad.size:
        return bad, f"{v[bad[0]]} is not a finite number"
    if name == TIME_COLUMN:
        bad = np.flatnonzero(np.diff(v) <= 0) + 1
        if bad.size:
            k = bad[0]
            return bad, (
                f"{v[k]:g} s is not after the row before's {v[k - 1]:g} s: rows are in acquisition "
                "order, time increasing"
            )
    elif name == ONE_TEMPERATURE_COLUMN or name in TEMPERATURE_COLUMNS:
        low, high = TEMPERATURE_RANGE
        bad = np.flatnonzero((v < low) | (v > high))
        if bad.size:
            t = v[bad[0]]
            why = f"{t:g} °C is outside the plausible {low:g} ... {high:g} °C"
            if low <= t - _KELVIN <= high:
                why += f"; it looks like kelvin ({t - _KELVIN:.4g} °C): give degrees Celsius"
            return bad, why
    elif name == PAYLOAD_MASS_COLUMN:
        bad = np.flatnonzero((v < 0) | (v > PAYLOAD_MAX_KG))
        if bad.size:
            m = v[bad[0]]
            if m < 0:
                return bad, f"{m:g} kg: a payload's mass cannot be negative"
            return bad, f"{m:g} kg is beyond {PAYLOAD_MAX_KG:,.0f} kg, more than a hexapod carries (grams?)"
    return None


@dataclass(frozen=True, eq=False)
class Covariates:
    """The covariates of ``m`` rows: each ``None`` when absent (all absent by default).

    Parameters
    ----------
    time : array_like, shape (m,), optional
        When each pose was measured, s, any origin, strictly increasing.
    temperatures : array_like, shape (m, 6) or (m,), optional
        Each leg's temperature, °C; a shape ``(m,)`` is one temperature for every leg (the
        ``temp`` column), broadcast to the six legs with ``one_temperature`` set.
    payload_kg : array_like, shape (m,), optional
        The payload's mass, kg.
    payload_com : array_like, shape (m, 3), optional
        The payload's centre of mass, mm, platform frame (needs ``payload_kg``).
    one_temperature : bool
        Whether the temperatures were one for every leg (written back as ``temp``).

    Examples
    --------
    >>> cov = Covariates(time=[0.0, 60.0], temperatures=[20.5, 21.0])
    >>> cov.names(), cov.temperatures.shape, len(cov)
    (('time', 'temperatures'), (2, 6), 2)
    >>> list(cov.subset([1]).to_columns())
    ['time', 'temp']
    """

    time: NDArray[np.float64] | None = None
    temperatures: NDArray[np.float64] | None = None
    payload_kg: NDArray[np.float64] | None = None
    payload_com: NDArray[np.float64] | None = None
    one_temperature: bool = False

    def __post_init__(self) -> None:
        shapes = {"time": 1, "temperatures": 2, "payload_kg": 1, "payload_com": 2}
        rows = set()
        for name, ndim in shapes.items():
            value = getattr(self, name)
            if value is None:
                continue
            arr = np.array(value, dtype=float)
            if name == "temperatures" and arr.ndim == 1:
                arr = np.repeat(arr[:, None], 6, axis=1)
                object.__setattr__(self, "one_temperature", True)
            width = {"temperatures": 6, "payload_com": 3}.get(name)
            if arr.ndim != ndim or (width is not None and arr.shape[1] != width):
                want = "(m,)" if width is None else f"(m, {width})"
                raise UsageError(f"covariates: {name} must have shape {want}, got {arr.shape}")
            rows.add(len(arr))
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)
        if len(rows) > 1:
            raise UsageError(f"covariates: the covariates have different numbers of rows {sorted(rows)}")
        if self.payload_com is not None and self.payload_kg is None:
            raise UsageError("covariates: a payload centre of mass needs the payload's mass (payload_kg)")
        if self.temperatures is None:
            object.__setattr__(self, "one_temperature", False)
        elif self.one_temperature and np.any(self.temperatures != self.temperatures[:, :1]):
            raise UsageError("covariates: one_temperature, but the legs' temperatures differ")
        for name, values in self.to_columns().items():
            found = value_problem(name, values)
            if found is not None:
                raise UsageError(f"covariates: row {found[0][0] + 1}, {name}: {found[1]}")

    @classmethod
    def from_columns(cls, columns: Mapping[str, ArrayLike]) -> Covariates:
        """The covariates of columns by name (:data:`COVARIATE_COLUMNS`; the inverse of
        :meth:`to_columns`), checked as :func:`check_columns` says."""
        unknown = [c for c in columns if c not in COVARIATE_COLUMNS]
        if unknown:
            known = _listed(COVARIATE_COLUMNS)
            raise UsageError(f"covariates: unknown column(s) {_listed(unknown)} (known: {known})")
        present = check_columns(columns)

        def stack(names: tuple[str, ...]) -> NDArray[np.float64] | None:
            if not all(n in present for n in names):
                return None
            return np.column_stack([np.asarray(columns[n], dtype=float).reshape(-1) for n in names])

        one = columns.get(ONE_TEMPERATURE_COLUMN)
        return cls(
            time=columns.get(TIME_COLUMN),
            temperatures=stack(TEMPERATURE_COLUMNS) if one is None else np.asarray(one, float).reshape(-1),
            payload_kg=columns.get(PAYLOAD_MASS_COLUMN),
            payload_com=stack(PAYLOAD_COM_COLUMNS),
        )

    def to_columns(self) -> dict[str, NDArray[np.float64]]:
        """The covariates present as file columns, in :data:`COVARIATE_COLUMNS` order (a
        temperature for every leg as ``temp``, else ``temp1 ... temp6``)."""
        out: dict[str, NDArray[np.float64]] = {}
        if self.time is not None:
            out[TIME_COLUMN] = self.time
        if self.temperatures is not None:
            if self.one_temperature:
                out[ONE_TEMPERATURE_COLUMN] = self.temperatures[:, 0]
            else:
                out.update(zip(TEMPERATURE_COLUMNS, self.temperatures.T, strict=True))
        if self.payload_kg is not None:
            out[PAYLOAD_MASS_COLUMN] = self.payload_kg
        if self.payload_com is not None:
            out.update(zip(PAYLOAD_COM_COLUMNS, self.payload_com.T, strict=True))
        return out

    def names(self) -> tuple[str, ...]:
        """The quantities present, of ``time``, ``temperatures``, ``payload_kg``, ``payload_com``."""
        return tuple(name for name in QUANTITIES if getattr(self, name) is not None)

    def __len__(self) -> int:
        """The number of rows (0 when no covariate is present)."""
        for name in QUANTITIES:
            value = getattr(self, name)
            if value is not None:
                return len(value)
        return 0

    def __bool__(self) -> bool:
        """Whether any covariate is present."""
        return bool(self.names())

    def subset(self, index: ArrayLike) -> Covariates:
        """The covariates of the rows at ``index`` (an integer or boolean index)."""
        if not self:
            return self
        idx = np.arange(len(self))[np.asarray(index)]
        # not validated again: the values were, and a subset in another order (a fold drawn at
        # random) is still the same poses, whose time no longer increases
        out = object.__new__(Covariates)
        for name in QUANTITIES:
            value = getattr(self, name)
            if value is not None:
                value = value[idx]
                value.flags.writeable = False
            object.__setattr__(out, name, value)
        object.__setattr__(out, "one_temperature", self.one_temperature)
        return out

    def replace(self, **changes: Any) -> Covariates:
        """Copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def require(self, names: Iterable[str], where: str) -> None:
        """Raise one line, ``where`` first (who needs them: ``"monday.csv: the thermal leg
        model"``), naming the quantities of ``names`` (:data:`QUANTITIES`) that are absent."""
        names = tuple(names)
        unknown = [n for n in names if n not in QUANTITIES]
        if unknown:
            raise UsageError(f"unknown covariate(s) {_listed(unknown)} (known: {_listed(QUANTITIES)})")
        missing = [QUANTITIES[n] for n in names if getattr(self, n) is None]
        if missing:
            raise InputError(f"{where} needs {' and '.join(missing)}, which the data do not have")


#: No covariate present: the default of every data class (immutable, so shared).
NO_COVARIATES = Covariates()


def check_rows(covariates: Covariates | None, rows: int, what: str = "poses") -> Covariates:
    """``covariates`` (None: none present) checked to have ``rows`` rows, for a data class."""
    if covariates is None:
        return NO_COVARIATES
    if not isinstance(covariates, Covariates):
        raise UsageError(f"covariates must be a Covariates, got {type(covariates).__name__}")
    if covariates and len(covariates) != rows:
        raise UsageError(f"covariates of {len(covariates)} rows for {rows} {what}")
    return covariates
