"""The ballbar's setup and data: where the bar's two balls sit, and what it reads at each pose.

A telescoping ballbar joins a pivot on the base side (a magnetic cup fixed to the base: the
point ``c``, base frame, mm) to a ball on the platform side (``b``, platform frame, mm). Its
length is ``length + d``: ``length`` the bar's length at zero reading (its calibration), ``d``
the reading (mm). A setup file (docs/ballbar.md)::

    units: mm
    ballbar: {pivot: [x, y, z], ball: [x, y, z], length: 150.0}
    fixed: []            # any of pivot, ball, length: held as given, the others identified

Its parameters, appended after the machine's, are ``pivot.x pivot.y pivot.z ball.x ball.y
ball.z length`` in the groups ``pivot``, ``ball`` and ``length`` (so ``--fit``/``--fix``
accept them), all lengths (scale 1 mm). One setup is one session: a campaign is several
setups (pivot positions, bar lengths), each with its own data file.

>>> setup = BallbarSetup.from_dict({"units": "mm", "ballbar": {"pivot": [0, 0, 0],
...                                 "ball": [0, 0, 60], "length": 150}})
>>> setup.kind, setup.names()
('ballbar', ('pivot.x', 'pivot.y', 'pivot.z', 'ball.x', 'ball.y', 'ball.z', 'length'))
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.parameters import ParameterSet
from hexcal.errors import InputError, UsageError
from hexcal.instruments.covariates import NO_COVARIATES, Covariates, check_rows
from hexcal.instruments.known_noise import Device, declared_noise, device_for, noise_mapping

#: Setup quantities a ballbar setup's ``fixed`` may name.
BALLBAR_FIXABLE = ("pivot", "ball", "length")
#: Keys of a ballbar setup mapping, and of its ``ballbar`` mapping.
BALLBAR_KEYS = ("units", "instrument", "ballbar", "fixed", "noise", "calibration")
BAR_KEYS = ("pivot", "ball", "length")
BALLBAR_NAMES = (*(f"pivot.{a}" for a in "xyz"), *(f"ball.{a}" for a in "xyz"), "length")
#: The shortest bar (mm) a setup may give: the two balls of a real bar are tens of mm apart.
MIN_LENGTH = 1.0


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
        raise InputError(f"{where}: not a finite number: {value!r}")
    return float(value)


def _point(value: Any, where: str) -> NDArray[np.float64]:
    if not isinstance(value, list | tuple) or len(value) != 3:
        raise InputError(f"{where}: must be a list [x, y, z] (mm)")
    return np.array([_number(v, f"{where}[{k}]") for k, v in enumerate(value)])


@dataclass(frozen=True, eq=False)
class BallbarSetup:
    """A ballbar setup (docs/ballbar.md).

    Parameters
    ----------
    pivot : array_like, shape (3,)
        The base-side ball's centre, base frame, mm.
    ball : array_like, shape (3,)
        The platform-side ball's centre, platform frame, mm.
    length : float
        The bar's length at zero reading (centre to centre), mm.
    fixed : sequence of str
        Quantities held exactly: any of ``pivot``, ``ball``, ``length``.
    euler : str, optional
        Kept for the interface of setups (a ballbar has no angles).
    calibration : mapping, optional
        Standard errors of a calibrated setup.
    noise : mapping, optional
        The bar's own noise as declared: ``{"position": σ}`` (the file's ``noise: {d: σ}``, mm).
    instrument : str, optional
        ``ballbar`` (the only kind that measures a ballbar setup).
    """

    pivot: NDArray[np.float64]
    ball: NDArray[np.float64]
    length: float
    fixed: tuple[str, ...] = ()
    euler: str | None = None
    calibration: dict[str, Any] | None = None
    columns: dict[str, str] | None = field(default=None)
    noise: dict[str, float] | None = None
    instrument: str | None = None

    def __post_init__(self) -> None:
        for what in ("pivot", "ball"):
            arr = np.array(getattr(self, what), dtype=float)
            if arr.shape != (3,) or not np.all(np.isfinite(arr)):
                raise InputError(f"ballbar.{what}: must be three finite numbers [x, y, z] (mm)")
            object.__setattr__(self, what, arr)
        length = float(self.length)
        if not np.isfinite(length) or length < MIN_LENGTH:
            raise InputError(f"ballbar.length: {self.length!r} mm; a bar is at least {MIN_LENGTH:g} mm long")
        object.__setattr__(self, "length", length)
        fixed = tuple(self.fixed)
        for name in fixed:
            if name not in BALLBAR_FIXABLE:
                raise InputError(
                    f"fixed: unknown quantity {name!r}; choose from {', '.join(BALLBAR_FIXABLE)}"
                )
        object.__setattr__(self, "fixed", tuple(dict.fromkeys(fixed)))
        device_for("ballbar", self.instrument)
        if self.noise is not None:
            if set(self.noise) != {"position"} or not self.noise["position"] > 0:
                raise InputError("noise: a ballbar setup declares d (the bar's σ, mm, > 0)")
            object.__setattr__(self, "noise", {"position": float(self.noise["position"])})

    @property
    def kind(self) -> str:
        return "ballbar"

    @property
    def device(self) -> Device:
        """The kind of instrument (a ballbar) and the noise such bars have."""
        return device_for("ballbar", self.instrument)

    @property
    def auto(self) -> bool:
        return False

    def names(self) -> tuple[str, ...]:
        return BALLBAR_NAMES

    def vector(self) -> NDArray[np.float64]:
        """``pivot (3), ball (3), length``."""
        return np.concatenate([self.pivot, self.ball, [self.length]])

    def parameters(self, euler: str | None = None) -> ParameterSet:
        """Groups ``pivot``, ``ball``, ``length`` (scale 1 mm); ``fixed`` ones not varied."""
        vary = np.array([g not in self.fixed for g in ("pivot",) * 3 + ("ball",) * 3 + ("length",)])
        groups = {"pivot": BALLBAR_NAMES[:3], "ball": BALLBAR_NAMES[3:6], "length": BALLBAR_NAMES[6:]}
        blocks = {"pivot": (0, 3), "ball": (3, 6), "length": (6, 7)}
        return ParameterSet(BALLBAR_NAMES, self.vector(), vary, np.ones(7), groups, blocks)

    def with_vector(self, values: ArrayLike, calibration: dict[str, Any] | None = None) -> BallbarSetup:
        values = np.asarray(values, dtype=float)
        if values.shape != (7,):
            raise InputError(f"ballbar setup values must have shape (7,), got {values.shape}")
        return replace(
            self, pivot=values[:3], ball=values[3:6], length=float(values[6]), calibration=calibration
        )

    def in_euler(self, euler: str) -> BallbarSetup:
        """The same setup (a ballbar has no angles), its sequence recorded."""
        return replace(self, euler=euler)

    @classmethod
    def from_dict(cls, data: Any) -> BallbarSetup:
        """A ballbar setup from its YAML mapping; one :class:`InputError` line per problem."""
        if not isinstance(data, dict):
            raise InputError("a ballbar setup must be a mapping (units, ballbar, fixed)")
        unknown = [k for k in data if k not in BALLBAR_KEYS]
        if unknown:
            raise InputError(f"unknown key {unknown[0]!r}; a ballbar setup has {', '.join(BALLBAR_KEYS)}")
        if "units" not in data:
            raise InputError("missing units (write 'units: mm')")
        if data["units"] != "mm":
            raise InputError(f"units: only mm is supported, got {data['units']!r}")
        bar = data.get("ballbar")
        if not isinstance(bar, dict):
            raise InputError("ballbar must be a mapping {pivot: [x, y, z], ball: [x, y, z], length: L}")
        unknown = [k for k in bar if k not in BAR_KEYS]
        if unknown:
            raise InputError(f"ballbar: unknown key {unknown[0]!r}; it has {', '.join(BAR_KEYS)}")
        for key in BAR_KEYS:
            if key not in bar:
                raise InputError(f"ballbar: missing {key}")
        fixed = data.get("fixed", [])
        if isinstance(fixed, str):
            fixed = [fixed]
        if not isinstance(fixed, list) or not all(isinstance(f, str) for f in fixed):
            raise InputError("fixed must be a list of pivot, ball, length")
        calibration = data.get("calibration")
        if calibration is not None and not isinstance(calibration, dict):
            raise InputError("calibration must be a mapping")
        instrument = data.get("instrument")
        if instrument is not None:
            device_for("ballbar", instrument if isinstance(instrument, str) else repr(instrument))
        return cls(
            _point(bar["pivot"], "ballbar.pivot"),
            _point(bar["ball"], "ballbar.ball"),
            _number(bar["length"], "ballbar.length"),
            tuple(fixed),
            None,
            calibration,
            noise=declared_noise(data["noise"], "ballbar") if "noise" in data else None,
            instrument=instrument,
        )

    def to_dict(self) -> dict[str, Any]:
        """The YAML mapping of the setup file."""
        out: dict[str, Any] = {
            "units": "mm",
            "ballbar": {
                "pivot": [float(v) for v in self.pivot],
                "ball": [float(v) for v in self.ball],
                "length": float(self.length),
            },
        }
        if self.fixed:
            out["fixed"] = list(self.fixed)
        if self.instrument is not None:
            out["instrument"] = self.instrument
        if self.noise:
            out["noise"] = noise_mapping(self.noise, "ballbar")
        if self.calibration is not None:
            out["calibration"] = self.calibration
        return out


@dataclass(frozen=True, eq=False)
class BallbarMeasurements:
    """Leg readings ``(m, 6)`` and the bar's reading ``d`` ``(m,)`` (mm) at each observation,
    their ids and covariates (:class:`~hexcal.instruments.covariates.Covariates`, none present by
    default)."""

    readings: NDArray[np.float64]
    d: NDArray[np.float64]
    ids: tuple[str, ...] = field(default=())
    covariates: Covariates = field(default=NO_COVARIATES)

    def __post_init__(self) -> None:
        readings = np.array(self.readings, dtype=float)
        if readings.ndim != 2 or readings.shape[1] != 6:
            raise UsageError(f"leg readings must have shape (m, 6), got {readings.shape}")
        d = np.array(self.d, dtype=float).reshape(-1)
        if d.shape != (len(readings),):
            raise UsageError(f"{d.size} bar readings for {len(readings)} rows of leg readings")
        for what, arr in (("leg readings", readings), ("bar readings", d[:, None])):
            bad = np.flatnonzero(~np.all(np.isfinite(arr), axis=1))
            if bad.size:
                raise UsageError(f"{what} contain NaN or inf (row {bad[0] + 1})")
        ids = tuple(str(i) for i in self.ids) or tuple(str(k + 1) for k in range(len(readings)))
        if len(ids) != len(readings):
            raise UsageError(f"{len(ids)} ids for {len(readings)} observations")
        readings.flags.writeable = False
        d.flags.writeable = False
        object.__setattr__(self, "readings", readings)
        object.__setattr__(self, "d", d)
        object.__setattr__(self, "ids", ids)
        object.__setattr__(self, "covariates", check_rows(self.covariates, len(readings), "observations"))

    def __len__(self) -> int:
        return len(self.readings)

    def subset(self, index: ArrayLike) -> BallbarMeasurements:
        idx = np.arange(len(self))[np.asarray(index)]
        ids = tuple(self.ids[i] for i in idx)
        return BallbarMeasurements(self.readings[idx], self.d[idx], ids, self.covariates.subset(idx))

    def replace(self, **changes: Any) -> BallbarMeasurements:
        return dataclasses.replace(self, **changes)
