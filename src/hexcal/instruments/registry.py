"""Instruments by name: a new instrument is one module plus one registration.

Each kind of instrument is one record, an :class:`InstrumentKind`: its model class, its setup
class and the setup file's key that names it (``ballbar:``), the setup kinds read as it, its
data class and the columns of its data files (with their units), the reader and writer of
those files and its planner (the candidate measurements it can take, such as a ballbar's
circles). :func:`register_instrument` adds one record; nothing elsewhere in hexcal tells the
kinds apart by name: the setup file's reader, the sessions' readers and writers, the unit row
of a table, the hint for a file read without its setup and the planning commands look the
record up.

The records of the built-in instruments are made here with what this layer knows (models,
setups, data classes, columns); the layers above fill in their part with
:func:`complete_instrument` where they define it (the files' reader and writer in
:mod:`hexcal.io.sessions`, the ballbar's planner in :mod:`hexcal.design.ballbar_plan`). An
instrument from outside gives every field in its one call.

:data:`MODELS` and :data:`SETUP_KINDS` are views of the records by name (the model classes, and
the instrument of each setup kind); :func:`instrument_for` gives the instrument a setup
describes, :func:`full_pose` the instrument of a measurement file read without a setup (the
platform pose in the base frame).

>>> sorted(MODELS)
['ballbar', 'pose', 'targets', 'tool']
>>> model_by_name("pose").determines_pose
True
>>> INSTRUMENTS["ballbar"].setup_key, INSTRUMENTS["ballbar"].columns
('ballbar', {'d': 'mm'})
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from hexcal.errors import UsageError
from hexcal.instruments.ballbar import BallbarModel
from hexcal.instruments.ballbar_setup import BallbarMeasurements, BallbarSetup
from hexcal.instruments.base import MeasurementModel
from hexcal.instruments.data import Measurements, TargetMeasurements
from hexcal.instruments.pose import FullPoseModel, ToolModel
from hexcal.instruments.setup import Setup
from hexcal.instruments.targets import TargetModel


@dataclass(frozen=True)
class InstrumentKind:
    """One kind of instrument: everything hexcal needs to read, simulate, plan and write it.

    Attributes
    ----------
    name : str
        The model's :attr:`~MeasurementModel.name` (the registry key).
    model : type
        The :class:`MeasurementModel` subclass; ``model(setup)`` is the instrument of a setup.
    setup : type, optional
        Its setup class (``from_dict``, ``to_dict``, ``kind``, ``in_euler``, ``parameters``,
        ``columns``), None for an instrument without a setup file (the full pose).
    setup_key : str, optional
        The top-level key of a setup file that says this kind (``ballbar``); a setup file with
        none of the registered keys is read by :class:`~hexcal.instruments.Setup`.
    setup_kinds : tuple of str
        The values of ``setup.kind`` read as this instrument (default ``(name,)`` with a setup).
    data : type, optional
        The class of its data (what its reader returns and :meth:`MeasurementModel.simulate`
        makes).
    columns : mapping of str to str
        The columns of its data files beyond the leg readings, by hexcal's name, with their unit
        (``{"d": "mm"}``): a unit row is checked against them, and a file that has them all and
        is read without a setup is named as this instrument's.
    label : str
        What a person calls it ("ballbar readings"), for messages.
    reader : callable, optional
        ``(path, instrument, euler, delimiter, decimal[, columns=]) -> data``.
    writer : callable, optional
        ``(path, data, euler, orientation="rad", comment=None) -> None``.
    planner : callable, optional
        ``(geometry, setup, **options) -> (poses, ids, lines)``: the candidate measurements of
        this kind at a setup (poses ``(m, 6)``, their ids, lines that describe them); without
        one the candidates are poses of the workspace (:func:`hexcal.design.candidate_poses`).
    """

    name: str
    model: type[MeasurementModel]
    setup: type | None = None
    setup_key: str | None = None
    setup_kinds: tuple[str, ...] = ()
    data: type | None = None
    columns: Mapping[str, str] = field(default_factory=dict)
    label: str = ""
    reader: Callable[..., Any] | None = None
    writer: Callable[..., None] | None = None
    planner: Callable[..., Any] | None = None

    def __post_init__(self) -> None:
        if not self.name:
            raise UsageError(f"{self.model.__name__} has no name to register")
        if self.setup is not None and not self.setup_kinds:
            object.__setattr__(self, "setup_kinds", (self.name,))
        object.__setattr__(self, "columns", dict(self.columns))
        object.__setattr__(self, "label", self.label or f"{self.name} data")


#: The instrument kinds by name.
INSTRUMENTS: dict[str, InstrumentKind] = {}


class _View(Mapping[str, Any]):
    """A read-only mapping over the records (their names to one value of each)."""

    def __init__(self, key: Callable[[InstrumentKind], Iterator[tuple[str, Any]]]) -> None:
        self._key = key

    def _items(self) -> dict[str, Any]:
        return dict(item for kind in INSTRUMENTS.values() for item in self._key(kind))

    def __getitem__(self, name: str) -> Any:
        return self._items()[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._items())

    def __len__(self) -> int:
        return len(self._items())

    def __repr__(self) -> str:
        return repr(self._items())


#: Instrument classes by name (a view of :data:`INSTRUMENTS`).
MODELS: Mapping[str, type[MeasurementModel]] = _View(lambda k: iter([(k.name, k.model)]))

#: The instrument of each kind of setup (``setup.kind``; a view of :data:`INSTRUMENTS`).
SETUP_KINDS: Mapping[str, str] = _View(lambda k: ((s, k.name) for s in k.setup_kinds))


def register_instrument(kind: InstrumentKind | type[MeasurementModel], **fields: Any) -> InstrumentKind:
    """Add an instrument kind (a record, or a model class with the record's other ``fields``),
    replacing one of the same name; a setup key or setup kind another kind has is refused."""
    record = kind if isinstance(kind, InstrumentKind) else InstrumentKind(kind.name, kind, **fields)
    if isinstance(kind, InstrumentKind) and fields:
        record = dataclasses.replace(record, **fields)
    for other in INSTRUMENTS.values():
        if other.name == record.name:
            continue
        if record.setup_key is not None and other.setup_key == record.setup_key:
            raise UsageError(f"setup key {record.setup_key!r} is {other.name}'s already")
        shared = set(record.setup_kinds) & set(other.setup_kinds)
        if shared:
            raise UsageError(f"setup kind {sorted(shared)[0]!r} is {other.name}'s already")
    INSTRUMENTS[record.name] = record
    return record


def unregister_instrument(name: str) -> None:
    """Remove the instrument kind ``name`` (a test's toy, once done)."""
    INSTRUMENTS.pop(name, None)


def complete_instrument(name: str, **fields: Any) -> InstrumentKind:
    """Fill in fields of a registered kind (a higher layer's part of a built-in: its reader and
    writer, its planner)."""
    return register_instrument(instrument_kind(name), **fields)


def instrument_kind(name: str) -> InstrumentKind:
    """The record of instrument ``name``; :class:`UsageError` naming the choices."""
    try:
        return INSTRUMENTS[name]
    except KeyError:
        raise UsageError(
            f"unknown measurement model {name!r}; choose from {', '.join(INSTRUMENTS)}"
        ) from None


def model_by_name(name: str, *args: Any, **options: Any) -> MeasurementModel:
    """A new instance of the instrument registered as ``name``."""
    return instrument_kind(name).model(*args, **options)


def setup_class_for(data: Any) -> type:
    """The setup class of a setup file's mapping: the kind whose ``setup_key`` it has, else
    :class:`~hexcal.instruments.Setup` (targets or a tool)."""
    if isinstance(data, dict):
        for kind in INSTRUMENTS.values():
            if kind.setup_key is not None and kind.setup_key in data and kind.setup is not None:
                return kind.setup
    return Setup


def setup_types() -> tuple[type, ...]:
    """The setup classes of the registered kinds (what a loaded setup may be)."""
    return tuple(dict.fromkeys(k.setup for k in INSTRUMENTS.values() if k.setup is not None))


def is_setup(value: Any) -> bool:
    """Whether ``value`` is a loaded setup of a registered kind (not a path)."""
    return isinstance(value, setup_types())


def kind_of_setup(setup: Any) -> InstrumentKind:
    """The instrument kind of a loaded setup (by its ``kind``)."""
    for kind in INSTRUMENTS.values():
        if setup.kind in kind.setup_kinds:
            return kind
    raise UsageError(f"no instrument for a setup of kind {setup.kind!r}")


def instrument_for(setup: Any, **options: Any) -> MeasurementModel:
    """The instrument of a setup (``None``: the full pose in the base frame)."""
    if setup is None:
        return FullPoseModel()
    return kind_of_setup(setup).model(setup, **options)


def column_unit(name: str) -> str | None:
    """The unit of an instrument's own data column ``name`` (hexcal's name), None when no
    registered kind has it."""
    for kind in INSTRUMENTS.values():
        if name in kind.columns:
            return kind.columns[name]
    return None


def full_pose() -> MeasurementModel:
    """The full pose in the base frame: the pose instrument with identity frame and tool, fixed."""
    return FullPoseModel()


for _kind in (
    InstrumentKind(BallbarModel.name, BallbarModel, BallbarSetup, "ballbar", data=BallbarMeasurements,
                   columns={"d": "mm"}, label="ballbar readings"),
    InstrumentKind(FullPoseModel.name, FullPoseModel, data=Measurements, label="poses"),
    InstrumentKind(TargetModel.name, TargetModel, Setup, data=TargetMeasurements, label="target positions"),
    InstrumentKind(ToolModel.name, ToolModel, Setup, data=Measurements, label="tool poses"),
):  # fmt: skip
    register_instrument(_kind)
