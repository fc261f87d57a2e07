"""The data of the HTML reports: results plus what the figures need, then the page.

:func:`identification_report` and :func:`validation_report` gather, from a result and its
data, the ``to_dict()`` values, the per-pose residuals before and after calibration and the
figures (SVG), into one JSON-ready mapping; :func:`render_html` turns such a mapping into
the self-contained page (:mod:`hexcal.report.html_pages`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from hexcal.core.linalg import RANK_RTOL
from hexcal.estimation.problem import identification_residuals
from hexcal.estimation.registry import ESTIMATORS
from hexcal.report import figures_report as fig
from hexcal.report.registry import render


def _pose_rms(geometry: Any, data: Any) -> np.ndarray:
    residuals = identification_residuals(geometry, data, "length")
    return np.sqrt(np.mean(residuals**2, axis=1))


def identification_report(
    result: Any, data: Any, inputs: Mapping[str, Any] | None = None, title: str = ""
) -> dict[str, Any]:
    """Everything the identify page shows, from an identification and all its measurements.

    ``data`` are all the measurements (outliers included: they are marked); ``inputs``
    names the files, options and versions that produced the result.
    """
    summary = result.to_dict()
    estimator = ESTIMATORS.get(summary["method"])
    if estimator is not None:
        summary["method_label"] = f"{estimator.name}: {estimator.label}"
    figures = {"parameter_changes": fig.svg(fig.parameter_changes(summary))}
    if getattr(data, "poses", None) is not None:
        before, after = _pose_rms(result.start, data), _pose_rms(result.geometry, data)
        marked = {"outlier (left out)": summary["outliers"], "flagged": summary["flagged"]}
        figures["pose_residuals"] = fig.svg(fig.pose_residuals(list(data.ids), before, after, marked))
        summary["pose_rms_before"] = dict(zip(data.ids, before.tolist(), strict=True))
        summary["pose_rms_after"] = dict(zip(data.ids, after.tolist(), strict=True))
    figures["correlation"] = fig.svg(fig.correlation(summary["names"], summary["correlation"]))
    figures["singular_values"] = fig.svg(fig.singular_values(summary["singular_values"], RANK_RTOL))
    if getattr(data, "poses", None) is not None:
        figures["workspace"] = fig.svg(fig.workspace_poses(data.poses, result.start.workspace))
    name = result.start.name or "geometry"
    return {
        "kind": "identification",
        "title": title or f"Calibration of {name}",
        "subtitle": (
            f"{summary['poses']} poses, {len(summary['names'])} parameters, estimator {summary['method']}"
        ),
        "result": summary,
        "figures": figures,
        "inputs": dict(inputs or {}),
    }


def validation_report(
    results: Mapping[str, Any], inputs: Mapping[str, Any] | None = None, title: str = ""
) -> dict[str, Any]:
    """Everything the validate page shows: summaries and per-pose errors by geometry name."""
    dicts = {name: r.to_dict() for name, r in results.items()}
    first = next(iter(dicts.values()))
    figures = {
        "pose_errors": fig.svg(fig.validation_errors(first["ids"], dicts)),
        "distributions": fig.svg(fig.validation_distributions(dicts)),
    }
    return {
        "kind": "validation",
        "title": title or "Validation on held-out measurements",
        "subtitle": f"{len(first['ids'])} held-out poses",
        "results": dicts,
        "figures": figures,
        "inputs": dict(inputs or {}),
    }


def render_html(report: Mapping[str, Any]) -> str:
    """The HTML page of a report mapping (its ``kind`` picks the page)."""
    return render(report.get("kind", "paper"), report, "html")
