"""The ISO tests of ``hexcal validate --iso230-4`` / ``--iso9283`` as a plain dictionary and
as the text the command prints (deviations in µm as ballbar software prints them, ISO 9283
positions in mm and angles in mrad; the JSON keeps mm and rad). Standard library only.

>>> print(iso_text({"iso230_4": None, "iso9283": None, "iso9283_note": "no repeated visits"}))
ISO 9283: no repeated visits
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from hexcal.core.text import printable

#: The name of each geometry's column, by its role in ``validate``.
ROLE_LABELS = {"nominal": "before (nominal)", "calibrated": "after (calibrated)"}

#: The rows of the circular test of one run: label, key, scale to µm.
RUN_ROWS = (
    ("circular deviation G", "circular_deviation_mm"),
    ("radial deviation F max", "radial_deviation_max_mm"),
    ("radial deviation F min", "radial_deviation_min_mm"),
    ("radius error", "radius_error_mm"),
)

RUN_NAMES = {"ccw": "CCW", "cw": "CW", "both": "both runs"}


def iso_dict(
    circles: Mapping[str, Any] | None,
    poses: Mapping[str, Any] | None,
    *,
    note: str | None = None,
    tolerance: float | None = None,
    instrument: str = "",
    names: Sequence[str] = (),
    after: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The ISO figures of geometries by role (``nominal``, ``calibrated``), JSON-ready: each
    ``CircularTest`` and ``PoseStatistics`` as its ``to_dict()``; ``labels`` name the roles of
    the figures (or of ``names`` when there are none); ``after_setup`` how the after column
    took the instrument's setup (:func:`hexcal.calibration.iso_validation.after_setup`)."""
    return {
        "after_setup": None if after is None else dict(after),
        "instrument": instrument,
        "labels": {name: ROLE_LABELS.get(name, name) for name in (circles or poses or names)},
        "iso230_4": None if circles is None else {k: v.to_dict() for k, v in circles.items()},
        "iso9283": None if poses is None else {k: v.to_dict() for k, v in poses.items()},
        "iso9283_note": note,
        "visit_tolerance_mm": tolerance,
    }


def _fixed(value: float, digits: int) -> str:
    """A coordinate with ``digits`` decimals, no negative zero.

    >>> _fixed(-1e-16, 3), _fixed(799.99999, 3)
    ('0.000', '800.000')
    """
    text = f"{value:.{digits}f}"
    return text[1:] if text.startswith("-") and float(text) == 0 else text


def _um(value: Any) -> str:
    if value is None or not isinstance(value, int | float) or not math.isfinite(value):
        return "-"
    return f"{1e3 * value:.4g}"


def circle_rows(tests: Mapping[str, Mapping[str, Any]]) -> list[tuple[str, list[Any]]]:
    """The rows of the circular test's table: label (µm), one value (mm) per geometry."""
    first = next(iter(tests.values()))
    rows: list[tuple[str, list[Any]]] = []
    for run in ("ccw", "cw", "both"):
        if run not in first["runs"]:
            continue
        for label, key in RUN_ROWS:
            if run == "both" and key == "circular_deviation_mm":
                label = "circular deviation G(b), bidirectional"
            where = "" if label.endswith("bidirectional") else f", {RUN_NAMES[run]}"
            rows.append((f"{label}{where} (µm)", [t["runs"][run][key] for t in tests.values()]))
        for axis, k in (("u", 0), ("v", 1)):
            rows.append(
                (
                    f"centre offset {axis}, {RUN_NAMES[run]} (µm)",
                    [t["runs"][run]["centre_offset_mm"][k] for t in tests.values()],
                )
            )
    if first.get("circular_hysteresis_mm") is not None:
        rows.append(("circular hysteresis H (µm)", [t["circular_hysteresis_mm"] for t in tests.values()]))
    return rows


def after_text(after: Mapping[str, Any] | None) -> str:
    """How the after column took the instrument's setup, in words (empty without a record).

    >>> print(after_text({"setup": "as given", "calibrated_setup": False, "frames": "set-up"}))
    after calibration: the setup as given (its quantities fixed; the calibration's frames are the set-up's)
    """
    if not after:
        return ""
    if after["setup"] == "as given":
        why = (
            "its quantities fixed, in the calibrated machine's frames"
            if after.get("calibrated_setup")
            else "its quantities fixed; the calibration's frames are the set-up's"
        )
        what = "the calibrated setup" if after.get("calibrated_setup") else "the setup"
        return f"after calibration: {what} as given ({why})"
    names = ", ".join(printable(str(n)) for n in after.get("quantities", []))
    text = (
        f"after calibration: {names} re-registered on this session for the calibrated machine by "
        f"{after.get('folds')}-fold cross-validation (seed {after.get('seed')}), as validate does"
    )
    if after.get("frames") == "convention" and not after.get("calibrated_setup"):
        text += " (the setup as set up is not in the frames the calibration's gauge convention chose)"
    held = after.get("held") or []
    if held:
        names = ", ".join(printable(str(n)) for n in held)
        text += f"; held as given, these data cannot determine them: {names}"
    return text + "; what the re-registration absorbs (a pivot's centre offset, a frame) is not shown after"


