"""The workflow: a whole calibration as one library call, its result, its reports and files.

:func:`calibrate` composes what the layers below decide (the noise, the leg model, outliers,
the verdict, steps and splits: :mod:`hexcal.calibration`) into one :class:`Calibration`,
whose ``to_dict()`` every report renders and whose ``save()`` writes the geometry file
(refusing a failed calibration). ``hexcal identify`` is: read the files, ``calibrate``, write.
Imports every layer below it, :mod:`hexcal.report` and :mod:`hexcal.io` (to write files);
:mod:`hexcal.cli` is above it.

Public names
------------
- ``calibrate``, ``Calibration``: the calibration workflow and its result.
"""

from hexcal._lazy import attach

_NAMES = {
    "Calibration": "calibration",
    "calibrate": "calibration",
}

__all__ = ["Calibration", "calibrate"]

__getattr__, _dir, _names = attach(__name__, _NAMES)


def __dir__() -> list[str]:
    return sorted(__all__)
