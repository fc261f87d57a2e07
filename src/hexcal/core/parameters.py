"""Named kinematic parameters: names, groups, blocks, scales, and the :class:`ParameterSet`.

The machine's parameters are two named blocks: ``joints``, ``u1.x ... u6.z`` (base joints)
and ``s1.x ... s6.z`` (platform joints), then ``legs``, the block of the leg model
(:mod:`hexcal.core.legs`: ``l0_1 ... l0_6``, ``g1 ... g6`` and the model's own terms). With
the linear leg model these are the 48 parameters of the seed paper's model
(:data:`PARAMETER_NAMES`). An instrument adds its own blocks (an instrument frame, targets
on the platform, a tool). A :class:`ParameterSet` holds any such list with values, vary
flags, characteristic scales, units, groups and blocks, in the spirit of lmfit's
``Parameters``; code reaches a block by name (:meth:`ParameterSet.span`), never by position.
Each parameter's unit (:data:`UNITS`: ``mm``, ``rad``, ``1``, or a leg model's own such as
``1/mm``) is set where the parameter is made (the machine's blocks here and in
:mod:`hexcal.core.legs`, an instrument's setup), so that no judgement or report guesses it
from the name.

Imports numpy and :mod:`hexcal.errors` only.

>>> params = ParameterSet.machine(np.zeros(48), fit="joints,l0", fix=("u1.z",))
>>> len(params), int(params.vary.sum())
(48, 41)
>>> params.groups["l0"]
('l0_1', 'l0_2', 'l0_3', 'l0_4', 'l0_5', 'l0_6')
>>> params["g1"].unit, params["u1.x"].unit
('1', 'mm')
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.errors import UsageError

PARAMETER_NAMES: tuple[str, ...] = (
    tuple(f"u{i}.{ax}" for i in range(1, 7) for ax in "xyz")
    + tuple(f"s{i}.{ax}" for i in range(1, 7) for ax in "xyz")
    + tuple(f"l0_{i}" for i in range(1, 7))
    + tuple(f"g{i}" for i in range(1, 7))
)
N_BASE_PARAMETERS = 42
N_ALL_PARAMETERS = 48

#: Names of the joint block: base joints, then platform joints.
JOINT_NAMES: tuple[str, ...] = PARAMETER_NAMES[:36]

#: Parameter groups of the machine, for selecting what an identification varies.
PARAMETER_GROUPS: dict[str, tuple[str, ...]] = {
    "joints": PARAMETER_NAMES[:36],
    "base": PARAMETER_NAMES[:18],
    "platform": PARAMETER_NAMES[18:36],
    "l0": PARAMETER_NAMES[36:42],
    "gains": PARAMETER_NAMES[42:48],
}

#: Default groups an identification varies: the 42 joint coordinates and initial lengths.
DEFAULT_FIT = "joints,l0"

#: Leg index (0-based) that each machine parameter belongs to.
PARAMETER_LEG = np.array([i for i in range(6) for _ in range(3)] * 2 + list(range(6)) * 2, dtype=np.intp)

#: The units hexcal holds parameters in: lengths in mm, angles in rad, ratios (gains) as pure
#: numbers. A leg model's own terms may carry another unit (``1/mm``); reports show ``rad`` in
#: degrees.
UNITS = ("mm", "rad", "1")

#: The unit of each machine parameter of the linear legs (mm for joints and ``l0``, 1 for gains).
PARAMETER_UNITS: tuple[str, ...] = ("mm",) * 42 + ("1",) * 6

#: Characteristic scale of each machine parameter (mm for joints and l0; gains are
#: dimensionless, and a gain change of 1e-3 moves a leg by about a millimetre).
PARAMETER_SCALE = np.concatenate([np.ones(42), np.full(6, 1e-3)])
PARAMETER_SCALE.flags.writeable = False

#: Minimum number of poses of a full-pose calibration: each leg has 7 parameters (8 with
#: its gain) and gets one equation per pose.
MIN_POSES = 7


@dataclass(frozen=True)
class Parameter:
    """One named parameter: value, whether it is varied, characteristic scale, group, unit."""

    name: str
    value: float
    vary: bool = True
    scale: float = 1.0
    group: str = ""
    unit: str = "mm"


def _readonly(values: ArrayLike, dtype: Any) -> NDArray[Any]:
    out = np.array(values, dtype=dtype)
    out.flags.writeable = False
    return out


class ParameterSet:
    """An ordered, immutable set of named parameters.

    Parameters
    ----------
    names : sequence of str
    values : array_like, shape (n,)
    vary : array_like of bool, shape (n,), optional
        Default all varied.
    scales : array_like, shape (n,), optional
        Characteristic scale of each parameter (the solver varies ``value / scale``);
        default 1.
    groups : mapping of str to sequence of str, optional
        Named groups of parameter names (a parameter may belong to several).
    blocks : mapping of str to (start, stop), optional
        Named contiguous blocks (``joints``, ``legs``, an instrument's setup): where each
        part of the model finds its values. Default one block ``all``.
    units : str or sequence of str, optional
        Each parameter's unit (:data:`UNITS`: ``mm``, ``rad``, ``1``, or a leg model's own),
        or one unit for all; default ``mm`` for every parameter.
    """

    def __init__(
        self,
        names: Sequence[str],
        values: ArrayLike,
        vary: ArrayLike | None = None,
        scales: ArrayLike | None = None,
        groups: Mapping[str, Sequence[str]] | None = None,
        blocks: Mapping[str, tuple[int, int]] | None = None,
        units: str | Sequence[str] | None = None,
    ) -> None:
        self.names: tuple[str, ...] = tuple(names)
        n = len(self.names)
        if len(set(self.names)) != n:
            raise UsageError("parameter names must be unique")
        self.values = _readonly(values, float)
        self.vary = _readonly(np.ones(n, dtype=bool) if vary is None else vary, bool)
        self.scales = _readonly(np.ones(n) if scales is None else scales, float)
        for what, arr in (("values", self.values), ("vary", self.vary), ("scales", self.scales)):
            if arr.shape != (n,):
                raise UsageError(f"parameter {what} must have shape ({n},), got {arr.shape}")
        given = "mm" if units is None else units
        self.units: tuple[str, ...] = (given,) * n if isinstance(given, str) else tuple(str(u) for u in given)
        if len(self.units) != n:
            raise UsageError(f"parameter units: {len(self.units)} for {n} parameters")
        self.groups: dict[str, tuple[str, ...]] = {k: tuple(v) for k, v in (groups or {}).items()}
        self.blocks: dict[str, tuple[int, int]] = (
            {"all": (0, n)} if blocks is None else {k: (int(a), int(b)) for k, (a, b) in blocks.items()}
        )
        for key, (a, b) in self.blocks.items():
            if not 0 <= a <= b <= n:
                raise UsageError(f"parameter block {key!r} [{a}, {b}) outside the {n} parameters")
        self._index = {name: k for k, name in enumerate(self.names)}

    # -- construction -------------------------------------------------------------------
    @classmethod
    def machine(
        cls, values: ArrayLike, fit: str | Sequence[str] = DEFAULT_FIT, fix: Iterable[str] = ()
    ) -> ParameterSet:
        """The 48 parameters of a machine with linear legs, values a 48-vector, vary flags from
        ``fit``/``fix`` (any leg model: :meth:`hexcal.core.Geometry.machine_parameters`)."""
        values = np.asarray(values, dtype=float)
        if values.shape != (N_ALL_PARAMETERS,):
            raise UsageError(f"machine parameter values must have shape (48,), got {values.shape}")
        blocks = {"joints": (0, 36), "legs": (36, 48)}
        flags = np.zeros(48, bool)
        base = cls(PARAMETER_NAMES, values, flags, PARAMETER_SCALE, PARAMETER_GROUPS, blocks, PARAMETER_UNITS)
        return base.select(fit, fix)

    def __add__(self, other: ParameterSet) -> ParameterSet:
        """The parameters of both sets, ``self`` first (e.g. machine plus instrument setup);
        blocks of the same name must not repeat."""
        groups = dict(self.groups)
        for key, names in other.groups.items():
            groups[key] = groups.get(key, ()) + names
        offset = len(self)
        blocks = dict(self.blocks) if "all" not in self.blocks or len(self.blocks) > 1 else {}
        for key, (a, b) in other.blocks.items():
            if key == "all" and len(other.blocks) == 1:
                continue
            if key in blocks:
                raise UsageError(f"parameter block {key!r} appears twice")
            blocks[key] = (a + offset, b + offset)
        return ParameterSet(
            self.names + other.names,
            np.concatenate([self.values, other.values]),
            np.concatenate([self.vary, other.vary]),
            np.concatenate([self.scales, other.scales]),
            groups,
            blocks or None,
            self.units + other.units,
        )

    def span(self, block: str) -> slice:
        """The positions of a named block (``joints``, ``legs``, a setup's block)."""
        try:
            a, b = self.blocks[block]
        except KeyError:
            raise UsageError(f"no parameter block {block!r}; the set has {', '.join(self.blocks)}") from None
        return slice(a, b)

    def has_block(self, block: str) -> bool:
        return block in self.blocks

    def free_in(self, block: str) -> NDArray[np.bool_]:
        """Which parameters of a block are varied (the block's slice of ``vary``)."""
        return np.array(self.vary[self.span(block)])

    def select(self, fit: str | Sequence[str] = DEFAULT_FIT, fix: Iterable[str] = ()) -> ParameterSet:
        """Copy that varies the groups in ``fit`` (comma-separated or a sequence) less ``fix``."""
        groups = [g.strip() for g in fit.split(",") if g.strip()] if isinstance(fit, str) else list(fit)
        vary = np.zeros(len(self), dtype=bool)
        for group in groups:
            if group not in self.groups:
                raise UsageError(f"unknown parameter group {group!r}; choose from {', '.join(self.groups)}")
            vary[[self._index[n] for n in self.groups[group]]] = True
        for name in fix:
            if name not in self._index:
                raise UsageError(f"unknown parameter {name!r} (names are like u1.x, s3.z, l0_2, g4)")
            vary[self._index[name]] = False
        if not vary.any():
            raise UsageError("no parameter left to identify")
        return self.with_vary(vary)

    def with_values(self, values: ArrayLike) -> ParameterSet:
        """Copy with new values of all parameters."""
        return ParameterSet(self.names, values, self.vary, self.scales, self.groups, self.blocks, self.units)

    def with_vary(self, vary: ArrayLike) -> ParameterSet:
        """Copy with new vary flags."""
        return ParameterSet(self.names, self.values, vary, self.scales, self.groups, self.blocks, self.units)

    def renamed(self, prefix: str, blocks: Mapping[str, tuple[int, int]] | None = None) -> ParameterSet:
        """Copy with ``prefix`` on every name and group name (``session2.frame.x``, group
        ``session2.frame``), the plain groups kept too (they gather several sets' members once
        added together); ``blocks`` replace the set's own when given."""
        names = tuple(prefix + n for n in self.names)
        groups = {prefix + g: tuple(prefix + n for n in v) for g, v in self.groups.items()}
        groups |= {g: tuple(prefix + n for n in v) for g, v in self.groups.items()}
        own = self.blocks if blocks is None else blocks
        return ParameterSet(names, self.values, self.vary, self.scales, groups, own, self.units)

    # -- access -------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.names)

    def __iter__(self) -> Iterator[Parameter]:
        for k in range(len(self)):
            yield self[k]

    def __getitem__(self, key: str | int) -> Parameter:
        k = self._index[key] if isinstance(key, str) else int(key)
        group = next((g for g, names in self.groups.items() if self.names[k] in names), "")
        value, vary, scale = float(self.values[k]), bool(self.vary[k]), float(self.scales[k])
        return Parameter(self.names[k], value, vary, scale, group, self.units[k])

    def __contains__(self, name: object) -> bool:
        return name in self._index

    def index(self, name: str) -> int:
        return self._index[name]

    @property
    def free_names(self) -> tuple[str, ...]:
        """Names of the varied parameters, in order."""
        return tuple(n for n, v in zip(self.names, self.vary, strict=True) if v)

    @property
    def free_units(self) -> tuple[str, ...]:
        """Units of the varied parameters, in order."""
        return tuple(u for u, v in zip(self.units, self.vary, strict=True) if v)

    def unit_of(self) -> dict[str, str]:
        """Each parameter's unit by name."""
        return dict(zip(self.names, self.units, strict=True))

    @property
    def n_free(self) -> int:
        return int(self.vary.sum())

    def unpacker(self) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
        """The map from solver variables ``x`` to all values.

        The solver varies ``x = (θ[vary] - values[vary]) / scales[vary]``; parameters not
        varied keep their values.
        """
        full0, mask = np.array(self.values), np.array(self.vary)
        base, scale = full0[mask], self.scales[mask]

        def unpack(x: NDArray[np.float64]) -> NDArray[np.float64]:
            full = full0.copy()
            full[mask] = base + x * scale
            return full

        return unpack

    def to_dict(self) -> dict[str, dict[str, Any]]:
        """``{name: {"value", "vary", "scale", "unit"}}``, JSON-ready."""
        return {
            n: {"value": float(v), "vary": bool(f), "scale": float(s), "unit": u}
            for n, v, f, s, u in zip(self.names, self.values, self.vary, self.scales, self.units, strict=True)
        }

    def __repr__(self) -> str:
        return f"ParameterSet({len(self)} parameters, {self.n_free} varied)"


def select_parameters(fit: str | Sequence[str] = DEFAULT_FIT, fix: Iterable[str] = ()) -> NDArray[np.bool_]:
    """Boolean mask over the 48 machine parameters: which ones an identification varies.

    Parameters
    ----------
    fit : str or sequence of str
        Group names from :data:`PARAMETER_GROUPS` (``joints``, ``base``, ``platform``,
        ``l0``, ``gains``), as a sequence or a comma-separated string.
    fix : sequence of str
        Parameter names to hold at their current values.

    >>> int(select_parameters("joints,l0,gains").sum())
    48
    """
    return np.array(ParameterSet.machine(np.zeros(48), fit, fix).vary)


def parameter_names(mask: ArrayLike | None = None) -> tuple[str, ...]:
    """Names of the machine parameters selected by a 48-mask (default joints and ``l0``)."""
    mask = select_parameters() if mask is None else np.asarray(mask, dtype=bool)
    return tuple(n for n, keep in zip(PARAMETER_NAMES, mask, strict=True) if keep)
