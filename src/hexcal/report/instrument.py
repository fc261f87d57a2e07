"""Reports of the instrument commands (``--setup``): dictionaries and their text.

Kinds (registered in :mod:`hexcal.report.registry`, text and JSON):

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
    "instrument_plan": instrument_plan_text,
    "instrument_study": instrument_study_text,
}
