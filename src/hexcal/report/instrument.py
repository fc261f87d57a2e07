"""Reports of the instrument commands (``--setup``): dictionaries and their text.

Kinds (registered in :mod:`hexcal.report.registry`, text and JSON):

- ``instrument``: what ``hexcal identify --setup`` adds to the identification report: the
  instrument, the frame registration of an ``auto`` frame and its residual, the gauge freedoms
  and the convention that removes them, the combinations not determined beyond the gauges,
  the outliers (one target observation or a whole pose) and the calibrated setup;
- ``instrument_validation``: held-out target positions (or tool positions) predicted from
  the leg readings, against measured;
- ``instrument_plan``: identifiability and predicted accuracy of poses for an instrument;
- ``instrument_study``: Monte Carlo campaigns with a setup.

Standard library only at import; the converters take the library's result objects.
"""

from __future__ import annotations

import math
from typing import Any


def _f(value: Any, digits: int = 4) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    return f"{value:.{digits}f}"


def instrument_dict(
    out: Any, outliers: tuple[str, ...] = (), flagged: tuple[str, ...] = ()
) -> dict[str, Any]:
    """The instrument part of an identification: ``out`` an
    :class:`hexcal.estimation.instrument.InstrumentResult`."""
    setup = out.setup
    reg = out.registration
    stderr = (setup.calibration or {}).get("stderr", {})
    values = dict(zip(setup.names(), setup.vector().tolist(), strict=True))
    return {
        "instrument": "position (targets)" if setup.kind == "targets" else "pose (tool)",
        "targets": list(setup.target_names),
        "registration": None
        if reg is None
        else {"points": reg.points, "rms_mm": reg.rms, "max_mm": reg.max, "frame": reg.frame.tolist()},
        "gauges": list(out.gauges),
        "convention": out.convention if out.gauges else "none (no gauge freedom)",
        "unidentifiable": list(out.unidentifiable),
        "outliers": list(outliers),
        "flagged": list(flagged),
        "setup": {n: {"value": v, "stderr": stderr.get(n)} for n, v in values.items()},
        "fixed": list(setup.fixed),
    }


def instrument_text(data: dict[str, Any], **_options: Any) -> str:
    """The ``[[Instrument]]`` sections of ``hexcal identify --setup``."""
    lines = ["[[Instrument]]", f"    {data['instrument']}"]
    if data["targets"]:
        lines[-1] += f": {len(data['targets'])} target(s) {', '.join(data['targets'])}"
    reg = data["registration"]
    if reg is not None:
        lines.append(
            f"    instrument frame auto: registered from {reg['points']} points, residual RMS "
            f"{_f(reg['rms_mm'], 3)} mm, max {_f(reg['max_mm'], 3)} mm (nominal machine and setup)"
        )
    if data["fixed"]:
        lines.append(f"    held exactly (setup 'fixed'): {', '.join(data['fixed'])}")
    lines.append("[[Gauge freedoms]]")
    if data["gauges"]:
        lines.append(
            f"    {len(data['gauges'])} combinations no data can determine: {', '.join(data['gauges'])}"
        )
        lines.append(f"    removed by the {data['convention']}")
        lines.append("    (rank, standard errors and bounds above are those of the gauge-fixed parameters)")
    else:
        lines.append("    none")
    weak = data["unidentifiable"]
    lines.append(
        "    beyond the gauges: "
        + ("every varied parameter is identified" if not weak else f"not determined: {'; '.join(weak)}")
    )
    lines.append("[[Calibrated setup]]")
    lines.append(f"    {'name':<10}{'value':>16}{'stderr':>12}")
    for name, item in data["setup"].items():
        value, err = item["value"], item["stderr"]
        unit_deg = name.split(".")[-1] in ("a", "b", "c") and not name.startswith("t")
        shown = math.degrees(value) if unit_deg else value
        err_shown = None if err is None else (math.degrees(err) if unit_deg else err)
        suffix = " deg" if unit_deg else " mm"
        lines.append(f"    {name:<10}{_f(shown, 6):>16}{_f(err_shown, 6):>12}{suffix}")
    if data["outliers"]:
        lines.append("[[Outliers left out]]")
        lines.extend(f"    {o}" for o in data["outliers"])
    elif data["flagged"]:
        lines.append("[[Outlier check]]")
        lines.append(f"    flagged (rerun with --robust to leave out): {', '.join(data['flagged'])}")
    else:
        lines.append("[[Outlier check]]")
        lines.append("    no target observation or pose with implausible residuals")
    return "\n".join(lines)


