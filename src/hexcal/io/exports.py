"""Controller exports by name: a new controller is one module plus one registration.

Each export is one record, a :class:`ControllerExport`: its name (``hexcal export NAME``), what
it writes for (its label), the files it may write into the ``--out`` folder (declared before
any work, so that each is checked like every output) and its function, which turns a geometry
into those files' texts and says what the user does with them (:class:`Exported`: the files,
the lines to print, the warnings). :func:`register_export` adds one; :func:`export_geometry`
runs one by name, from Python as from ``hexcal export``. LinuxCNC's ``genhexkins`` is the first
(:mod:`hexcal.io.linuxcnc`).

>>> sorted(EXPORTS)
['linuxcnc']
>>> EXPORTS["linuxcnc"].files[:2]
('hexcal-kins.hal', 'hexcal-joints.ini')
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hexcal.core.geometry import Geometry
from hexcal.errors import UsageError


@dataclass(frozen=True)
class Exported:
    """What an export made: ``files`` (name -> text, to write into one folder), ``lines`` (what
    to do with them, printed after the files are written) and ``warnings`` (one line each)."""

    files: dict[str, str]
    lines: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class ControllerExport:
    """One controller's export.

    Attributes
    ----------
    name : str
        ``hexcal export NAME``.
    label : str
        What it writes for ("LinuxCNC genhexkins").
    files : tuple of str
        Every file name it may write (declared outputs of the command).
    export : callable
        ``(geometry, *, source, source_sha256, source_date, **options) -> Exported``; refuses a
        geometry it cannot write with one :class:`~hexcal.errors.HexcalError` line.
    options : tuple of str
        The options it takes besides the source (``shared_sensor`` for LinuxCNC's thermal
        file); another one given is refused in one line.
    """

    name: str
    label: str
    files: tuple[str, ...]
    export: Callable[..., Exported]
    options: tuple[str, ...] = ()


#: The controller exports by name.
EXPORTS: dict[str, ControllerExport] = {}


def register_export(export: ControllerExport) -> ControllerExport:
    """Add a controller export (replacing one of the same name)."""
    if not export.name or not export.files:
        raise UsageError("a controller export needs a name and the files it writes")
    EXPORTS[export.name] = export
    return export


def unregister_export(name: str) -> None:
    """Remove the export ``name`` (a test's toy, once done)."""
    EXPORTS.pop(name, None)


def controller_export(name: str) -> ControllerExport:
    """The export ``name``; :class:`UsageError` naming the choices."""
    try:
        return EXPORTS[name]
    except KeyError:
        raise UsageError(f"export {name!r}: unknown controller; choose from {', '.join(EXPORTS)}") from None


def export_files(name: str) -> tuple[str, ...]:
    """The files export ``name`` may write (none for an unknown name: it is refused later)."""
    found = EXPORTS.get(name)
    return () if found is None else found.files


def geometry_source(geometry: str | os.PathLike[str]) -> dict[str, Any]:
    """Where a geometry came from, for an export's header: a preset's name, or a file's path, its
    SHA-256 and its modification time (UTC)."""
    import datetime
    import hashlib

    from hexcal.core.presets import PRESETS
    from hexcal.io.inputs import check_input

    if isinstance(geometry, str) and geometry in PRESETS:
        return {"source": f"built-in preset {geometry}", "source_sha256": None, "source_date": None}
    path = Path(geometry)
    check_input(path)
    sha256 = hashlib.sha256(path.read_bytes()).hexdigest()
    mtime = datetime.datetime.fromtimestamp(path.stat().st_mtime, tz=datetime.UTC)
    return {"source": str(path), "source_sha256": sha256, "source_date": mtime.strftime("%Y-%m-%dT%H:%M:%SZ")}


def export_geometry(
    name: str, geometry: Geometry, options: dict[str, Any] | None = None, **source: Any
) -> Exported:
    """The files of ``geometry`` for controller ``name`` (``source``: where it came from,
    :func:`geometry_source`; ``options``: the export's own, set ones only), with what to do
    with them and the warnings."""
    export = controller_export(name)
    given = {key: value for key, value in (options or {}).items() if value}
    unknown = sorted(set(given) - set(export.options))
    if unknown:
        words = ", ".join("--" + key.replace("_", "-") for key in unknown)
        raise UsageError(f"export {name}: {words} acts only on an export that takes it")
    return export.export(geometry, **source, **given)


def _linuxcnc(geometry: Geometry, shared_sensor: bool = False, **source: Any) -> Exported:
    """LinuxCNC ``genhexkins``: the HAL file, the INI keys and, for a stroke leg model, the
    joints' compensation tables, for a thermal one the run-time ``hexcal-thermal.hal``
    (:func:`hexcal.io.linuxcnc.export_linuxcnc`)."""
    from hexcal.io.linuxcnc import euler_warning, export_linuxcnc
    from hexcal.io.linuxcnc_comp import COMP_FILES
    from hexcal.io.linuxcnc_thermal import THERMAL_HAL_FILE

    files = export_linuxcnc(geometry, **source, shared_sensor=shared_sensor)
    lines = [
        "paste: [HAL] HALFILE = hexcal-kins.hal; the [TRAJ], [JOINT_N], [AXIS_*] keys of hexcal-joints.ini"
    ]
    warnings = [w for w in (euler_warning(geometry),) if w]
    if COMP_FILES[0] in files:
        lines.append(
            f"copy {COMP_FILES[0]} .. {COMP_FILES[-1]} into the machine's configuration folder (the joints' "
            "COMP_FILE tables of the stroke leg model)"
        )
        from hexcal.calibration import workspace_stroke_excess

        beyond = workspace_stroke_excess(geometry)
        line = beyond.warning("poses of the workspace box (its corners and random poses)") if beyond else None
        if line:
            warnings.append(f"{line}; the tables hold their end trims there, as the model holds its curve")
    if THERMAL_HAL_FILE in files:
        sensors = "hexcal-temp" if shared_sensor else "hexcal-temp-0 .. hexcal-temp-5"
        lines.append(
            f"thermal legs: load {THERMAL_HAL_FILE} after the machine's HAL file "
            f"([HAL] HALFILE = {THERMAL_HAL_FILE}); drive {sensors} from the legs' temperature sensors "
            "(°C) and name the drives' signals hexcal-drive-cmd-N and hexcal-drive-fb-N (its header says how)"
        )
    return Exported(files, lines, warnings)


def _builtin() -> None:
    from hexcal.io.linuxcnc import HAL_FILE, INI_FILE
    from hexcal.io.linuxcnc_comp import COMP_FILES
    from hexcal.io.linuxcnc_thermal import THERMAL_HAL_FILE

    files = (HAL_FILE, INI_FILE, *COMP_FILES, THERMAL_HAL_FILE)
    register_export(ControllerExport("linuxcnc", "LinuxCNC genhexkins", files, _linuxcnc, ("shared_sensor",)))


_builtin()
