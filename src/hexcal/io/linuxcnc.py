"""LinuxCNC ``genhexkins``: export a geometry to HAL/INI text and import one from them.

LinuxCNC drives a hexapod with its ``genhexkins`` kinematics module. Its parameters are
HAL pins ``genhexkins.base.N.x|y|z`` (base joint ``N`` in the base = world frame) and
``genhexkins.platform.N.x|y|z`` (platform joint ``N`` in the platform frame); joint ``N``
of the machine is the length of strut ``N``, and the pose words ``A B C`` are roll,
pitch and yaw in degrees, ``R = Rz(C) Ry(B) Rx(A)``: hexcal's Euler sequence ``xyz``
(extrinsic). The conventions, side by side:

==========================  =====================================  =========================
quantity                    hexcal                                 LinuxCNC genhexkins
==========================  =====================================  =========================
leg / strut ``i``           leg ``i`` (1..6), ``u_i``, ``s_i``     joint ``N = i - 1``
base joint                  ``base_joints[i-1]``, mm               ``genhexkins.base.N.*``
platform joint              ``platform_joints[i-1]``, mm           ``genhexkins.platform.N.*``
position                    pose ``x, y, z``, mm                   ``X Y Z`` ([TRAJ] mm)
orientation                 ``a, b, c`` rad, sequence ``xyz``      ``A B C``, degrees
strut length                ``l0_i + g_i dl_i``                    joint position
length at reading 0         ``l0_i``                               ``[JOINT_N] HOME_OFFSET``
leg gain                    ``g_i``                                scale / ``g_i``
==========================  =====================================  =========================

Everything here is text in, text out: :func:`export_linuxcnc` returns the two files'
contents and :func:`hexcal.io.linuxcnc_import.import_linuxcnc` parses given texts. Parsing errors raise
:class:`LinuxCNCFormatError` (a ``ValueError``) with one line naming the file and line.

LinuxCNC executes the HAL file (``halcmd`` runs every line: ``loadusr`` starts programs) and
reads the INI file, so nothing from an input reaches them except as a number or inside a
one-line comment (:func:`comment_line`): characters that are not printable (line breaks,
other control and format characters, Unicode line separators) are written as ``\\xNN`` /
``\\uNNNN`` escapes, a comment never ends in a backslash (``halcmd`` and LinuxCNC's INI
reader both continue such a line onto the next, comments included) and stays under
:data:`MAX_LINE_BYTES` (LinuxCNC's INI reader reads a longer line as two, the second parsed as
a key; ``halcmd`` refuses lines of about a kilobyte). :func:`check_export_lines` then checks
every line written against the grammar of the two files.
"""

from __future__ import annotations

import re

import numpy as np
from numpy.typing import NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.text import printable as _printable
from hexcal.errors import InputError
from hexcal.errors import LinuxCNCFormatError as LinuxCNCFormatError  # re-exported: its home before

#: File names written by :func:`export_linuxcnc`.
HAL_FILE = "hexcal-kins.hal"
INI_FILE = "hexcal-joints.ini"

#: LinuxCNC's pose angles are roll, pitch, yaw about the fixed X, Y, Z axes: scipy ``xyz``.
LINUXCNC_EULER = "xyz"

#: Defaults of LinuxCNC's ``genhexkins.h`` (the machine's linear units; inches in the
#: hexapod-sim sample configuration). Rows are joints 0..5, columns x, y, z.
GENHEXKINS_DEFAULT_BASE = np.array(
    [
        [-22.950, 13.250, 0.0],
        [22.950, 13.250, 0.0],
        [22.950, 13.250, 0.0],
        [0.000, -26.500, 0.0],
        [0.000, -26.500, 0.0],
        [-22.950, 13.250, 0.0],
    ]
)
GENHEXKINS_DEFAULT_PLATFORM = np.array(
    [
        [-1.000, 11.500, 0.0],
        [1.000, 11.500, 0.0],
        [10.459, -4.884, 0.0],
        [9.459, -6.616, 0.0],
        [-9.459, -6.616, 0.0],
        [-10.459, -4.884, 0.0],
    ]
)


