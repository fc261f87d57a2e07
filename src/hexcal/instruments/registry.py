"""Measurement models by name: a new instrument is one new module plus one line here.

>>> sorted(MODELS)
['pose', 'targets', 'tool']
>>> model_by_name("pose").measures_pose
True
"""

from __future__ import annotations

from hexcal.errors import UsageError
from hexcal.instruments.base import MeasurementModel
from hexcal.instruments.pose import FullPoseModel
from hexcal.instruments.targets import TargetModel
from hexcal.instruments.tool import ToolModel

#: Measurement model classes by name.
MODELS: dict[str, type[MeasurementModel]] = {
    FullPoseModel.name: FullPoseModel,
    TargetModel.name: TargetModel,
    ToolModel.name: ToolModel,
}


def model_by_name(name: str) -> MeasurementModel:
    """A new instance of the model registered as ``name``."""
    try:
        return MODELS[name]()
    except KeyError:
        raise UsageError(f"unknown measurement model {name!r}; choose from {', '.join(MODELS)}") from None
