"""The data of the HTML reports: results plus what the figures need, then the page.

:func:`identification_report`, :func:`validation_report`, :func:`paper_report` and
:func:`study_report` gather, from a result and its
data, the ``to_dict()`` values, the per-pose residuals before and after calibration and the
figures (SVG), into one JSON-ready mapping; :func:`render_html` turns such a mapping into
the self-contained page (:mod:`hexcal.report.html_pages`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from hexcal.core.linalg import RANK_RTOL
from hexcal.estimation.registry import ESTIMATORS
from hexcal.report import figures_report as fig
from hexcal.report.figures import (
    conditions,
    parameter_errors_figure,
    study_figure,
    validation_errors_figure,
)
from hexcal.report.html_pages import tables_page
from hexcal.report.registry import render
from hexcal.report.tables import STUDY_COLUMNS


def identification_report(
    result: Any, inputs: Mapping[str, Any] | None = None, title: str = ""
) -> dict[str, Any]:
    """Everything the identify page shows, from an identification (any instrument, any number
    of sessions); ``inputs`` names the files, options and versions that produced the result."""
    summary = result.to_dict()
    estimator = ESTIMATORS.get(summary["method"])
    if estimator is not None:
        summary["method_label"] = f"{estimator.name}: {estimator.label}"
    figures = {"parameter_changes": fig.svg(fig.parameter_changes(summary))}
    before, after = summary.get("pose_rms_before"), summary.get("pose_rms_after")
    if before is not None and after is not None:
        marked = {"outlier (left out)": summary["outliers"], "flagged": summary["flagged"]}
        figures["pose_residuals"] = fig.svg(
            fig.pose_residuals(summary["ids"], np.asarray(before), np.asarray(after), marked)
        )
    figures["correlation"] = fig.svg(fig.correlation(summary["names"], summary["correlation"]))
    figures["singular_values"] = fig.svg(fig.singular_values(summary["singular_values"], RANK_RTOL))
    if result.poses is not None:
        figures["workspace"] = fig.svg(fig.workspace_poses(result.poses, result.start.workspace))
    name = result.start.name or "geometry"
    sessions = summary["sessions"]
    what = sessions[0]["description"] if len(sessions) == 1 else f"{len(sessions)} sessions"
    return {
        "kind": "identification",
        "title": title or f"Calibration of {name}",
        "subtitle": (
            f"{summary['poses']} poses ({what}), {len(summary['names'])} parameters, estimator "
            f"{summary['method']}"
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


def paper_report(
    summary: Mapping[str, Any],
    figure_data: Mapping[str, Any],
    inputs: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The page of ``hexcal paper --html``: Table I, the validation table, Figs. 10 and 11.

    ``summary`` is ``PaperExperiment.to_dict(seed=..., true_machine=..., noise=...)`` and
    ``figure_data`` :func:`hexcal.report.paper_figure_data` of the same experiment.
    """
    note = paper_note(summary)
    paper = summary.get("paper", {})
    bound = summary.get("bound", {})
    rows = [
        (
            label,
            summary[key],
            summary.get("std", {}).get(key),
            bound.get(key, {}).get("bound"),
            bound.get(key, {}).get("efficiency"),
            paper.get(key, "-"),
            summary.get("failures", {}).get(key, 0),
        )
        for key, label in summary.get("rows", {}).items()
    ]
    validation = summary.get("validation", {})
    val_rows = [
        (
            when,
            *(
                validation[when][k]
                for k in ("position_max", "position_rms", "orientation_max", "orientation_rms")
            ),
        )
        for when in ("before", "after")
        if when in validation
    ]
    data = {**figure_data, "note": note}
    return {
        "kind": "paper",
        "title": "Seed paper experiment: Table I by Monte Carlo",
        "subtitle": note,
        "tables": {
            "Table I: mean absolute error of the 42 parameters (mm)": {
                "columns": [
                    "row",
                    "hexcal mean",
                    "std",
                    "Cramér–Rao bound",
                    "efficiency",
                    "paper",
                    "failed trials",
                ],
                "rows": rows,
            },
            "Validation on further corners (boundary calibration)": {
                "columns": [
                    "",
                    "position max (mm)",
                    "position RMS (mm)",
                    "orientation max (rad)",
                    "orientation RMS (rad)",
                ],
                "rows": val_rows,
            },
        },
        "text": render("paper", dict(summary)),
        "figures": {
            "fig10_parameter_errors": fig.svg(parameter_errors_figure(data)),
            "fig11_validation_errors": fig.svg(validation_errors_figure(data)),
        },
        "captions": {
            "fig10_parameter_errors": "Paper Fig. 10: mean absolute error of each parameter before and "
            "after calibration (log scale).",
            "fig11_validation_errors": "Paper Fig. 11: pose errors at the validation corners, first trial.",
        },
        "inputs": dict(inputs or {}),
    }


