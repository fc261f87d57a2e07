"""The exceptions and warnings hexcal raises: one root, :class:`HexcalError`.

Every failure a user can cause (a malformed file, an impossible option, data that cannot
determine the parameters, a solver that does not converge) raises a subclass of
:class:`HexcalError` whose message is one line naming the problem; the command line
prints it as ``hexcal: error: ...`` and exits with status 1. Most subclasses are also
``ValueError`` (bad values) so that plain Python code can catch them as such.

This module imports nothing and may be imported by every layer.

>>> try:
...     raise InputError("measured.csv: line 4, column 'x': not a number: 'abc'")
... except HexcalError as exc:
...     print(f"hexcal: error: {exc}")
hexcal: error: measured.csv: line 4, column 'x': not a number: 'abc'
"""

from __future__ import annotations


class HexcalError(Exception):
    """Root of the errors hexcal reports to its user as one line."""


class UsageError(HexcalError, ValueError):
    """An argument or option has an impossible value (unknown name, negative count...)."""


class InputError(HexcalError, ValueError):
    """An input file is missing or malformed; the message names file, line and column."""


class LinuxCNCFormatError(InputError):
    """A LinuxCNC HAL, INI or compensation table file cannot be read; the message names the
    file and the line (``hexcal.io.linuxcnc``)."""


class GeometryError(HexcalError, ValueError):
    """A geometry description is invalid (missing key, wrong shape, wrong unit...)."""


class IdentificationError(HexcalError, ValueError):
    """The data cannot determine the parameters, or the solver failed."""


class CalibrationFailed(HexcalError):
    """A calibration whose verdict is ``fail`` was to be written: nothing is written."""


class ValidationError(HexcalError, ValueError):
    """The model cannot be evaluated at some poses (forward kinematics fails)."""


class SelectionError(HexcalError, ValueError):
    """Poses cannot be selected as asked (too few candidates, unknown criterion...)."""


class SimulationError(HexcalError, RuntimeError):
    """A simulated campaign could not be carried out (e.g. unreachable poses)."""


class HexcalWarning(UserWarning):
    """Root of hexcal's warnings (printed as ``hexcal: warning: ...`` by the command line)."""


class InputWarning(HexcalWarning):
    """An input file is readable but probably not what the user meant."""