def instrument_validation_dict(results: dict[str, Any], kind: str) -> dict[str, Any]:
    """``results``: label -> :class:`hexcal.instruments.instrument_data.InstrumentValidation`."""
    return {
        "kind": kind,
        "results": {
            label: {"count": r.count, "rms_mm": r.rms, "max_mm": r.max} for label, r in results.items()
        },
    }


def instrument_validation_text(data: dict[str, Any], **_options: Any) -> str:
    what = "target position(s)" if data["kind"] == "targets" else "tool position(s)"
    lines = []
    for label, r in data["results"].items():
        lines.append(
            f"{label}: {r['count']} held-out {what} predicted from the leg readings: "
            f"RMS {_f(r['rms_mm'])} mm, max {_f(r['max_mm'])} mm"
        )
    return "\n".join(lines)


def instrument_plan_text(data: dict[str, Any], **_options: Any) -> str:
    """Identifiability and predicted accuracy of a pose set for an instrument."""
    lines = [
        f"Planning for the instrument of the setup ({data['instrument']}), {data['poses']} pose(s)",
        f"    parameters varied   {data['parameters']} ({data['machine_parameters']} machine + "
        f"{data['parameters'] - data['machine_parameters']} setup)",
        f"    gauge freedoms      {data['gauges']}",
        f"    rank                {data['rank']} (needed: {data['parameters'] - data['gauges']})",
        "    beyond the gauges   "
        + ("all identified" if not data["unidentifiable"] else "; ".join(data["unidentifiable"])),
        "    predicted (Cramér–Rao) σ, gauge-fixed:",
        f"      joint coordinates  median {_f(data['joint_bound_mm'])} mm, "
        f"max {_f(data['joint_bound_max_mm'])} mm",
        f"      l0                 median {_f(data['l0_bound_mm'])} mm",
    ]
    if data.get("full_pose_joint_bound_mm") is not None:
        lines.append(
            f"    same poses with a full-pose instrument: joint σ median "
            f"{_f(data['full_pose_joint_bound_mm'])} mm (ratio "
            f"{_f(data['joint_bound_mm'] / data['full_pose_joint_bound_mm'], 2)})"
        )
    if data.get("selection"):
        s = data["selection"]
        lines.append(
            f"    selected {s['n']} of {s['candidates']} candidates ({s['criterion']}-optimal for this "
            f"instrument); {s['n']} random candidates give joint σ median {_f(s['random_joint_bound_mm'])} mm"
        )
    return "\n".join(lines)


def instrument_study_text(data: dict[str, Any], **_options: Any) -> str:
    """Monte Carlo campaigns with a setup: identification error against its bound."""
    lines = [
        f"Campaigns with the setup ({data['instrument']}): {data['trials']} trial(s) per cell, "
        f"seed {data['seed']}, missing rate {data['missing_rate']:g}, noise {data['noise']}",
        "    machine parameters (gauge-fixed): RMS error and Cramér–Rao σ (RMS over parameters);",
        "    held-out targets: RMS distance of positions predicted from leg readings",
        f"    {'strategy':<10}{'poses':>6}{'ok':>5}{'error mm':>11}{'bound mm':>11}"
        f"{'ratio':>7}{'held-out mm':>13}{'s/fit':>7}",
    ]
    for c in data["cells"]:
        lines.append(
            f"    {c['strategy']:<10}{c['poses']:>6}{c['ok']:>5}{_f(c['error_mm']):>11}"
            f"{_f(c['bound_mm']):>11}{_f(c['ratio'], 2):>7}{_f(c['heldout_mm']):>13}{_f(c['seconds'], 3):>7}"
        )
    return "\n".join(lines)


#: Text renderers of the instrument kinds (JSON is generic).
INSTRUMENT_RENDERERS = {
    "instrument": instrument_text,
    "instrument_validation": instrument_validation_text,
    "instrument_plan": instrument_plan_text,
    "instrument_study": instrument_study_text,
}