#: A number as C's ``strtod`` reads it (no hex, inf or nan): the only values written.
NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")

#: Longest comment line written, in bytes (UTF-8). LinuxCNC's INI reader reads a line of
#: 255 bytes or more in pieces, each parsed as a line of its own (measured with LinuxCNC
#: 2.9's ``inivar``: ``#`` and 254 characters, then ``K = 1`` on the same line, sets ``K``);
#: ``halcmd`` refuses a line of about 1000 bytes.
MAX_LINE_BYTES = 200

#: Characters of one input value (a name, a path, a calibration field) in a comment.
MAX_VALUE_CHARS = 80

_HAL_LINE = re.compile(r"setp genhexkins\.(base|platform)\.[0-5]\.[xyz] (?P<v>\S+)")
_INI_SECTION = re.compile(r"\[(TRAJ|JOINT_[0-5]|AXIS_[XYZABC])\]")
_INI_WORDS = {"LINEAR_UNITS = mm", "ANGULAR_UNITS = degree", "COMP_FILE_TYPE = 1"} | {
    f"COMP_FILE = hexcal-comp-{n}.tbl" for n in range(6)
}
_INI_KEY = re.compile(
    r"(HOME|HOME_OFFSET|MIN_LIMIT|MAX_LIMIT|HEXCAL_LEG_GAIN|HEXCAL_STROKE|HEXCAL_STROKE_DEGREE)"
    r" = (?P<v>\S+( \S+)*)"
)


def printable(value: object, most: int = MAX_VALUE_CHARS) -> str:
    """``str(value)`` one line and printable (:func:`hexcal.core.text.printable`), cut to ``most``.

    >>> printable("m1\\nloadusr -w touch x")
    'm1\\\\x0aloadusr -w touch x'
    """
    return _printable(value, most)


def comment_line(text: str) -> str:
    """``# text`` as one safe comment line of a HAL or INI file (see the module's notes).

    >>> comment_line("name a\\\\")
    '# name a\\\\x5c'
    """
    line = "# " + printable(text, most=MAX_LINE_BYTES)
    if line.endswith("\\"):  # halcmd and the INI reader would join the next line to it
        line = line[:-1] + "\\x5c"
    while len(line.encode("utf-8")) > MAX_LINE_BYTES:  # printable non-ASCII: several bytes each
        line = line[:-4] + "..."
    return line


def _comment_ok(line: str) -> bool:
    return (
        line.startswith("#")
        and line.isprintable()
        and not line.endswith("\\")
        and len(line.encode("utf-8")) <= MAX_LINE_BYTES
    )


def check_export_lines(name: str, text: str) -> None:
    """Refuse to write a HAL or INI text with a line that is not a comment, a known section
    or key, or a ``setp`` of a ``genhexkins`` coordinate to a number (ValueError).

    The export builds its lines from numbers and :func:`comment_line`; this check makes sure
    that no other text can ever reach a file that LinuxCNC executes.
    """
    hal = name.endswith(".hal")
    for number, line in enumerate(text.split("\n")[:-1] if text.endswith("\n") else text.split("\n"), 1):
        if not line or _comment_ok(line):
            continue
        if hal:
            match = _HAL_LINE.fullmatch(line)
            values = [match["v"]] if match else None
        elif _INI_SECTION.fullmatch(line) or line in _INI_WORDS:
            continue
        else:
            match = _INI_KEY.fullmatch(line)
            values = match["v"].split(" ") if match else None
        if not values or not all(NUMBER.fullmatch(v) for v in values):
            raise ValueError(
                f"{name}: line {number} would be neither a comment nor a number ({printable(line, 60)!r}); "
                "nothing was written"
            )


# -- export -------------------------------------------------------------------------


