"""Instruments by name: a new instrument is one new module plus one registration.

:data:`MODELS` maps each name to its class (a built-in instrument is one line here, another
one registers itself with :func:`register_instrument`); :func:`instrument_for` gives the
instrument a setup describes (its quantities say which: targets, a tool or a ballbar), and
:func:`full_pose` the instrument of a measurement file read without a setup (the platform
pose in the base frame).

>>> sorted(MODELS)
['ballbar', 'pose', 'targets', 'tool']
>>> model_by_name("pose").determines_pose
True
"""

from __future__ import annotations

from typing import Any

from hexcal.errors import UsageError
from hexcal.instruments.ballbar import BallbarModel
from hexcal.instruments.ballbar_setup import BallbarSetup
from hexcal.instruments.base import MeasurementModel
from hexcal.instruments.pose import FullPoseModel, ToolModel
from hexcal.instruments.setup import Setup
from hexcal.instruments.targets import TargetModel

#: Instrument classes by name.
MODELS: dict[str, type[MeasurementModel]] = {
    BallbarModel.name: BallbarModel,
    FullPoseModel.name: FullPoseModel,
    TargetModel.name: TargetModel,
    ToolModel.name: ToolModel,
}

#: The instrument of each kind of setup (:attr:`Setup.kind`).
SETUP_KINDS: dict[str, str] = {
    "targets": TargetModel.name,
    "tool": ToolModel.name,
    "ballbar": BallbarModel.name,
}


def register_instrument(model: type[MeasurementModel]) -> type[MeasurementModel]:
    """Add an instrument class to :data:`MODELS` under its ``name`` (replacing one of the same
    name); usable as a class decorator."""
    if not model.name:
        raise UsageError(f"{model.__name__} has no name to register")
    MODELS[model.name] = model
    return model


def model_by_name(name: str, *args: Any, **options: Any) -> MeasurementModel:
    """A new instance of the instrument registered as ``name``."""
    try:
        cls = MODELS[name]
    except KeyError:
        raise UsageError(f"unknown measurement model {name!r}; choose from {', '.join(MODELS)}") from None
    return cls(*args, **options)


def instrument_for(setup: Setup | BallbarSetup | None, **options: Any) -> MeasurementModel:
    """The instrument of a setup (``None``: the full pose in the base frame)."""
    if setup is None:
        return FullPoseModel()
    try:
        name = SETUP_KINDS[setup.kind]
    except KeyError:
        raise UsageError(f"no instrument for a setup of kind {setup.kind!r}") from None
    return model_by_name(name, setup, **options)


def full_pose() -> MeasurementModel:
    """The full pose in the base frame: the pose instrument with identity frame and tool, fixed."""
    return FullPoseModel()
