"""Summaries and text reports of hexcal's results."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.simulation import PaperExperiment

#: The seed paper's Table I (mean absolute parameter error, mm) and its validation claims.
PAPER_TABLE1 = {"before": 2.6652, "interior": 0.7236, "boundary": 0.3752}
PAPER_VALIDATION = {
    "before": {"position": "about 15 mm", "orientation": "about 0.05 rad"},
    "after": {"position": "below 0.03 mm", "orientation": "below 3e-6 rad"},
}


def _pose_error_stats(errors: dict[str, NDArray[np.float64]]) -> dict[str, float]:
    """Per-trial max averaged over trials, and RMS over all poses of all trials."""
    out: dict[str, float] = {}
    for key in ("position", "orientation"):
        e = errors[key]
        out[f"{key}_max"] = float(np.nanmean(np.nanmax(e, axis=1)))
        out[f"{key}_rms"] = float(np.sqrt(np.nanmean(e**2)))
        out[f"{key}_max_worst"] = float(np.nanmax(e))
    return out


def paper_summary(experiment: PaperExperiment, **meta: Any) -> dict[str, Any]:
    """The Table I reproduction as a JSON-ready mapping (see ``hexcal paper``)."""
    errors = experiment.mean_abs_errors()
    summary: dict[str, Any] = dict(meta)
    summary.update(
        {
            "trials": experiment.trials,
            "method": experiment.method,
            "before": float(np.nanmean(errors["before"])),
            "interior": float(np.nanmean(errors["interior"])),
            "boundary": float(np.nanmean(errors["boundary"])),
            "std": {k: float(np.nanstd(v)) for k, v in errors.items()},
            "failures": experiment.failures,
            "paper": dict(PAPER_TABLE1),
            "validation": {
                "before": _pose_error_stats(experiment.validation_before),
                "after": _pose_error_stats(experiment.validation_after),
                "paper": PAPER_VALIDATION,
                "statistics": "max: per-trial maximum over the validation poses, averaged over "
                "trials; rms: over all validation poses of all trials; max_worst: over all",
            },
        }
    )
    return summary


def format_paper_summary(summary: dict[str, Any]) -> str:
    """Text table of :func:`paper_summary` beside the paper's figures."""
    t = summary["trials"]
    lines = [
        f"Table I: mean absolute error of the 42 parameters (mm), {t} trials, method {summary['method']!r}",
        f"  {'row':<44}{'hexcal mean':>12}{'std':>9}{'paper':>9}",
    ]
    labels = {
        "before": "before calibration",
        "interior": "15 random poses inside the workspace",
        "boundary": "15 of the 64 corners",
    }
    for key, label in labels.items():
        lines.append(
            f"  {label:<44}{summary[key]:>12.4f}{summary['std'][key]:>9.4f}{PAPER_TABLE1[key]:>9.4f}"
        )
    fails = summary["failures"]
    if any(fails.values()):
        lines.append(f"  identification failed in {fails} trials (left out of the means)")
    val = summary["validation"]
    lines += [
        "",
        "Validation on 10 further corners (boundary calibration):",
        f"  {'':<12}{'pos max mm':>12}{'pos rms mm':>12}{'ang max rad':>13}{'ang rms rad':>13}   paper",
    ]
    for key in ("before", "after"):
        v = val[key]
        paper = PAPER_VALIDATION[key]
        lines.append(
            f"  {key:<12}{v['position_max']:>12.4g}{v['position_rms']:>12.4g}"
            f"{v['orientation_max']:>13.3g}{v['orientation_rms']:>13.3g}"
            f"   {paper['position']}, {paper['orientation']}"
        )
    lines.append("  (max: per-trial maximum averaged over trials; rms: over all poses)")
    return "\n".join(lines)
