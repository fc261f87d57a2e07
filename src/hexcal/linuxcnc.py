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
contents and :func:`import_linuxcnc` parses given texts. Parsing errors raise
:class:`LinuxCNCFormatError` (a ``ValueError``) with one line naming the file and line.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.geometry import Geometry

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

_LINEAR_UNITS = {
    "mm": 1.0,
    "metric": 1.0,
    "millimeter": 1.0,
    "millimeters": 1.0,
    "inch": 25.4,
    "in": 25.4,
    "imperial": 25.4,
    "inches": 25.4,
}
_COORD = re.compile(r"genhexkins\.(base|platform)\.(\d+)\.([xyz])")
# a number as C's strtod reads it, without hex, inf and nan
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")
_INI_REF = re.compile(r"\[([^\]\s]+)\]([^\s\[\]]+)")


class LinuxCNCFormatError(ValueError):
    """A HAL or INI file cannot be read; the message names the file and the line."""


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
    lines = [f"# {title} -- written by hexcal's `hexcal export linuxcnc`"]
    name = f" (name {geometry.name})" if geometry.name else ""
    lines.append(f"# source geometry: {source}{name}")
    if sha256:
        lines.append(f"# sha256 of the geometry file: {sha256}")
    cal = geometry.calibration
    if cal:
        parts = [f"method {cal.get('method', 'unknown')}"]
        if "poses" in cal:
            parts.append(f"{cal['poses']} poses")
        if cal.get("data"):
            parts.append(f"data {cal['data']}")
        cal_date = cal.get("date") or (f"{date} (geometry file modified)" if date else "unknown")
        parts.append(f"date {cal_date}")
        lines.append("# calibration: " + ", ".join(parts))
    else:
        lines.append("# calibration: none (this geometry was not identified by hexcal)")
    lines.append("# units: mm; the machine's INI must have [TRAJ] LINEAR_UNITS = mm, ANGULAR_UNITS = degree")
    lines.append(
        "# angles: LinuxCNC's A, B, C are hexcal's Euler sequence 'xyz' in degrees (extrinsic roll A"
    )
    lines.append("#   about X, pitch B about Y, yaw C about Z, all fixed axes: R = Rz(C) Ry(B) Rx(A))")
    if geometry.euler != LINUXCNC_EULER:
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
    the workspace box, in LinuxCNC's ``X Y Z A B C``.
    """
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
        from hexcal.kinematics import inverse_kinematics

        home = geometry.home_pose
        abc = _xyz_degrees(home[3:], geometry.euler)
        words = " ".join(_num(v) for v in (*home[:3], *abc))
        ini += [
            "# home pose X Y Z (mm) A B C (degrees): where the forward kinematics starts after homing",
            f"HOME = {words}",
        ]
        home_lengths = inverse_kinematics(geometry, home)
    ini.append("")
    for n in range(6):
        ini += [
            f"[JOINT_{n}]",
            f"# hexcal leg {n + 1}. HOME_OFFSET: strut length at reading dl = 0 (l0), mm; the joint",
            "# position the home switch sets",
            f"HOME_OFFSET = {_num(geometry.initial_leg_lengths[n])}",
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
            "",
        ]
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
    return {HAL_FILE: "\n".join(hal).rstrip("\n") + "\n", INI_FILE: "\n".join(ini).rstrip("\n") + "\n"}


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


@dataclass(frozen=True)
class IniFile:
    """A LinuxCNC INI file: ``(section, key) -> (value, line)``; the first occurrence wins."""

    name: str
    values: dict[tuple[str, str], tuple[str, int]]

    def get(self, section: str, key: str) -> tuple[str, int] | None:
        return self.values.get((section, key))

    def number(self, section: str, key: str) -> float | None:
        found = self.get(section, key)
        if found is None:
            return None
        text, line = found
        return _parse_number(text, self.name, line, f"[{section}] {key}")

    def numbers(self, section: str, key: str) -> list[float] | None:
        found = self.get(section, key)
        if found is None:
            return None
        text, line = found
        return [_parse_number(t, self.name, line, f"[{section}] {key}") for t in text.split()]


def _parse_number(text: str, file: str, line: int, what: str) -> float:
    if not _NUMBER.fullmatch(text):
        raise LinuxCNCFormatError(f"{file}: line {line}: {what}: {text!r} is not a number")
    value = float(text)
    if not math.isfinite(value):
        raise LinuxCNCFormatError(f"{file}: line {line}: {what}: {text!r} is out of range")
    return value


def parse_ini(text: str, name: str = "INI file") -> IniFile:
    """Read a LinuxCNC INI file (``[SECTION]``, ``KEY = VALUE``, ``#`` and ``;`` comments)."""
    values: dict[tuple[str, str], tuple[str, int]] = {}
    section: str | None = None
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line[0] in "#;":
            continue
        if line.startswith("["):
            match = re.fullmatch(r"\[([^\]]+)\]", line)
            if not match:
                raise LinuxCNCFormatError(f"{name}: line {number}: malformed section header {line!r}")
            section = match.group(1).strip()
            continue
        key, sep, value = line.partition("=")
        if not sep or not key.strip():
            raise LinuxCNCFormatError(f"{name}: line {number}: expected KEY = VALUE, got {line!r}")
        if section is None:
            raise LinuxCNCFormatError(f"{name}: line {number}: {key.strip()} is outside any [SECTION]")
        values.setdefault((section, key.strip()), (value.strip(), number))
    return IniFile(name, values)


@dataclass(frozen=True)
class HalSettings:
    """The ``setp genhexkins...`` values of a HAL file."""

    coordinates: dict[tuple[str, int, int], float]
    """``(part, joint, axis) -> value`` with part ``base`` or ``platform``, axis 0..2."""
    options: dict[str, float]
    """``spindle-offset``, ``tool-offset``, ``screw-lead`` when set."""
    warnings: list[str]


def parse_hal(text: str, name: str = "HAL file", ini: IniFile | None = None) -> HalSettings:
    """The ``setp genhexkins.*`` lines of a HAL file; other commands are ignored.

    ``[SECTION]KEY`` values are replaced from ``ini`` as ``halcmd -i`` does. A coordinate
    set twice takes the last value (as HAL does), with a warning.
    """
    coordinates: dict[tuple[str, int, int], float] = {}
    seen: dict[tuple[str, int, int], int] = {}
    options: dict[str, float] = {}
    warnings: list[str] = []
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        tokens = line.split()
        if not tokens or tokens[0] != "setp" or len(tokens) < 2 or not tokens[1].startswith("genhexkins."):
            continue
        pin = tokens[1]
        match = _COORD.fullmatch(pin)
        option = pin.removeprefix("genhexkins.")
        if not match and option not in ("spindle-offset", "tool-offset", "screw-lead"):
            continue  # iteration controls, joint axis vectors...: not part of hexcal's model
        if len(tokens) != 3:
            raise LinuxCNCFormatError(f"{name}: line {number}: expected 'setp {pin} VALUE', got {line!r}")
        value_text = tokens[2]
        ref = _INI_REF.fullmatch(value_text)
        if ref:
            if ini is None:
                raise LinuxCNCFormatError(
                    f"{name}: line {number}: {pin} is set from {value_text}: give the INI file (--ini)"
                )
            found = ini.get(ref.group(1), ref.group(2))
            if found is None:
                raise LinuxCNCFormatError(f"{name}: line {number}: {value_text} is not in {ini.name}")
            value_text = found[0]
        value = _parse_number(value_text, name, number, pin)
        if match:
            part, joint, axis = match.group(1), int(match.group(2)), "xyz".index(match.group(3))
            if joint > 5:
                raise LinuxCNCFormatError(f"{name}: line {number}: {pin}: genhexkins has joints 0..5")
            key = (part, joint, axis)
            if key in seen:
                warnings.append(f"{name}: {pin} is set on lines {seen[key]} and {number}; line {number} wins")
            coordinates[key], seen[key] = value, number
            continue
        options[option] = value
    return HalSettings(coordinates, options, warnings)


# -- import -------------------------------------------------------------------------


def _names(keys: Sequence[tuple[str, int, int]]) -> str:
    return ", ".join(f"{part}.{joint}.{'xyz'[axis]}" for part, joint, axis in keys)


def _home_pose_radians(pose_deg: Sequence[float]) -> NDArray[np.float64]:
    pose = np.array(pose_deg, dtype=float)
    pose[3:] = np.deg2rad(pose[3:])
    return pose


def import_linuxcnc(
    hal_text: str,
    ini_text: str | None = None,
    *,
    hal_name: str = "HAL file",
    ini_name: str = "INI file",
    home_pose: ArrayLike | None = None,
    name: str | None = None,
) -> tuple[Geometry, list[str]]:
    """A hexcal geometry from a LinuxCNC ``genhexkins`` configuration.

    Parameters
    ----------
    hal_text : str
        HAL file text with the ``setp genhexkins.base|platform.N.x|y|z`` lines. A
        coordinate not set takes its ``genhexkins.h`` default (with a warning).
    ini_text : str, optional
        The machine's INI file text: units, ``[TRAJ] HOME``, per-joint ``HOME_OFFSET``,
        ``MIN_LIMIT``/``MAX_LIMIT``, ``HEXCAL_LEG_GAIN`` and the ``[AXIS_*]`` limits.
    hal_name, ini_name : str
        File names for messages.
    home_pose : array_like, shape (6,), optional
        ``X Y Z`` (machine units) and ``A B C`` (degrees) of the home pose when the INI
        has no ``[TRAJ] HOME``. Default ``(0, 0, h, 0, 0, 0)`` with ``h`` the mean
        distance of the base joints from the Z axis (struts at about 45 degrees).
    name : str, optional
        Geometry name (default: the INI's ``[EMC] MACHINE``, else ``linuxcnc``).

    Returns
    -------
    geometry : Geometry
        In mm, with ``euler = "xyz"`` (G-code's A B C). ``l0`` is ``[JOINT_N]
        HOME_OFFSET`` where given, else the strut length at the home pose; gains are
        ``HEXCAL_LEG_GAIN`` where given, else 1; leg length limits are the tightest
        joint limits; the workspace is the ``[AXIS_X..C]`` box when all six are given
        and the angle limits are within ±90 degrees.
    warnings : list of str
        One line each, for the user.
    """
    from hexcal.kinematics import inverse_kinematics

    ini = parse_ini(ini_text, ini_name) if ini_text is not None else None
    hal = parse_hal(hal_text, hal_name, ini)
    warnings = list(hal.warnings)

    scale = 1.0
    if ini is not None:
        units = ini.get("TRAJ", "LINEAR_UNITS")
        if units is not None:
            unit = units[0].strip().lower()
            if unit not in _LINEAR_UNITS:
                raise LinuxCNCFormatError(
                    f"{ini_name}: line {units[1]}: [TRAJ] LINEAR_UNITS = {units[0]!r} is not mm or inch"
                )
            scale = _LINEAR_UNITS[unit]
            if scale != 1.0:
                warnings.append(
                    f"{ini_name}: LINEAR_UNITS is {units[0]}: lengths converted to mm (x {scale})"
                )
        angular = ini.get("TRAJ", "ANGULAR_UNITS")
        if angular is not None and angular[0].strip().lower() not in ("degree", "deg", "degrees"):
            raise LinuxCNCFormatError(
                f"{ini_name}: line {angular[1]}: [TRAJ] ANGULAR_UNITS = {angular[0]!r}: "
                "genhexkins works in degrees"
            )

    base = GENHEXKINS_DEFAULT_BASE.copy()
    platform = GENHEXKINS_DEFAULT_PLATFORM.copy()
    missing = []
    for part, joints in (("base", base), ("platform", platform)):
        for n in range(6):
            for axis in range(3):
                key = (part, n, axis)
                if key in hal.coordinates:
                    joints[n, axis] = hal.coordinates[key]
                else:
                    missing.append(key)
    if len(missing) == 36:
        warnings.append(
            f"{hal_name}: no 'setp genhexkins.base|platform' line: all 36 joint coordinates are "
            "genhexkins.h defaults"
        )
    elif missing:
        warnings.append(f"{hal_name}: not set, genhexkins.h defaults used: {_names(missing)}")
    offset = hal.options.get("spindle-offset", 0.0)
    if offset:
        base[:, 2] += offset
        platform[:, 2] += offset
        warnings.append(
            f"{hal_name}: genhexkins.spindle-offset {offset!r} added to the z of every joint "
            "(export writes the sum; set the offset to 0 with it)"
        )
    if hal.options.get("screw-lead", 0.0):
        warnings.append(
            f"{hal_name}: genhexkins.screw-lead is set: its strut length correction is not in "
            "hexcal's model and is ignored"
        )

    # home pose, in machine units and degrees
    home_words: list[float] | None = None
    if ini is not None:
        home_words = ini.numbers("TRAJ", "HOME")
        if home_words is not None and len(home_words) != 6:
            line = ini.get("TRAJ", "HOME")[1]  # type: ignore[index]
            warnings.append(
                f"{ini_name}: line {line}: [TRAJ] HOME has {len(home_words)} values, not 6: ignored"
            )
            home_words = None
    home_source = "[TRAJ] HOME"
    if home_words is None and home_pose is not None:
        home_words = [float(v) for v in np.asarray(home_pose, dtype=float).ravel()]
        if len(home_words) != 6:
            raise ValueError(f"home pose must have 6 values X Y Z A B C, got {len(home_words)}")
        home_source = "the given home pose"
    if home_words is None:
        height = float(np.mean(np.hypot(base[:, 0], base[:, 1])))
        home_words = [0.0, 0.0, height, 0.0, 0.0, 0.0]
        home_source = "the default home pose"

    # per-joint values
    l0 = np.full(6, np.nan)
    gains = np.ones(6)
    limits: list[tuple[float, float]] = []
    if ini is not None:
        for n in range(6):
            section = f"JOINT_{n}"
            offset_value = ini.number(section, "HOME_OFFSET")
            if offset_value is not None:
                l0[n] = offset_value
            gain = ini.number(section, "HEXCAL_LEG_GAIN")
            if gain is not None:
                if not gain > 0:
                    line = ini.get(section, "HEXCAL_LEG_GAIN")[1]  # type: ignore[index]
                    raise LinuxCNCFormatError(f"{ini_name}: line {line}: HEXCAL_LEG_GAIN must be > 0")
                gains[n] = gain
            lo, hi = ini.number(section, "MIN_LIMIT"), ini.number(section, "MAX_LIMIT")
            if lo is not None and hi is not None:
                limits.append((lo, hi))

    geometry_mm = Geometry(
        base_joints=base * scale if scale != 1.0 else base,
        platform_joints=platform * scale if scale != 1.0 else platform,
        initial_leg_lengths=np.zeros(6),
        euler=LINUXCNC_EULER,
    )
    home = _home_pose_radians(home_words)
    home[:3] *= scale
    no_offset = np.flatnonzero(np.isnan(l0))
    if no_offset.size:
        at_home = inverse_kinematics(geometry_mm, home)
        l0[no_offset] = at_home[no_offset] / scale
        pose_text = " ".join(f"{v:g}" for v in home_words)
        if ini is None:
            what = "no INI file"
        else:
            what = "no [JOINT_N] HOME_OFFSET for joint(s) " + ", ".join(str(n) for n in no_offset)
        source = f"{home_source} X Y Z A B C = {pose_text}"
        warnings.append(f"{what}: initial leg lengths l0 are the strut lengths at {source}")
    l0 = l0 * scale

    leg_limits = None
    if len(limits) == 6:
        lows, highs = zip(*limits, strict=True)
        lo, hi = max(lows) * scale, min(highs) * scale
        if len(set(lows)) > 1 or len(set(highs)) > 1:
            warnings.append(f"{ini_name}: joint limits differ: the tightest, [{lo:g}, {hi:g}] mm, are used")
        if lo < hi:
            leg_limits = (lo, hi)
        else:
            warnings.append(f"{ini_name}: joint limits leave no range: leg length limits not set")

    workspace = None
    if ini is not None:
        box = []
        for axis in "XYZABC":
            lo, hi = ini.number(f"AXIS_{axis}", "MIN_LIMIT"), ini.number(f"AXIS_{axis}", "MAX_LIMIT")
            if lo is None or hi is None:
                break
            box.append((lo, hi))
        if len(box) == 6:
            arr = np.array(box, dtype=float)
            if np.any(np.abs(arr[3:]) > 90.0):
                warnings.append(
                    f"{ini_name}: [AXIS_A..C] limits go beyond ±90 degrees: no workspace box taken "
                    "(give one in the geometry YAML)"
                )
            elif np.any(arr[:, 0] > arr[:, 1]):
                warnings.append(
                    f"{ini_name}: an [AXIS_*] MIN_LIMIT exceeds its MAX_LIMIT: no workspace taken"
                )
            else:
                arr[:3] *= scale
                arr[3:] = np.deg2rad(arr[3:])
                workspace = arr

    if name is None:
        machine = ini.get("EMC", "MACHINE") if ini is not None else None
        name = machine[0] if machine else "linuxcnc"
    geometry = geometry_mm.replace(
        initial_leg_lengths=l0,
        leg_gains=gains,
        leg_length_limits=leg_limits,
        home_pose=home,
        workspace=workspace,
        name=name,
    )
    return geometry, warnings
