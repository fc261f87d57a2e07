"""The pages of the campaign planning commands, ``hexcal observability --html`` and
``hexcal select --html``: what a pose set tells about the parameters before anything is
measured, gathered from the analyses' ``to_dict()`` and drawn with the poses.

Each ``*_report`` returns a JSON-ready mapping for :func:`hexcal.report.html.tables_page`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from hexcal.core.linalg import RANK_RTOL
from hexcal.design import describe_value
from hexcal.report import figures as fig
from hexcal.report.units import UNIT_WORDS, fmt, parameter_unit

POSES_CAPTION = (
    "The {} poses: positions x–y coloured by z (left), angles a–b coloured by c (right); poses at one "
    "place of a projection are drawn as rings, one per pose, their count beside. Dashed: the workspace box."
)

#: The observability indices in words.
INDEX_LABELS = {
    "n_poses": "poses",
    "n_parameters": "parameters",
    "rank": "rank of the identification Jacobian",
    "condition_number": "condition number (σmax/σmin)",
    "O1": "O1: geometric mean of the singular values (D-optimality)",
    "O2": "O2: σmin/σmax, the inverse condition number",
    "O3": "O3: σmin (E-optimality)",
    "O4": "O4: σmin²/σmax, the noise amplification index",
    "O5": "O5: 1/Σ(1/σi) (A-optimality)",
}

#: What each selection criterion's value is, in words and units (F: the Fisher information
#: of the selected poses, for lengths in mm).
CRITERION_WORDS = {
    "A": "A-optimal: the smallest trace(F⁻¹), the sum of the parameters' Cramér–Rao variances, in mm²",
    "D": "D-optimal: the largest det(F)^(1/n), the geometric mean of the information's eigenvalues, in 1/mm²",
    "E": "E-optimal: the largest λmin(F), the information of the worst-determined combination, in 1/mm²",
    "O4": "O4-optimal: the largest λmin/√λmax of F, the noise amplification index, in 1/mm",
}


def noise_table(noise: Mapping[str, Any] | None) -> dict[str, Any]:
    """The noise a prediction assumes, one row per group: as given (``--noise``: half-widths
    of a uniform distribution, or σ of a normal one) and as a standard deviation."""
    if not noise:
        return {"columns": ["group", "value"], "rows": [("noise", "not recorded")]}
    dist = noise.get("distribution", "uniform")
    word = "half-width ±" if dist == "uniform" else "σ"
    sigmas = noise.get("sigmas") or {}
    if not isinstance(sigmas, Mapping):
        sigmas = dict(zip(("leg", "position", "orientation"), sigmas, strict=False))
    rows = [
        (group, f"{word}{fmt(noise.get(group))}", sigmas.get(group), unit)
        for group, unit in (("leg", "mm"), ("position", "mm"), ("orientation", "rad"))
    ]
    return {
        "columns": ["group", f"as given ({dist})", "standard deviation σ", "unit"],
        "rows": rows,
        "sortable": False,
        "note": "The noise of the measurements the prediction assumes (--noise, --noise-dist).",
    }


def stroke_table(coverage: Mapping[str, Any] | None) -> dict[str, Any] | None:
    """The share of each leg's stroke the poses' readings cover (a leg model with a curve of
    the stroke), and the findings below it, as the text says them; None without one."""
    if not coverage:
        return None
    rows = [(f"leg {k + 1}", 100.0 * c) for k, c in enumerate(coverage["covered"])]
    findings = "; ".join(f"warning: {f}" for f in coverage.get("findings") or [])
    note = "The stroke terms are determined where the readings cover the stroke." + (
        f" {findings}." if findings else ""
    )
    return {"columns": ["leg", "stroke covered (%)"], "rows": rows, "sortable": False, "note": note}


def observability_report(
    data: Mapping[str, Any], poses: Any, box: Any | None = None, inputs: Mapping[str, Any] | None = None
) -> dict[str, Any]:
    """The page of ``hexcal observability --html``: what measures, the gauge freedoms, indices,
    the noise assumed, predicted accuracy, the stroke coverage, the predicted standard deviation
    of every parameter, singular values, the poses.

    ``data`` is ``PoseAnalysis.to_dict()``; ``poses`` the analysed poses (n, 6).
    """
    keys = ("n_poses", "n_parameters", "rank", "condition_number", "O1", "O2", "O3", "O4", "O5")
    indices = [(INDEX_LABELS[k], data.get(k)) for k in keys if k in data]
    if data.get("instrument"):
        indices.insert(0, ("measured by", data["instrument"]))
    if data.get("gauge_labels"):
        indices.insert(3, ("gauge freedoms (fixed by the convention)", ", ".join(data["gauge_labels"])))
    predicted = data.get("predicted_mean_abs_error_mm", {})
    tests = data.get("test_poses") or {}
    accuracy = [("mean absolute parameter error (mm)", predicted.get("estimator"), predicted.get("bound"))]
    for key, label, scale in (
        ("position_rms_mean_mm", "test pose position RMS, mean (mm)", 1.0),
        ("position_rms_max_mm", "test pose position RMS, max (mm)", 1.0),
        ("orientation_rms_mean_rad", "test pose orientation RMS, mean (mrad)", 1e3),
        ("orientation_rms_max_rad", "test pose orientation RMS, max (mrad)", 1e3),
    ):
        if key in tests:
            accuracy.append((label, None if tests[key] is None else tests[key] * scale, None))
    params = [
        (name, v.get("std_estimator"), v.get("std_bound"), UNIT_WORDS[parameter_unit(name)])
        for name, v in data.get("parameters", {}).items()
    ]
    tables = {
        "Observability indices": {"columns": ["index", "value"], "rows": indices, "sortable": False},
        "Noise assumed": noise_table(data.get("noise")),
        "Predicted accuracy": {"columns": ["quantity", "estimator", "Cramér–Rao bound"], "rows": accuracy},
        "Predicted standard deviation per parameter": {
            "columns": ["parameter", "estimator", "Cramér–Rao bound", "unit"],
            "rows": params,
        },
    }
    stroke = stroke_table(data.get("stroke_coverage"))
    if stroke is not None:
        tables["Stroke coverage"] = stroke
    if data.get("unidentifiable"):
        tables["Parameter changes these poses cannot see"] = {
            "columns": ["combination (a direction δθ ∝ the sum)"],
            "rows": [(c,) for c in data["unidentifiable"]],
        }
    figures = {"singular_values": fig.svg(fig.singular_values(data["singular_values"], RANK_RTOL))}
    figures["workspace"] = fig.svg(fig.workspace_poses(poses, box, "Analysed poses in the workspace"))
    return {
        "kind": "observability",
        "title": "Observability of a measurement pose set",
        "subtitle": f"{data.get('n_poses')} poses, {data.get('n_parameters')} parameters, "
        f"residual {data.get('method')}, scaling {data.get('scaling')}",
        "tables": tables,
        "figures": figures,
        "wide": ["workspace"],
        "captions": {
            "singular_values": "Singular values of the scaled identification Jacobian of these poses.",
            "workspace": POSES_CAPTION.format("analysed"),
        },
        "inputs": dict(inputs or {}),
    }


def selection_rows(data: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """The selection in words: strategy, criterion and what its value means (with units),
    the value of the selected set and of the greedy start, the exchanges, the seed."""
    rows: list[tuple[str, Any]] = [("strategy", data.get("strategy"))]
    criterion = data.get("criterion")
    if data.get("label"):
        rows.append(("selected", data["label"]))
    if criterion:
        rows.append(("criterion", CRITERION_WORDS.get(criterion, criterion)))
        for key, text_key, label in (
            ("value", "value_text", "criterion of the selected poses"),
            ("greedy_value", "greedy_text", "criterion after the greedy start (before the exchanges)"),
        ):
            value = data.get(text_key)
            if value is None and data.get(key) is not None:
                value = describe_value(data[key], criterion)
            if value is not None:
                rows.append((label, value))
        rows.append(("exchanges made", data.get("swaps")))
    rows += [("poses", data.get("n")), ("candidates", data.get("candidates")), ("seed", data.get("seed"))]
    rows.append(("measured by", data.get("instrument")))
    return [(k, str(v)) for k, v in rows if v is not None]  # words: one left-aligned column


def selection_report(
    data: Mapping[str, Any], poses: Any, box: Any | None = None, inputs: Mapping[str, Any] | None = None
) -> dict[str, Any]:
    """The page of ``hexcal select --html``: the selection in words (what measures), the
    predicted errors of the strategies compared, the noise assumed, the stroke coverage (a leg
    model with a curve of the stroke), the selected poses (table and workspace figure).

    ``data`` is ``PoseSelection.to_dict()``; ``poses`` the selected poses (n, 6), in the
    order of ``data["ids"]``.
    """
    comparisons = data.get("comparisons") or {}
    method = data.get("method", "length")
    predicted = [
        (
            "the selected poses" if name == "selected" else comparisons.get(name, name),
            v.get("estimator"),
            v.get("bound"),
        )
        for name, v in data.get("predicted_mean_abs_error_mm", {}).items()
    ]
    p = np.asarray(poses, dtype=float).reshape(-1, 6)
    angles = np.rad2deg(p[:, 3:])
    rows = [(pid, *p[k, :3].tolist(), *angles[k].tolist()) for k, pid in enumerate(data.get("ids", []))]
    tables = {
        "Selection": {"columns": ["", "value"], "rows": selection_rows(data), "sortable": False},
        "Predicted mean absolute parameter error (mm)": {
            "columns": ["poses", f"identify (method {method})", "Cramér–Rao bound"],
            "rows": predicted,
        },
    }
    if data.get("noise"):
        tables["Noise assumed"] = noise_table(data["noise"])
    stroke = stroke_table(data.get("stroke_coverage"))
    if stroke is not None:
        tables["Stroke coverage"] = stroke
    tables["Selected poses"] = {
        "columns": ["id", "x (mm)", "y (mm)", "z (mm)", "a (deg)", "b (deg)", "c (deg)"],
        "rows": rows,
    }
    criterion = data.get("criterion")
    return {
        "kind": "select",
        "title": f"Selected measurement poses ({data.get('n')}"
        + (f", {criterion}-optimal)" if criterion else ")"),
        "subtitle": f"strategy {data.get('strategy')}, candidates {data.get('candidates')}, "
        f"seed {data.get('seed')}",
        "tables": tables,
        "figures": {"workspace": fig.svg(fig.workspace_poses(p, box, "Selected poses in the workspace"))},
        "wide": ["workspace"],
        "captions": {"workspace": POSES_CAPTION.format("selected")},
        "inputs": dict(inputs or {}),
    }
