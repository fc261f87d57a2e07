"""LinuxCNC ``genhexkins`` import: a geometry from a configuration's HAL and INI text.

See :mod:`hexcal.io.linuxcnc` for the conventions; parsing errors raise
:class:`~hexcal.io.linuxcnc.LinuxCNCFormatError` with one line naming the file and line.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.geometry import Geometry
from hexcal.io.linuxcnc import (
    GENHEXKINS_DEFAULT_BASE,
    GENHEXKINS_DEFAULT_PLATFORM,
    LINUXCNC_EULER,
    NUMBER,
    LinuxCNCFormatError,
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
_INI_REF = re.compile(r"\[([^\]\s]+)\]([^\s\[\]]+)")


@dataclass(frozen=True)
class IniFile:
    """A LinuxCNC INI file: ``(section, key) -> (value, line)`` of each key's first occurrence.

    A key that hexcal reads (:meth:`get`) must be set once, in a section that appears once:
    otherwise the file is refused, naming the file, the line and the key. (LinuxCNC takes
    the first value and reads only the first section of a name; a repeated key it does not
    read, such as ``[HAL] HALFILE``, is normal and stays allowed.)
    """

    name: str
    values: dict[tuple[str, str], tuple[str, int]]
    repeated: dict[tuple[str, str], tuple[int, int]] = field(default_factory=dict)
    """``(section, key) -> (first line, next line)`` of keys set more than once."""
    repeated_sections: dict[str, tuple[int, int]] = field(default_factory=dict)
    """``section -> (first line, next line)`` of section headers given more than once."""

    def get(self, section: str, key: str) -> tuple[str, int] | None:
        if section in self.repeated_sections:
            first, again = self.repeated_sections[section]
            raise LinuxCNCFormatError(
                f"{self.name}: line {again}: section [{section}] appears again (first on line {first}), "
                f"and hexcal reads its {key}; give each section once"
            )
        if (section, key) in self.repeated:
            first, again = self.repeated[section, key]
            raise LinuxCNCFormatError(
                f"{self.name}: line {again}: [{section}] {key} is set again (first on line {first}); "
                "give it once"
            )
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
    if not NUMBER.fullmatch(text):
        raise LinuxCNCFormatError(f"{file}: line {line}: {what}: {text!r} is not a number")
    value = float(text)
    if not math.isfinite(value):
        raise LinuxCNCFormatError(f"{file}: line {line}: {what}: {text!r} is out of range")
    return value


def parse_ini(text: str, name: str = "INI file") -> IniFile:
    """Read a LinuxCNC INI file (``[SECTION]``, ``KEY = VALUE``, ``#`` and ``;`` comments)."""
    values: dict[tuple[str, str], tuple[str, int]] = {}
    repeated: dict[tuple[str, str], tuple[int, int]] = {}
    sections: dict[str, int] = {}
    repeated_sections: dict[str, tuple[int, int]] = {}
    section: str | None = None
    for number, raw in enumerate(text.split("\n"), start=1):  # LinuxCNC's line ends: \n only
        line = raw.strip()
        if not line or line[0] in "#;":
            continue
        if line.startswith("["):
            match = re.fullmatch(r"\[([^\]]+)\]", line)
            if not match:
                raise LinuxCNCFormatError(f"{name}: line {number}: malformed section header {line!r}")
            section = match.group(1).strip()
            if section in sections:
                repeated_sections.setdefault(section, (sections[section], number))
            sections.setdefault(section, number)
            continue
        key, sep, value = line.partition("=")
        if not sep or not key.strip():
            raise LinuxCNCFormatError(f"{name}: line {number}: expected KEY = VALUE, got {line!r}")
        if section is None:
            raise LinuxCNCFormatError(f"{name}: line {number}: {key.strip()} is outside any [SECTION]")
        found = values.setdefault((section, key.strip()), (value.strip(), number))
        if found[1] != number:
            repeated.setdefault((section, key.strip()), (found[1], number))
    return IniFile(name, values, repeated, repeated_sections)


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
    for number, raw in enumerate(text.split("\n"), start=1):  # halcmd's line ends: \n only
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
    comp_reader: Callable[[str], str] | None = None,
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
    comp_reader : callable, optional
        The text of a ``[JOINT_N] COMP_FILE`` value (its file beside the INI): the joints'
        compensation tables become a stroke leg model (:mod:`hexcal.io.linuxcnc_comp`).

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
    from hexcal.core.kinematics import inverse_kinematics

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
                if lo > hi:  # LinuxCNC refuses every move of such a joint: no machine is described
                    line = ini.get(section, "MIN_LIMIT")[1]  # type: ignore[index]
                    raise LinuxCNCFormatError(
                        f"{ini_name}: line {line}: [{section}] MIN_LIMIT {lo:g} exceeds its MAX_LIMIT "
                        f"{hi:g}: the joint has no range"
                    )
                limits.append((lo, hi))

    geometry_mm = Geometry(
        base_joints=base * scale if scale != 1.0 else base,
        platform_joints=platform * scale if scale != 1.0 else platform,
        initial_leg_lengths=np.ones(6),  # a stand-in: only its joints are used, for l0 at home
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
        if 0 < lo < hi:
            leg_limits = (lo, hi)
        elif lo <= 0 < hi:
            warnings.append(
                f"{ini_name}: joint limits [{lo:g}, {hi:g}] mm are not strut lengths (min <= 0): "
                "leg length limits not set"
            )
        else:
            raise LinuxCNCFormatError(
                f"{ini_name}: the joints' limits have no common range (the tightest are [{lo:g}, {hi:g}] "
                "mm): hexcal's leg limits hold for every leg; correct MIN_LIMIT/MAX_LIMIT"
            )

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
    if ini is not None:  # joint compensation tables: a stroke leg model (hexcal.io.linuxcnc_comp)
        from hexcal.io.linuxcnc_checks import check_comp_tables, check_imported_model, comp_file_tables
        from hexcal.io.linuxcnc_comp import import_comp_tables

        tables = comp_file_tables(ini, comp_reader)
        if tables:
            check_comp_tables(ini, tables, geometry)
        geometry = import_comp_tables(geometry, ini, comp_reader, warnings)
        if tables:
            check_imported_model(geometry, ini.name, tables)
    return geometry, warnings