def paper_note(summary: Mapping[str, Any]) -> str:
    """The conditions line of the paper figures: true machine, noise, trials, seed."""
    true = summary.get("true_machine")
    amplitude = "nominal + U(±5 mm)" if true == "random" else (f"true machine {true}" if true else None)
    return conditions(summary.get("trials"), summary.get("noise"), amplitude, summary.get("seed"))


def study_note(study: Mapping[str, Any]) -> str:
    """The conditions line of the study figure (same form as :func:`paper_note`)."""
    return paper_note(study)


#: Column headers (with units) of the study table, by ``StudyCell.row()`` key.
STUDY_HEADERS = {
    "error_mean": "parameter error mean (mm)",
    "error_std": "std (mm)",
    "bound": "Cramér–Rao bound (mm)",
    "efficiency": "efficiency (error / bound)",
    "position_rms": "validation position RMS (mm)",
    "orientation_rms": "validation orientation RMS (rad)",
    "failures": "failed trials",
}


def study_report(study: Mapping[str, Any], inputs: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The page of ``hexcal simulate --html``: the study table and the study figure.

    ``study`` is ``study.json``: ``trials``, ``seed``, ``noise`` (text), ``true_machine``
    (optional) and ``cells`` (the ``StudyCell.row()`` dictionaries).
    """
    rows = study["cells"]
    note = study_note(study)
    keys = ["strategy", "noise", "method", *STUDY_COLUMNS, "failures"]
    table_rows = [[r.get(c) for c in keys] for r in rows]
    columns = [STUDY_HEADERS.get(k, k) for k in keys]
    return {
        "kind": "study",
        "title": "Monte Carlo study of calibration campaigns",
        "subtitle": note,
        "tables": {
            "Study: parameter error (mm) and pose errors per campaign": {
                "columns": columns,
                "rows": table_rows,
            },
        },
        "text": render("study", list(rows)),
        "figures": {"study": fig.svg(study_figure(rows, note))},
        "figures_first": True,
        "captions": {
            "study": "Mean absolute parameter error against the number of poses; colour: strategy, "
            "line style: method, marker: noise level; dotted: Cramér–Rao bounds.",
        },
        "inputs": dict(inputs or {}),
    }


def check_html_target(html: str, inputs: Iterable[Any] = (), outputs: Iterable[Any] = ()) -> None:
    """Refuse, before any work, an ``--html`` file that is also an input or another output.

    Raises
    ------
    ValueError
        When ``html`` names the same file as one of ``inputs`` or ``outputs`` (None skipped).
    """
    target = Path(html).resolve()
    for role, paths in (("an input", inputs), ("another output", outputs)):
        for path in paths:
            if path is not None and Path(path).resolve() == target:
                raise ValueError(f"--html {html}: is also {role} ({path})")


POSES_CAPTION = "The {} poses: x–y coloured by z, a–b coloured by c; dashed: the workspace box."


def observability_report(
    data: Mapping[str, Any], poses: Any, box: Any | None = None, inputs: Mapping[str, Any] | None = None
) -> dict[str, Any]:
    """The page of ``hexcal observability --html``: indices, predicted accuracy, the
    predicted standard deviation of every parameter, singular values, the poses.

    ``data`` is ``PoseAnalysis.to_dict()``; ``poses`` the analysed poses (n, 6).
    """
    indices = {k: data.get(k) for k in ("n_poses", "n_parameters", "rank", "condition_number")}
    indices |= {k: data[k] for k in ("O1", "O2", "O3", "O4", "O5") if k in data}
    predicted = data.get("predicted_mean_abs_error_mm", {})
    tests = data.get("test_poses") or {}
    accuracy = [("mean absolute parameter error (mm)", predicted.get("estimator"), predicted.get("bound"))]
    for key, label in (
        ("position_rms_mean_mm", "test pose position RMS, mean (mm)"),
        ("position_rms_max_mm", "test pose position RMS, max (mm)"),
        ("orientation_rms_mean_rad", "test pose orientation RMS, mean (rad)"),
        ("orientation_rms_max_rad", "test pose orientation RMS, max (rad)"),
    ):
        if key in tests:
            accuracy.append((label, tests[key], None))
    params = [
        (name, v.get("std_estimator"), v.get("std_bound")) for name, v in data.get("parameters", {}).items()
    ]
    figures = {"singular_values": fig.svg(fig.singular_values(data["singular_values"], RANK_RTOL))}
    figures["workspace"] = fig.svg(fig.workspace_poses(poses, box, "Analysed poses in the workspace"))
    return {
        "kind": "tables",
        "title": "Observability of a measurement pose set",
        "subtitle": f"{data.get('n_poses')} poses, {data.get('n_parameters')} parameters, "
        f"residual {data.get('method')}, scaling {data.get('scaling')}",
        "tables": {
            "Observability indices": {"columns": ["index", "value"], "rows": list(indices.items())},
            "Predicted accuracy": {
                "columns": ["quantity", "estimator", "Cramér–Rao bound"],
                "rows": accuracy,
            },
            "Predicted standard deviation per parameter": {
                "columns": ["parameter", "estimator (mm)", "Cramér–Rao bound (mm)"],
                "rows": params,
            },
        },
        "figures": figures,
        "captions": {
            "singular_values": "Singular values of the scaled identification Jacobian of these poses.",
            "workspace": POSES_CAPTION.format("analysed"),
        },
        "inputs": dict(inputs or {}),
    }


def selection_report(
    data: Mapping[str, Any], poses: Any, box: Any | None = None, inputs: Mapping[str, Any] | None = None
) -> dict[str, Any]:
    """The page of ``hexcal select --html``: the selection, the predicted errors of the
    strategies compared, the selected poses (table and workspace figure).

    ``data`` is ``Selection.to_dict()``; ``poses`` the selected poses (n, 6), in the order
    of ``data["ids"]``.
    """
    keys = ("strategy", "criterion", "n", "candidates", "value", "greedy_value", "swaps", "seed")
    summary = [(k, data[k]) for k in keys if k in data]
    predicted = [
        (name, v.get("estimator"), v.get("bound"))
        for name, v in data.get("predicted_mean_abs_error_mm", {}).items()
    ]
    p = np.asarray(poses, dtype=float).reshape(-1, 6)
    angles = np.rad2deg(p[:, 3:])
    rows = [(pid, *p[k, :3].tolist(), *angles[k].tolist()) for k, pid in enumerate(data.get("ids", []))]
    return {
        "kind": "tables",
        "title": f"Selected measurement poses ({data.get('n')}, criterion {data.get('criterion')})",
        "subtitle": f"strategy {data.get('strategy')}, candidates {data.get('candidates')}, "
        f"seed {data.get('seed')}",
        "tables": {
            "Selection": {"columns": ["", "value"], "rows": summary},
            "Predicted mean absolute parameter error (mm)": {
                "columns": ["poses", "estimator", "Cramér–Rao bound"],
                "rows": predicted,
            },
            "Selected poses": {
                "columns": ["id", "x (mm)", "y (mm)", "z (mm)", "a (deg)", "b (deg)", "c (deg)"],
                "rows": rows,
            },
        },
        "figures": {"workspace": fig.svg(fig.workspace_poses(p, box, "Selected poses in the workspace"))},
        "captions": {"workspace": POSES_CAPTION.format("selected")},
        "inputs": dict(inputs or {}),
    }


def render_html(report: Mapping[str, Any]) -> str:
    """The HTML page of a report mapping (its ``kind`` picks the page; ``tables``: a page
    of tables and figures, :func:`hexcal.report.html_pages.tables_page`)."""
    if report.get("kind") == "tables":
        return tables_page(report)
    return render(report.get("kind", "paper"), report, "html")