def _num(value: float) -> str:
    """Shortest text that reads back (with C's strtod too) as exactly ``value``."""
    return repr(float(value))


def _xyz_degrees(angles: NDArray[np.float64], euler: str) -> NDArray[np.float64]:
    """LinuxCNC's ``A B C`` (degrees) of hexcal angles in sequence ``euler``."""
    if euler == LINUXCNC_EULER:
        return np.rad2deg(angles)
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler(euler, angles).as_euler(LINUXCNC_EULER, degrees=True)


def _header(geometry: Geometry, title: str, source: str, sha256: str | None, date: str | None) -> list[str]:
    """The comment lines at the top of both files; every input value through :func:`printable`."""
    lines = [comment_line(f"{title} -- written by hexcal's `hexcal export linuxcnc`")]
    name = f" (name {printable(geometry.name)})" if geometry.name else ""
    lines.append(comment_line(f"source geometry: {printable(source)}{name}"))
    if sha256:
        lines.append(comment_line(f"sha256 of the geometry file: {printable(sha256)}"))
    cal = geometry.calibration
    if cal:
        parts = [f"method {printable(cal.get('method', 'unknown'))}"]
        if "poses" in cal:
            parts.append(f"{printable(cal['poses'])} poses")
        if cal.get("data"):
            parts.append(f"data {printable(cal['data'])}")
        cal_date = cal.get("date") or (f"{date} (geometry file modified)" if date else "unknown")
        parts.append(f"date {printable(cal_date)}")
        lines.append(comment_line("calibration: " + ", ".join(parts)))
    else:
        lines.append("# calibration: none (this geometry was not identified by hexcal)")
    lines.append("# units: mm; the machine's INI must have [TRAJ] LINEAR_UNITS = mm, ANGULAR_UNITS = degree")
    lines.append(
        "# angles: LinuxCNC's A, B, C are hexcal's Euler sequence 'xyz' in degrees (extrinsic roll A"
    )
    lines.append("#   about X, pitch B about Y, yaw C about Z, all fixed axes: R = Rz(C) Ry(B) Rx(A))")
    if geometry.euler != LINUXCNC_EULER:  # a checked sequence: three letters of xyz or XYZ
        lines.append(
            f"#   NOTE: this geometry's poses use the sequence {geometry.euler!r}: its angles are not"
        )
        lines.append("#   G-code A B C; the joint coordinates below do not depend on the sequence")
    lines.append("# joints: LinuxCNC joint N is hexcal's leg N+1 (u_{N+1}, s_{N+1}, l0_{N+1}, g_{N+1})")
    return lines


