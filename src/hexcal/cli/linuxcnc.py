"""LinuxCNC subcommands of ``hexcal``: ``export linuxcnc`` and ``import linuxcnc``.

- ``hexcal export linuxcnc --geometry G --out DIR`` writes ``DIR/hexcal-kins.hal`` and
  ``DIR/hexcal-joints.ini`` (both or neither);
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
#: ``HAL_FILE`` and ``INI_FILE``, spelled here so that the parser needs no numpy; a test
#: checks that they agree).
EXPORT_FILES = ("hexcal-kins.hal", "hexcal-joints.ini")
#: The joint compensation tables of a stroke leg model (``hexcal.io.linuxcnc_comp.COMP_FILES``).
COMP_FILES = tuple(f"hexcal-comp-{n}.tbl" for n in range(6))


def register(sub: Any, geometry_help: str = GEOMETRY_HELP) -> None:
    """Add ``export`` and ``import`` to the ``hexcal`` parser's subparsers."""
    p = sub.add_parser("export", help="write a geometry in a controller's format (LinuxCNC genhexkins)")
    p.add_argument("target", choices=("linuxcnc",), help="controller format")
    p.add_argument("--geometry", required=True, help=f"(calibrated) {geometry_help}")
    p.add_argument(
        "--out",
        required=True,
        help="folder for hexcal-kins.hal and hexcal-joints.ini, and hexcal-comp-0..5.tbl for a stroke "
        "leg model (created if missing)",
    )
    p.set_defaults(
        func=cmd_export,
        inputs=("geometry",),
        outputs=(),
        folders=("out",),
        folder_files={"out": EXPORT_FILES + COMP_FILES},
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
    """Write ``hexcal-kins.hal`` and ``hexcal-joints.ini`` through the command's output set.

    The two files are declared outputs of the command (``folder_files``): checked before the
    work like every output (an input, a FIFO, a read-only or hard-linked file is refused; a
    symbolic link is written through; a replaced file keeps its mode) and committed together.
    """
    from hexcal.core.presets import PRESETS
    from hexcal.io import check_input, load_geometry, write_text
    from hexcal.io.linuxcnc import euler_warning, export_linuxcnc

    geometry = load_geometry(args.geometry)
    if args.geometry in PRESETS:
        source, sha256, date = f"built-in preset {args.geometry}", None, None
    else:
        path = Path(args.geometry)
        check_input(path)
        data = path.read_bytes()
        import datetime
        import hashlib

        sha256 = hashlib.sha256(data).hexdigest()
        mtime = datetime.datetime.fromtimestamp(path.stat().st_mtime, tz=datetime.UTC)
        source, date = str(path), mtime.strftime("%Y-%m-%dT%H:%M:%SZ")
    files = export_linuxcnc(geometry, source=source, source_sha256=sha256, source_date=date)
    folder = Path(args.out)
    for name, text in files.items():
        write_text(folder / name, text)
    warning = euler_warning(geometry)
    if warning:
        _warn(warning)
    print(f"wrote {', '.join(str(folder / name) for name in files)}")
    print("paste: [HAL] HALFILE = hexcal-kins.hal; the [TRAJ], [JOINT_N], [AXIS_*] keys of hexcal-joints.ini")
    if COMP_FILES[0] in files:
        print(
            f"copy {COMP_FILES[0]} .. {COMP_FILES[-1]} into the machine's configuration folder (the joints' "
            "COMP_FILE tables of the stroke leg model)"
        )
        from hexcal.calibration import workspace_stroke_excess

        beyond = workspace_stroke_excess(geometry)
        line = beyond.warning("poses of the workspace box (its corners and random poses)") if beyond else None
        if line:
            _warn(f"{line}; the tables hold their end trims there, as the model holds its curve")


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
        + "(euler xyz: hexcal's a b c are G-code A B C in radians)"
    )
