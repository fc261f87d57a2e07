"""How a parameter is shown to a person: its unit, its value in that unit, and its block.

Results hold lengths in mm, gains as pure numbers and angles in rad; a report shows the
instrument angles (``frame.a/b/c``, ``tool.a/b/c``) in degrees wherever they appear (text,
pages, figures), so that one table never says rad where the next says deg. Parameters are
grouped in the blocks a person thinks in (base joints, platform joints, l0, gains, the
instrument frame, the tool, the targets), each session's own. Standard library only.

>>> round(display("frame.a", 0.5235987755982988), 9), parameter_unit("frame.a"), parameter_unit("g1")
(30.0, 'deg', '1')
>>> block_of("session2.t3.x"), block_of("u4.y")
('session 2 targets', 'base joints')
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from typing import Any

_SESSION = re.compile(r"^session(\d+)\.")

#: Block labels by the leading letters of a parameter name (after a session prefix).
BLOCK_LABELS = {
    "u": "base joints",
    "s": "platform joints",
    "l": "l0",
    "g": "gains",
    "frame": "instrument frame",
    "tool": "tool",
    "t": "targets",
}

#: Unit words of the tables, by unit.
UNIT_WORDS = {"mm": "mm", "deg": "deg", "1": "dimensionless"}


def _bare(name: str) -> tuple[str, str]:
    """``(session prefix label, name without it)``: ``("session 2 ", "frame.a")``."""
    match = _SESSION.match(name)
    if match is None:
        return "", name
    return f"session {match.group(1)} ", name[match.end() :]


def is_angle(name: str) -> bool:
    """An instrument angle (``frame.a/b/c``, ``tool.a/b/c``, of any session): held in rad,
    shown in degrees."""
    bare = _bare(name)[1]
    return bare.startswith(("frame.", "tool.")) and bare.rsplit(".", 1)[-1] in ("a", "b", "c")


def is_gain(name: str) -> bool:
    """A leg gain (``g1`` ... ``g6``): dimensionless."""
    return re.fullmatch(r"g\d+", _bare(name)[1]) is not None


def parameter_unit(name: str) -> str:
    """The unit a parameter is shown in: ``deg`` (instrument angles), ``1`` (gains) or ``mm``."""
    if is_angle(name):
        return "deg"
    return "1" if is_gain(name) else "mm"


def display(name: str, value: Any) -> Any:
    """A value (or standard error) of parameter ``name`` in its display unit (degrees for
    instrument angles); None and non-numbers pass through."""
    if value is None or isinstance(value, bool) or not isinstance(value, int | float):
        return value
    return math.degrees(value) if is_angle(name) else value


def block_of(name: str) -> str:
    """The block a parameter belongs to (``base joints``, ``session 2 targets``, ...)."""
    session, bare = _bare(name)
    head = bare.split(".", 1)[0] if bare.startswith(("frame.", "tool.")) else re.match(r"[a-z]*", bare)[0]
    return session + BLOCK_LABELS.get(head, BLOCK_LABELS.get(head[:1], head or bare))


def blocks(names: Sequence[str]) -> list[tuple[str, int, int]]:
    """Contiguous runs of one block: ``(label, start, stop)`` in the order of ``names``.

    >>> blocks(["u1.x", "u1.y", "s1.x", "l0_1", "g1"])
    [('base joints', 0, 2), ('platform joints', 2, 3), ('l0', 3, 4), ('gains', 4, 5)]
    """
    out: list[tuple[str, int, int]] = []
    for k, name in enumerate(names):
        label = block_of(name)
        if out and out[-1][0] == label:
            out[-1] = (label, out[-1][1], k + 1)
        else:
            out.append((label, k, k + 1))
    return out


#: The validation quantities, shown alike in the text and on the page: label (with its
#: unit), summary key, factor from the result's units (mm, rad) to the label's.
VALIDATION_ROWS = (
    ("leg residual RMS (mm)", "leg_rms", 1.0),
    ("leg residual max (mm)", "leg_max", 1.0),
    ("position error RMS (mm)", "position_rms", 1.0),
    ("position error max (mm)", "position_max", 1.0),
    ("orientation error RMS (mrad)", "orientation_rms", 1e3),
    ("orientation error max (mrad)", "orientation_max", 1e3),
)

#: The instrument's own validation errors (``instrument_<name>_rms``): what, unit, factor.
INSTRUMENT_ERRORS = {
    "target": ("target distance", "mm", 1.0),
    "position": ("tool position", "mm", 1.0),
    "orientation": ("tool angle", "mrad", 1e3),
}


def validation_rows(summary: Sequence[str]) -> list[tuple[str, str, float]]:
    """The rows ``(label, key, factor)`` of a validation summary with keys ``summary``: the
    platform pose's, then the instrument's own errors (orientation in mrad).

    >>> validation_rows(["poses", "instrument_target_rms"])[-1]
    ('target distance max (mm)', 'instrument_target_max', 1.0)
    """
    rows = list(VALIDATION_ROWS)
    for key in summary:
        if key.startswith("instrument_") and key.endswith("_rms"):
            name = key.removeprefix("instrument_").removesuffix("_rms")
            what, unit, scale = INSTRUMENT_ERRORS.get(name, (name, "mm", 1.0))
            rows += [(f"{what} RMS ({unit})", key, scale), (f"{what} max ({unit})", key[:-4] + "_max", scale)]
    return rows


def validation_summaries(data: dict[str, Any]) -> dict[str, dict[str, Any] | None]:
    """The summaries (``ValidationResult.summary()`` keys: no units in them) of the calibrated
    and the nominal machine in a validation's dictionary
    (:func:`hexcal.report.validation_report_dict`, :func:`hexcal.report.validation_json`): its
    figures are the keys ending in their unit.

    >>> validation_summaries({"poses": 3, "leg_rms_mm": 0.01, "orientation_max_rad": 2e-5,
    ...                       "instrument": "pose", "nominal": None})
    {'calibrated': {'poses': 3, 'leg_rms': 0.01, 'orientation_max': 2e-05}, 'nominal': None}
    """

    def plain(figures: dict[str, Any]) -> dict[str, Any]:
        return {
            key.removesuffix("_mm").removesuffix("_rad"): value
            for key, value in figures.items()
            if key == "poses" or key.endswith(("_mm", "_rad"))
        }

    nominal = data.get("nominal")
    return {"calibrated": plain(data), "nominal": None if nominal is None else plain(nominal)}


def fmt(value: Any, digits: int = 4, missing: str = "n/a") -> str:
    """A number for a person: ``missing`` (never ``nan``) for None and non-finite values.

    >>> fmt(0.000123456), fmt(float("nan")), fmt(None, missing="-")
    ('0.0001235', 'n/a', '-')
    """
    if value is None or isinstance(value, bool):
        return missing
    try:
        v = float(value)
    except (TypeError, ValueError):
        return str(value)
    return f"{v:.{digits}g}" if math.isfinite(v) else missing


#: What the validate page says under an instrument's own per-pose errors.
OWN_NOTE = "The instrument does not give the platform pose: its own prediction errors, predicted minus read."


def has_poses(result: Mapping[str, Any]) -> bool:
    """Whether a validation has a platform pose error anywhere (NaN or None where not)."""
    return any(isinstance(v, int | float) and v == v for v in result.get("position_error", ()))


def own_rows(results: Mapping[str, Any], first: Mapping[str, Any]) -> tuple[list[str], list[tuple]]:
    """Per-pose columns and rows of the instrument's own errors (a ballbar's bar error, mm)."""
    names = list(first.get("instrument_errors") or {})
    cols = ["pose"] + [f"{geo} {name} (mm)" for geo in results for name in names]
    rows = [
        (pid, *(r["instrument_errors"][name][k] for r in results.values() for name in names))
        for k, pid in enumerate(first["ids"])
    ]
    return cols, rows
