"""The HTML pages of hexcal's commands, built from their ``to_dict()`` dictionaries.

A page's input is a plain mapping (JSON-ready): the result's ``to_dict()`` under
``"result"``, the figures as SVG text under ``"figures"`` (name to SVG, in display order),
and what makes the report traceable under ``"inputs"`` (files with their SHA-256, options,
hexcal version, date). See :mod:`hexcal.report.html` for the page itself.

>>> result = {"method": "ml", "poses": 15, "names": ["u1.x"], "start": {"u1.x": 305.4},
...           "parameters": {"u1.x": 305.3}, "stderr": {"u1.x": 0.01}, "bound": {"u1.x": 0.009}}
>>> page = identification_page({"result": result, "figures": {}, "inputs": {}})
>>> "u1.x" in page and 'id="parameters"' in page
True
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

from hexcal.report.html import (
    data_table,
    esc,
    figure_grid,
    html_page,
    inputs_table,
    key_value_table,
    section,
    verdict_block,
)
from hexcal.report.text import validation_rows

#: Captions of the identification figures, by figure name.
IDENTIFICATION_CAPTIONS = {
    "parameter_changes": "Identified change of every parameter from its nominal value, with ±2 standard "
    "errors (bars) and ±2 Cramér–Rao σ (ticks).",
    "pose_residuals": "RMS leg residual of every measured pose with the nominal and the identified "
    "parameters; outliers and flagged poses are marked.",
    "correlation": "Correlation matrix of the identified parameters (shared scale −1 to 1).",
    "singular_values": "Singular values of the column-normalised identification Jacobian, relative to "
    "the largest; the rank threshold is dashed.",
    "workspace": "Measured poses: positions x–y coloured by z (left) and angles a–b coloured by c "
    "(right); dashed: the nominal workspace box (measured poses of a miscalibrated machine lie off it).",
}

#: At most this many rows in a per-pose table (the worst poses; a note says so).
MAX_POSE_ROWS = 2000

VALIDATION_CAPTIONS = {
    "pose_errors": "Position and orientation error of every held-out pose, nominal and calibrated geometry.",
    "distributions": "Distribution of the held-out pose errors, nominal and calibrated geometry.",
}


def _verdict(result: Mapping[str, Any]) -> str:
    verdict = result.get("verdict")
    if verdict is None:
        return verdict_block("not assessed", ["this result carries no verdict"])
    return verdict_block(verdict, result.get("reasons", ()))


def _noise_text(noise: Any) -> str:
    if not isinstance(noise, Mapping):
        return "-" if noise is None else str(noise)
    sig = noise.get("sigmas", noise)
    source = noise.get("source", "given")
    try:
        return (
            f"σ leg {float(sig['leg']):.4g} mm, position {float(sig['position']):.4g} mm, "
            f"orientation {float(sig['orientation']):.4g} rad ({source})"
        )
    except (KeyError, TypeError, ValueError):
        return str(noise)


def fit_statistics(result: Mapping[str, Any]) -> dict[str, Any]:
    """The fit statistics shown on the identify page, labelled."""
    rows: dict[str, Any] = {
        "estimator": result.get("method_label", result.get("method", "-")),
        "measurement": result.get("model", "pose"),
        "poses": result.get("poses"),
        "parameters varied": result.get("n_parameters", len(result.get("names", ()))),
        "degrees of freedom": result.get("dof"),
        "leg RMS before (mm)": result.get("leg_rms_before"),
        "leg RMS after (mm)": result.get("leg_rms_after"),
        "reduced chi-square": result.get("reduced_chi_square"),
        "rank": result.get("rank"),
        "noise model": _noise_text(result.get("noise")),
        "iterations": result.get("iterations"),
        "solver status": result.get("message"),
    }
    if result.get("outliers"):
        rows["outliers removed (pose ids)"] = " ".join(map(str, result["outliers"]))
    if result.get("flagged"):
        rows["poses flagged (ids)"] = " ".join(map(str, result["flagged"]))
    return {k: v for k, v in rows.items() if v is not None}


def parameter_rows(result: Mapping[str, Any]) -> list[tuple[Any, ...]]:
    """Rows ``(name, nominal, identified, change, stderr, bound)`` of the parameter table."""
    names = result.get("names") or list(result.get("parameters", {}))
    start, values = result.get("start", {}), result.get("parameters", {})
    stderr, bound = result.get("stderr", {}), result.get("bound") or {}
    rows = []
    for name in names:
        value, nominal = values.get(name), start.get(name)
        change = value - nominal if value is not None and nominal is not None else None
        rows.append((name, nominal, value, change, stderr.get(name), bound.get(name)))
    return rows


def identification_page(report: Mapping[str, Any]) -> str:
    """The page of ``hexcal identify --html``: verdict, statistics, parameters, figures, inputs."""
    result = report.get("result", {})
    title = report.get("title", "hexcal calibration report")
    sections = [
        _verdict(result),
        section("Fit statistics", key_value_table(fit_statistics(result)), "statistics"),
        section(
            "Parameters",
            data_table(
                ("parameter", "nominal", "identified", "change", "std. error", "Cramér–Rao σ"),
                parameter_rows(result),
                table_id="parameters",
                scroll=True,
            )
            + '<p class="muted">mm for joints and l0; gains dimensionless. Click a column to sort.</p>',
            "parameters-section",
        ),
    ]
    figures = report.get("figures", {})
    if figures:
        sections.append(section("Figures", figure_grid(figures, IDENTIFICATION_CAPTIONS), "figures"))
    sections.append(section("Inputs", inputs_table(report.get("inputs", {})), "inputs"))
    return html_page(title, sections, report.get("subtitle", ""))


def validation_page(report: Mapping[str, Any]) -> str:
    """The page of ``hexcal validate --html``: summary side by side, per-pose table, figures."""
    results = report.get("results", {})
    columns = ("", *results)
    summaries = [r["summary"] for r in results.values()]
    # the rows of the text report: the instrument's own errors too, none the instrument cannot give
    rows = [(label, *(s.get(k, float("nan")) for s in summaries)) for label, k in validation_rows(summaries)]
    sections = [section("Summary", data_table(columns, rows, sortable=False), "summary")]
    first = next(iter(results.values()), None)
    if first is not None:
        per_pose = [
            (pid, *(r[key][k] for r in results.values() for key in ("position_error", "orientation_error")))
            for k, pid in enumerate(first["ids"])
        ]
        cols = ["pose"] + [f"{name} {q}" for name in results for q in ("position (mm)", "orientation (rad)")]
        note = ""
        if len(per_pose) > MAX_POSE_ROWS:
            # a table of 10,000 rows slows the page down: keep the worst poses, say so
            per_pose = sorted(per_pose, key=lambda row: -row[1])[:MAX_POSE_ROWS]
            note = (
                f'<p class="muted" id="poses-note">The {MAX_POSE_ROWS} poses with the largest '
                f"{next(iter(results))} position error of {len(first['ids'])}; the full table: "
                "<code>hexcal validate --out FILE</code>.</p>"
            )
        table = data_table(cols, per_pose, table_id="poses", scroll=True)
        sections.append(section("Per pose", table + note, "poses"))
    figures = report.get("figures", {})
    if figures:
        sections.append(section("Figures", figure_grid(figures, VALIDATION_CAPTIONS), "figures"))
    sections.append(section("Inputs", inputs_table(report.get("inputs", {})), "inputs"))
    return html_page(report.get("title", "hexcal validation report"), sections, report.get("subtitle", ""))


def tables_page(report: Mapping[str, Any]) -> str:
    """A page of tables and figures (``hexcal paper`` and ``hexcal simulate``).

    ``report["tables"]`` maps a title to ``{"columns": [...], "rows": [[...], ...]}``; an
    optional ``report["text"]`` is shown preformatted (the command's text table, folded);
    the figures come after the tables, or first with ``report["figures_first"]``.
    """
    sections = []
    for title, table in report.get("tables", {}).items():
        body = data_table(
            table["columns"], table["rows"], table_id=_slug(title), scroll=len(table["rows"]) > 20
        )
        sections.append(
            section(title, body + '<p class="muted">Click a column to sort.</p>', f"{_slug(title)}-section")
        )
    figures = report.get("figures", {})
    if figures:
        grid = section("Figures", figure_grid(figures, report.get("captions", {})), "figures")
        sections.insert(0 if report.get("figures_first") else len(sections), grid)
    if report.get("text"):
        printed = (
            "<details><summary>the command's text output</summary>"
            f'<pre class="mono">{esc(report["text"])}</pre></details>'
        )
        sections.append(section("As printed", printed, "text"))
    sections.append(section("Inputs", inputs_table(report.get("inputs", {})), "inputs"))
    return html_page(report.get("title", "hexcal report"), sections, report.get("subtitle", ""))


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")