def _circle_line(test: Mapping[str, Any], label: str) -> str:
    centre = ", ".join(_fixed(v, 3) for v in test["nominal_centre_mm"])
    normal = ", ".join(_fixed(v, 4) for v in test["plane_axes"][2])
    return (
        f"    {label}commanded circle: radius {test['nominal_radius_mm']:.6g} mm about ({centre}) mm, "
        f"plane normal ({normal})"
    )


def _circle_lines(tests: Mapping[str, Mapping[str, Any]], labels: Mapping[str, str]) -> list[str]:
    first = next(iter(tests.values()))
    counts = " + ".join(f"{r['points']} {RUN_NAMES[n]}" for n, r in first["runs"].items() if n != "both")
    lines = [f"ISO 230-4 circular test: {counts} points"]
    many = len(tests) > 1
    lines += [_circle_line(t, f"{printable(labels.get(n, n))}: " if many else "") for n, t in tests.items()]
    lines.append(f"    {'':<46}" + "".join(f"{printable(labels.get(n, n)):>20}" for n in tests))
    for label, values in circle_rows(tests):
        lines.append(f"    {label:<46}" + "".join(f"{_um(v):>20}" for v in values))
    return lines


def pose_rows(stats: Mapping[str, Any]) -> list[list[Any]]:
    """Rows of one geometry's ISO 9283 table (poses visited at least twice): id, visits,
    AP_p, AP_x, AP_y, AP_z (mm), AP_a, AP_b, AP_c (mrad), RP_l (mm), RP_a, RP_b, RP_c (mrad)."""
    rows = []
    for pose in stats["poses"]:
        if pose["visits"] < 2:
            continue
        rows.append(
            [pose["id"], pose["visits"], pose["AP_p_mm"], *pose["AP_xyz_mm"]]
            + [1e3 * v for v in pose["AP_abc_rad"]]
            + [pose["RP_l_mm"]]
            + [1e3 * v for v in pose["RP_abc_rad"]]
        )
    return rows


POSE_COLUMNS = (
    "pose", "visits", "AP_p (mm)", "AP_x (mm)", "AP_y (mm)", "AP_z (mm)", "AP_a (mrad)", "AP_b (mrad)",
    "AP_c (mrad)", "RP_l (mm)", "RP_a (±mrad)", "RP_b (±mrad)", "RP_c (±mrad)",
)  # fmt: skip


def _pose_lines(data: Mapping[str, Any]) -> list[str]:
    stats, labels = data["iso9283"], data.get("labels", {})
    first = next(iter(stats.values()))
    tol = data.get("visit_tolerance_mm")
    once = sum(1 for p in first["poses"] if p["visits"] < 2)
    lines = [
        f"ISO 9283 pose accuracy (AP) and repeatability (RP): {first['repeated']} commanded pose(s) "
        "visited more than once"
        + (f" (visits: leg readings within {tol:g} mm)" if tol is not None else "")
        + (f"; {once} visited once left out" if once else "")
    ]
    for name, table in stats.items():
        lines.append(f"  {printable(labels.get(name, name))}")
        lines.append("    " + "".join(f"{c:>13}" for c in POSE_COLUMNS))
        for row in pose_rows(table):
            cells = [f"{printable(row[0])[:12]:>13}", f"{row[1]:>13d}"]
            cells += ["-".rjust(13) if v is None or not math.isfinite(v) else f"{v:>13.4g}" for v in row[2:]]
            lines.append("    " + "".join(cells))
    return lines


def iso_text(data: Mapping[str, Any]) -> str:
    """The ISO tests as the command prints them (:func:`iso_dict`)."""
    lines: list[str] = []
    labels = data.get("labels", {})
    if data.get("iso230_4"):
        lines += _circle_lines(data["iso230_4"], labels)
    if data.get("iso9283"):
        lines += _pose_lines(data)
    elif data.get("iso9283_note"):
        lines.append(f"ISO 9283: {printable(data['iso9283_note'])}")
    after = after_text(data.get("after_setup"))
    if after and (data.get("iso230_4") or data.get("iso9283")):
        lines.append(f"    {after}")
    return "\n".join(lines)