def export_linuxcnc(
    geometry: Geometry,
    source: str = "(in memory)",
    source_sha256: str | None = None,
    source_date: str | None = None,
) -> dict[str, str]:
    """The ``genhexkins`` HAL file and the per-joint INI values of a geometry.

    Parameters
    ----------
    geometry : Geometry
    source : str
        Where the geometry came from (a file path or a preset name), for the header.
    source_sha256 : str, optional
        SHA-256 of the geometry file, for the header.
    source_date : str, optional
        The geometry file's modification time, given as the calibration date when the
        geometry's ``calibration`` has no ``date``.

    Returns
    -------
    dict of str to str
        ``{"hexcal-kins.hal": ..., "hexcal-joints.ini": ...}``.

    Notes
    -----
    Coordinates are written with Python's shortest round-trip representation, which
    C's ``strtod`` (used by ``halcmd``) reads back to the same double. The INI holds, per
    joint, ``HOME_OFFSET = l0`` (strut length at reading 0, i.e. at the home switch),
    ``HOME`` (strut length at the home pose), ``MIN_LIMIT``/``MAX_LIMIT`` (leg length
    limits) and ``HEXCAL_LEG_GAIN = g`` (the joint's position scale, counts per mm, is
    to be divided by ``g``); ``[TRAJ] HOME`` is the home pose and ``[AXIS_*]`` limits
    the workspace box, in LinuxCNC's ``X Y Z A B C``. A leg model with a curve of the stroke
    (``stroke``) adds, per joint, a compensation table (``COMP_FILE``, ``COMP_FILE_TYPE = 1``:
    :mod:`hexcal.io.linuxcnc_comp`), returned as ``hexcal-comp-N.tbl``, and its
    ``HOME_OFFSET`` is the model's length at reading 0; a leg model with terms but no stroke is
    refused rather than written without them.
    """
    tables = None
    if geometry.leg_model.stroke_range() is not None:
        from hexcal.io.linuxcnc_comp import comp_tables

        tables = comp_tables(geometry)
    elif geometry.leg_model.terms or geometry.leg_model.settings():
        raise InputError(
            f"{source}: the legs follow the {geometry.leg_model.name} model, which has no stroke to "
            "tabulate, and genhexkins struts are linear (l0 + g dl): its terms would be lost, so nothing "
            "is exported"
        )
    hal = _header(geometry, HAL_FILE, source, source_sha256, source_date)
    hal += [
        "# use: in the machine's INI, [HAL] HALFILE = hexcal-kins.hal after the file that loads",
        "#   genhexkins ([KINS] KINEMATICS = genhexkins), and delete the machine's own",
        "#   'setp genhexkins.base.*' and 'setp genhexkins.platform.*' lines; leave",
        "#   genhexkins.spindle-offset at 0 (hexcal's platform frame is the measured one)",
        "",
    ]
    for part, joints in (("base", geometry.base_joints), ("platform", geometry.platform_joints)):
        frame = "base (world) frame" if part == "base" else "platform frame"
        hal.append(f"# {part} joints, {frame}, mm")
        for n in range(6):
            for k, axis in enumerate("xyz"):
                hal.append(f"setp genhexkins.{part}.{n}.{axis} {_num(joints[n, k])}")
        hal.append("")

    ini = _header(geometry, INI_FILE, source, source_sha256, source_date)
    ini += [
        "# Copy each key below into the section of the same name in the machine's INI file,",
        "# replacing the key there. Strut model: strut length (mm) = l0 + g * dl, where dl is the",
        "# strut reading the calibration was measured with (mm from the home switch at the old",
        "# scale: for a geometry from `hexcal import linuxcnc`, joint position - old HOME_OFFSET).",
        "# LinuxCNC ignores the HEXCAL_* keys; `hexcal import linuxcnc` reads them back.",
        "",
        "[TRAJ]",
        "LINEAR_UNITS = mm",
        "ANGULAR_UNITS = degree",
    ]
    home_lengths = None
    if geometry.home_pose is not None:
        from hexcal.core.kinematics import inverse_kinematics

        home = geometry.home_pose
        abc = _xyz_degrees(home[3:], geometry.euler)
        words = " ".join(_num(v) for v in (*home[:3], *abc))
        ini += [
            "# home pose X Y Z (mm) A B C (degrees): where the forward kinematics starts after homing",
            f"HOME = {words}",
        ]
        home_lengths = inverse_kinematics(geometry, home)
    ini.append("")
    from hexcal.core.kinematics import leg_lengths

    at_switch = leg_lengths(geometry, np.zeros(6))  # l0 for linear legs
    for n in range(6):
        ini += [
            f"[JOINT_{n}]",
            f"# hexcal leg {n + 1}. HOME_OFFSET: strut length at reading dl = 0 (l0; with a stroke model",
            "# l0 plus its curve there), mm; the joint position the home switch sets",
            f"HOME_OFFSET = {_num(at_switch[n])}",
        ]
        if home_lengths is not None:
            ini += [
                "# HOME: strut length at the home pose, mm; where the joint goes after homing",
                f"HOME = {_num(home_lengths[n])}",
            ]
        if geometry.leg_length_limits is not None:
            lo, hi = geometry.leg_length_limits
            ini += [
                "# strut length limits, mm",
                f"MIN_LIMIT = {_num(lo)}",
                f"MAX_LIMIT = {_num(hi)}",
            ]
        ini += [
            "# leg gain g, mm of strut per mm of reading. Scale correction: divide this joint's",
            "# position scale (counts per mm: stepgen/encoder SCALE, INPUT_SCALE, OUTPUT_SCALE) by g",
            f"HEXCAL_LEG_GAIN = {_num(geometry.leg_gains[n])}",
        ]
        if tables is not None:
            ini += _comp_lines(geometry, n, tables[n])
        ini.append("")
    if geometry.workspace is not None:
        box = geometry.workspace
        for k, axis in enumerate("XYZ"):
            ini += [
                f"[AXIS_{axis}]",
                "# workspace box, mm",
                f"MIN_LIMIT = {_num(box[k, 0])}",
                f"MAX_LIMIT = {_num(box[k, 1])}",
                "",
            ]
        if geometry.euler == LINUXCNC_EULER:
            for k, axis in enumerate("ABC"):
                lo, hi = np.rad2deg(box[k + 3])
                ini += [
                    f"[AXIS_{axis}]",
                    "# workspace box, degrees",
                    f"MIN_LIMIT = {_num(lo)}",
                    f"MAX_LIMIT = {_num(hi)}",
                    "",
                ]
        else:
            ini += [
                "# [AXIS_A], [AXIS_B], [AXIS_C]: not written; the workspace's angle ranges are in the",
                f"# sequence {geometry.euler!r}, which is not a box in LinuxCNC's A B C",
                "",
            ]
    files = {HAL_FILE: "\n".join(hal).rstrip("\n") + "\n", INI_FILE: "\n".join(ini).rstrip("\n") + "\n"}
    for file_name, text in files.items():
        check_export_lines(file_name, text)
    if tables is not None:
        from hexcal.io.linuxcnc_comp import COMP_FILES, format_comp_table

        files |= {COMP_FILES[n]: format_comp_table(table) for n, table in enumerate(tables)}
    return files


