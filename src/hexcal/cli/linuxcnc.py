"""Controller subcommands of ``hexcal``: ``export CONTROLLER`` and ``import linuxcnc``.

- ``hexcal export CONTROLLER --geometry G --out DIR`` writes the files of a registered
  controller export (:data:`hexcal.io.exports.EXPORTS`; ``linuxcnc``: ``DIR/hexcal-kins.hal``
  and ``DIR/hexcal-joints.ini``, the compensation tables of a stroke leg model and the
  run-time ``hexcal-thermal.hal`` of a thermal one), all or none;
- ``hexcal import linuxcnc --hal FILE [--ini FILE] --out G.yaml`` writes a geometry of
  the machine a LinuxCNC configuration describes.

The module imports the standard library only; numpy and hexcal's modules are imported
inside the commands, so that ``hexcal --help`` stays fast. Known failures raise
``ValueError`` subclasses, which ``hexcal.cli.main`` prints as one line.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

from hexcal.cli.common import GEOMETRY_HELP, CommandError

#: The files ``export linuxcnc`` writes into its ``--out`` folder (``hexcal.io.linuxcnc``'s
#: ``HAL_FILE`` and ``INI_FILE``, spelled here for the tests; a test checks that they agree).
EXPORT_FILES = ("hexcal-kins.hal", "hexcal-joints.ini")
#: The joint compensation tables of a stroke leg model (``hexcal.io.linuxcnc_comp.COMP_FILES``).
COMP_FILES = tuple(f"hexcal-comp-{n}.tbl" for n in range(6))
#: The run-time file of a thermal leg model (``hexcal.io.linuxcnc_thermal.THERMAL_HAL_FILE``).
THERMAL_FILE = "hexcal-thermal.hal"


def _export_files(target: str) -> tuple[str, ...]:
    """The files the export ``target`` may write (its record's; declared before any work)."""
    from hexcal.io.exports import export_files

    return export_files(target)


def register(sub: Any, geometry_help: str = GEOMETRY_HELP) -> None:
    """Add ``export`` and ``import`` to the ``hexcal`` parser's subparsers."""
    p = sub.add_parser("export", help="write a geometry in a controller's format (LinuxCNC genhexkins)")
    p.add_argument("target", metavar="CONTROLLER", help="controller format: a registered export (linuxcnc)")
    p.add_argument("--geometry", required=True, help=f"(calibrated) {geometry_help}")
    p.add_argument(
        "--out",
        required=True,
        help="folder for the controller's files (linuxcnc: hexcal-kins.hal and hexcal-joints.ini, "
        "hexcal-comp-0..5.tbl for a stroke leg model, hexcal-thermal.hal for a thermal one; created if "
        "missing)",
    )
    p.add_argument(
        "--shared-sensor",
        action="store_true",
        help="linuxcnc, a thermal leg model: one temperature sensor for every leg (signal hexcal-temp) "
        "instead of one per leg (hexcal-temp-0..5)",
    )
    p.set_defaults(
        func=cmd_export,
        inputs=("geometry",),
        outputs=(),
        folders=("out",),
        folder_files={"out": lambda args: _export_files(args.target)},
    )

    p = sub.add_parser("import", help="a geometry from a controller's configuration (LinuxCNC genhexkins)")
    p.add_argument("target", choices=("linuxcnc",), help="controller format")
    p.add_argument("--hal", required=True, help="HAL file with the 'setp genhexkins...' lines")
    p.add_argument(
        "--ini",
        help="the machine's INI file (units, HOME_OFFSET, limits, [TRAJ] HOME; its joints' COMP_FILE "
        "tables, read from the INI's folder, become a stroke leg model)",
    )
    p.add_argument(
        "--home",
        metavar="X,Y,Z,A,B,C",
        help="home pose (machine units, degrees) when the INI has no [TRAJ] HOME; "
        "l0 is the strut lengths there for joints without HOME_OFFSET",
    )
    p.add_argument("--name", help="geometry name (default: the INI's [EMC] MACHINE)")
    p.add_argument("--out", required=True, help="geometry YAML file to write")
    p.set_defaults(func=cmd_import, inputs=("hal", "ini"), outputs=("out",), folders=())


def _warn(message: str) -> None:
    print(f"hexcal: warning: {message}", file=sys.stderr)


#: Bytes a HAL or INI file may have (a machine's configuration is a few kB).
MAX_CONFIG_BYTES = 16 * 1024 * 1024


def _read_text(path: str, what: str) -> str:
    """A configuration file, read like every input: a regular file, within a size limit."""
    from hexcal.io.inputs import read_text

    if not os.path.lexists(path):
        raise CommandError(f"{path}: no such {what} file")
    return read_text(path, max_bytes=MAX_CONFIG_BYTES)


def cmd_export(args: argparse.Namespace) -> None:
    """Write a registered controller export's files through the command's output set.

    The files are declared outputs of the command (``folder_files``, from the export's record):
    checked before the work like every output (an input, a FIFO, a read-only or hard-linked file
    is refused; a symbolic link is written through; a replaced file keeps its mode) and
    committed together.
    """
    from hexcal.io import load_geometry, write_text
    from hexcal.io.exports import controller_export, export_geometry, geometry_source

    controller_export(args.target)  # an unknown controller: one line, before anything is read
    geometry = load_geometry(args.geometry)
    done = export_geometry(
        args.target, geometry, {"shared_sensor": args.shared_sensor}, **geometry_source(args.geometry)
    )
    folder = Path(args.out)
    for name, text in done.files.items():
        write_text(folder / name, text)
    print(f"wrote {', '.join(str(folder / name) for name in done.files)}")
    for line in done.lines:
        print(line)
    for warning in done.warnings:
        _warn(warning)


def _parse_home(text: str) -> list[float]:
    parts = [p.strip() for p in text.replace(" ", ",").split(",") if p.strip()]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise CommandError(f"--home: {text!r} is not six numbers X,Y,Z,A,B,C") from None
    if len(values) != 6 or not all(abs(v) < float("inf") for v in values):
        raise CommandError(f"--home: {text!r} is not six finite numbers X,Y,Z,A,B,C")
    return values


def cmd_import(args: argparse.Namespace) -> None:
    """Write the geometry of a LinuxCNC configuration (``--out`` is checked by the command's
    output set before this runs: not an input, its folder writable)."""
    from hexcal.errors import GeometryError
    from hexcal.io import save_geometry
    from hexcal.io.linuxcnc import sequence_note
    from hexcal.io.linuxcnc_import import import_linuxcnc

    out = Path(args.out)
    hal_text = _read_text(args.hal, "HAL")
    ini_text = _read_text(args.ini, "INI") if args.ini else None
    home = _parse_home(args.home) if args.home else None

    def comp_reader(value: str) -> str:  # a COMP_FILE beside the INI, as LinuxCNC opens it
        path = Path(args.ini).parent / value
        if path.resolve() == out.resolve():
            raise CommandError(f"--out {out}: it is the compensation table {path} that the INI names")
        return _read_text(str(path), "compensation table")

    geometry, warnings = import_linuxcnc(
        hal_text,
        ini_text,
        hal_name=args.hal,
        ini_name=args.ini or "INI file",
        home_pose=home,
        name=args.name,
        comp_reader=comp_reader,
    )
    try:  # the rules of every geometry hexcal reads: never write one it would refuse to load
        geometry.check_plausible()
    except GeometryError as exc:
        files = f"{args.hal} and {args.ini}" if args.ini else args.hal
        raise CommandError(f"{files}: hexcal cannot use the machine they describe: {exc}") from None
    save_geometry(geometry, out)
    for warning in warnings:
        _warn(warning)
    print(
        f"wrote the geometry of {args.hal}{' and ' + args.ini if args.ini else ''} to {out} "
        + f"({sequence_note(geometry)})"
    )
