"""The workflow: a whole calibration, and its validation, as one library call each, their
results, reports and files.

:func:`calibrate` composes what the layers below decide (the noise, the leg model, outliers,
the verdict, steps and splits: :mod:`hexcal.calibration`) into one :class:`Calibration`,
whose ``to_dict()`` every report renders and whose ``save()`` writes the geometry file
(refusing a failed calibration). ``hexcal identify`` is: read the files, ``calibrate``, write.
:func:`validate` does the same for a held-out session (the re-registration, what the
calibration expected, the nominal machine beside, the ISO tests): one :class:`Validation`,
whose ``to_dict()`` the text, JSON, HTML, per-pose table and polar figure render;
``hexcal validate`` is: read the files, ``validate``, write.
Imports every layer below it, :mod:`hexcal.report` and :mod:`hexcal.io` (to write files);
:mod:`hexcal.cli` is above it.

Public names
------------
- ``calibrate``, ``Calibration``: the calibration workflow and its result.
- ``validate``, ``Validation``, ``IsoTests``: the validation workflow, its result and its ISO
  test.
"""

from hexcal._lazy import attach

_NAMES = {
    "Calibration": "calibration",
    "IsoTests": "validation",
    "Validation": "validation",
    "calibrate": "calibration",
    "validate": "validation",
}

__all__ = ["Calibration", "IsoTests", "Validation", "calibrate", "validate"]

__getattr__, _dir, _names = attach(__name__, _NAMES)


def __dir__() -> list[str]:
    return sorted(__all__)
