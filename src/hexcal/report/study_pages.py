"""The pages of ``hexcal paper --html`` and ``hexcal simulate --html`` (Monte Carlo studies):
their tables and figures gathered from the studies' dictionaries, and the conditions line
written on the page and on every figure of a study.

Each ``*_report`` returns a JSON-ready mapping for :func:`hexcal.report.html.tables_page`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from hexcal.report import figures as fig
from hexcal.report.figures.render import trials_phrase
from hexcal.report.registry import render
from hexcal.report.tables import STUDY_COLUMNS


def paper_note(summary: Mapping[str, Any]) -> str:
    """The conditions line of the paper figures: true machine, noise, trials, seed."""
    true = summary.get("true_machine")
    amplitude = "nominal + U(±5 mm)" if true == "random" else (f"true machine {true}" if true else None)
    return fig.conditions(summary.get("trials"), summary.get("noise"), amplitude, summary.get("seed"))


def study_note(study: Mapping[str, Any]) -> str:
    """The conditions line of the study figure (same form as :func:`paper_note`)."""
    return paper_note(study)


def conditions_table(summary: Mapping[str, Any]) -> dict[str, Any]:
    """The conditions of a study as labelled rows: the machines, the instrument, the noise (as
    given and as standard deviations, one row per group), trials, seed."""
    noise = summary.get("noise")
    sigmas = (
        summary.get("noise_sigmas") or (noise.get("sigmas") if isinstance(noise, Mapping) else None) or {}
    )
    if isinstance(noise, Mapping):
        word = "±" if noise.get("distribution", "uniform") == "uniform" else "σ "
        given = {
            g: f"{noise.get('distribution', '')} {word}{noise[g]:g}"
            for g in ("leg", "position", "orientation")
        }
    else:
        given = {}
    true = summary.get("true_machine")
    rows: list[tuple[str, Any]] = [
        ("nominal machine", summary.get("nominal") or (summary.get("nominal_geometry") or {}).get("name")),
        ("true machine", "random: nominal + U(±5 mm) per trial" if true == "random" else true),
        ("measured by", summary.get("instrument")),
    ]
    if isinstance(noise, str):
        rows.append(("noise (as given)", noise))
    for group, unit in (("leg", "mm"), ("position", "mm"), ("orientation", "rad")):
        if group in sigmas:
            shown = f"{given[group]} {unit}, " if group in given else ""
            rows.append((f"noise: {group}", f"{shown}σ {sigmas[group]:.4g} {unit}"))
    rows += [("trials", summary.get("trials")), ("seed", summary.get("seed"))]
    return {
        "columns": ["", "value"],
        "rows": [(k, str(v)) for k, v in rows if v is not None],
        "sortable": False,
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
    trials = int(summary.get("trials") or figure_data.get("trials") or 1)
    return {
        "kind": "paper",
        "title": "Seed paper experiment: Table I by Monte Carlo",
        "subtitle": note,
        "tables": {
            "Conditions": conditions_table(summary),
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
                "note": "In rad, as the paper's table (Fig. 11 draws the first trial in mrad); max: the "
                "per-trial maximum averaged over the trials.",
            },
        },
        "text": render("paper", dict(summary)),
        "figures": {
            "fig10_parameter_errors": fig.svg(fig.parameter_errors_figure(data)),
            "fig11_validation_errors": fig.svg(fig.validation_errors_figure(data)),
        },
        "captions": {
            "fig10_parameter_errors": "Paper Fig. 10: mean absolute error of each parameter before and "
            f"after calibration, over {trials_phrase(trials)} (log scale).",
            "fig11_validation_errors": "Paper Fig. 11: pose errors at the validation corners of the "
            + ("single trial." if trials == 1 else f"first of the {trials} trials."),
        },
        "inputs": dict(inputs or {}),
    }


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
    one_count = len({r["poses"] for r in rows}) == 1
    return {
        "kind": "study",
        "title": "Monte Carlo study of calibration campaigns",
        "subtitle": note,
        "tables": {
            "Conditions": conditions_table(study),
            "Study: parameter error (mm) and pose errors per campaign": {
                "columns": columns,
                "rows": table_rows,
            },
        },
        "text": render("study", list(rows)),
        "figures": {"study": fig.svg(fig.study_figure(rows, note))},
        "figures_first": True,
        "captions": {
            "study": (
                "Mean absolute parameter error of each campaign (± its standard deviation over the "
                "trials) and its Cramér–Rao bound (bar)."
                if one_count
                else "Mean absolute parameter error against the number of poses; colour: strategy, "
                "line style: method, marker: noise level; dotted: Cramér–Rao bounds."
            ),
        },
        "inputs": dict(inputs or {}),
    }