def _comp_lines(geometry: Geometry, n: int, table: object) -> list[str]:
    """The ``[JOINT_N]`` keys of a stroke model's compensation table (numbers and fixed text)."""
    from hexcal.io.linuxcnc_comp import COMP_FILES

    model = geometry.leg_model
    low, high = model.stroke_range()  # type: ignore[misc]
    return [
        f"# stroke leg model of degree {int(model.settings()[0])}: the strut's length is not linear in its",
        "# reading. LinuxCNC adds the trim of this table (strut length mm -> trim mm, interpolated,",
        f"# {len(table.nominal)} entries, within {table.max_error:.2g} mm) to the joint position; keep the",  # type: ignore[attr-defined]
        "# file beside the machine's INI file (LinuxCNC opens it from the configuration's folder).",
        "# The table spans the calibrated stroke; beyond it LinuxCNC holds the end trims, which is the",
        "# model's own continuation (its curve held, the strut following its gain)",
        f"COMP_FILE = {COMP_FILES[n]}",
        "COMP_FILE_TYPE = 1",
        "# the stroke (readings) and degree the table was made from, for `hexcal import linuxcnc`",
        f"HEXCAL_STROKE = {_num(low[n])} {_num(high[n])}",
        f"HEXCAL_STROKE_DEGREE = {int(model.settings()[0])}",
    ]


def euler_warning(geometry: Geometry) -> str | None:
    """The one-line warning for a geometry whose angles are not LinuxCNC's, or None."""
    if geometry.euler == LINUXCNC_EULER:
        return None
    return (
        f"the geometry's angles use the Euler sequence {geometry.euler!r}, LinuxCNC's A B C are "
        f"'xyz' (roll-pitch-yaw, degrees): the joint coordinates are exported unchanged, but G-code "
        f"angles mean 'xyz' angles"
    )


# -- reading HAL and INI files --------------------------------------------------------
