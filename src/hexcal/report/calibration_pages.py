"""The page of ``hexcal identify --html`` (and a calibration's view in a notebook): what it
shows, gathered from the calibration, and the page itself (``hexcal validate``'s pages:
:mod:`hexcal.report.validation_pages`).

:func:`identification_report` gathers, from a calibration, its ``to_dict()`` and its figures
(SVG), into one JSON-ready mapping; :func:`identification_page` turns such a mapping into the
self-contained page (it reads plain dictionaries only). Lengths in mm, instrument angles in
degrees, errors of orientation in mrad, everywhere on a page and in its figures.

>>> result = {"method": "ml", "poses": 15, "names": ["u1.x"], "start": {"u1.x": 305.4},
...           "parameters": {"u1.x": 305.3}, "stderr": {"u1.x": 0.01}, "bound": {"u1.x": 0.009}}
>>> page = identification_page({"result": result, "figures": {}, "inputs": {}})
>>> "u1.x" in page and 'id="parameters"' in page
True
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from hexcal.core.linalg import RANK_RTOL
from hexcal.estimation.registry import ESTIMATORS
from hexcal.report import figures as fig
from hexcal.report.html import (
    data_table,
    esc,
    figure_grid,
    html_page,
    inputs_table,
    key_value_table,
    section,
    to_precision,
    verdict_block,
)
from hexcal.report.units import UNIT_WORDS, display, fmt, is_angle, parameter_unit

#: Captions of the identification figures, by figure name.
IDENTIFICATION_CAPTIONS = {
    "parameter_changes": "Identified change of every parameter from its start value, with ±2 standard "
    "errors (bars) and ±2 Cramér–Rao σ (ticks); one panel per unit (mm, 10⁻³ for gains, degrees).",
    "pose_residuals": "RMS leg residual of every measured pose with the nominal and the identified "
    "parameters; outliers and flagged poses are marked.",
    "correlation": "Correlation matrix of the identified parameters (shared scale −1 to 1), grouped by "
    "block: lines between the blocks, their names above.",
    "singular_values": "Singular values of the column-normalised identification Jacobian, relative to "
    "the largest; the rank threshold is dashed.",
    "workspace": "The poses of the measurements (measured, or estimated from what the instrument saw): "
    "positions x–y coloured by z (left) and angles a–b coloured by c (right); poses at one place are "
    "drawn as rings, one per pose. Dashed: the nominal workspace box (the poses a miscalibrated machine "
    "reaches may lie off it).",
}

#: Correlation matrices of more parameters than this span the page's width.
WIDE_CORRELATION = 24


# -- identify ------------------------------------------------------------------------------------


def identification_report(
    result: Any, inputs: Mapping[str, Any] | None = None, title: str = ""
) -> dict[str, Any]:
    """Everything the identify page shows, from a calibration (:class:`hexcal.Calibration`: its
    ``to_dict()``, the text's and the JSON's schema) or an identification (any instrument, any
    number of sessions); ``inputs`` names the files, options and versions that produced it
    (default the calibration's own)."""
    if hasattr(result, "leg_model_choice") and hasattr(result, "result"):  # a Calibration
        summary = result.to_dict()
        inputs = summary.get("inputs") if inputs is None else inputs
        result = result.result
    else:
        summary = result.to_dict()
    estimator = ESTIMATORS.get(summary["method"])
    if estimator is not None:
        summary["method_label"] = f"{estimator.name}: {estimator.label}"
    figures = {"parameter_changes": fig.svg(fig.parameter_changes(summary))}
    before, after = summary.get("pose_rms_before"), summary.get("pose_rms_after")
    if before is not None and after is not None:
        marked = {"outlier (left out)": summary["outliers"], "flagged": summary["flagged"]}
        figures["pose_residuals"] = fig.svg(fig.pose_residuals(summary["ids"], before, after, marked))
    figures["correlation"] = fig.svg(fig.correlation(summary["names"], summary["correlation"]))
    figures["singular_values"] = fig.svg(fig.singular_values(summary["singular_values"], RANK_RTOL))
    if result.poses is not None:
        figures["workspace"] = fig.svg(
            fig.workspace_poses(result.poses, result.start.workspace, "Poses of the measurements")
        )
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
        "wide": ["correlation"] if len(summary["names"]) > WIDE_CORRELATION else [],
        "inputs": dict(inputs or {}),
    }


def _verdict(result: Mapping[str, Any]) -> str:
    verdict = result.get("verdict")
    if verdict is None:
        return verdict_block("not assessed", ["this result carries no verdict"])
    return verdict_block(verdict, result.get("reasons", ()))


def fit_statistics(result: Mapping[str, Any]) -> dict[str, Any]:
    """The fit statistics shown on the identify page, labelled (the noise has its own section)."""
    sessions = result.get("sessions") or []
    rows: dict[str, Any] = {
        "estimator": result.get("method_label", result.get("method", "-")),
        "measurement": "; ".join(s["description"] for s in sessions) or result.get("model", "pose"),
        "poses": result.get("poses"),
        "parameters varied": result.get("n_parameters", len(result.get("names", ()))),
        "degrees of freedom": result.get("dof"),
        "leg RMS before (mm)": result.get("leg_rms_before"),
        "leg RMS after (mm)": result.get("leg_rms_after"),
        "reduced chi-square": result.get("reduced_chi_square"),
        "rank": result.get("rank"),
        "iterations": result.get("iterations"),
        "solver status": result.get("message"),
    }
    if result.get("outliers"):
        rows["outliers removed (pose ids)"] = " ".join(map(str, result["outliers"]))
    if result.get("flagged"):
        rows["poses flagged (ids)"] = " ".join(map(str, result["flagged"]))
    return {k: v for k, v in rows.items() if v is not None}


def _sigma(value: Any, unit: str) -> tuple[str, str]:
    """A noise σ for a table: angles in mrad."""
    if unit == "rad":
        return fmt(None if value is None else value * 1e3), "mrad"
    return fmt(value), unit


def noise_rows(result: Mapping[str, Any]) -> tuple[list[str], list[tuple[Any, ...]], str]:
    """``(columns, rows, note)`` of the noise the identification used: every group of every
    session, learned (σ and its standard error) or given (and what the data say of it)."""
    noise = result.get("noise")
    if not noise:
        return [], [], "no noise model: the estimator weighs every residual alike"
    if noise.get("source") == "estimated" and noise.get("groups"):
        rows = []
        for g in noise["groups"]:
            sigma, unit = _sigma(g["sigma"], g["unit"])
            err, _ = _sigma(g["stderr"], g["unit"])
            how = (
                "learned from the data" if g["estimated"] else "not learned: too few data (start value kept)"
            )
            rows.append((g["session"], g["label"], sigma, err if g["estimated"] else "-", unit, how))
        state = result.get("noise_estimate") or {}
        note = "Learned from the data (the default without --noise): σ of each group with its standard error."
        if state.get("converged") is False:
            note += f" The estimate did not converge in {state.get('iterations')} iterations."
        return ["session", "group", "σ", "std. error", "unit", "source"], rows, note
    check = result.get("noise_check") or {}
    dist = noise.get("distribution", "")
    if check:
        rows = []
        for group, c in check.items():
            unit = "rad" if group.split()[-1] in ("orientation", "angle") else "mm"
            given, unit_shown = _sigma(c["given"], unit)
            data, _ = _sigma(c["given"] * c["ratio"], unit)
            verdict = "disagrees" if c.get("disagrees") else "agrees"
            rows.append((group, given, data, unit_shown, fmt(c["ratio"], 3), fmt(c["p_value"], 2), verdict))
        columns = ["group", "given σ", "σ the data show", "unit", "ratio", "p-value", "the data"]
        return columns, rows, f"Given, not learned ({dist}), as standard deviations; tested against the data."
    rows = []
    for s in result.get("sessions") or [{"label": "", "noise": noise}]:
        for group, unit in (("leg", "mm"), ("position", "mm"), ("orientation", "rad")):
            sigma, shown = _sigma((s.get("noise") or noise).get(group), unit)
            rows.append((s["label"], group, sigma, shown))
    return (
        ["session", "group", "given σ", "unit"],
        rows,
        f"Given with --noise ({dist}), as standard deviations.",
    )


def _noise_section(result: Mapping[str, Any]) -> str:
    columns, rows, note = noise_rows(result)
    table = data_table(columns, rows, sortable=False, table_id="noise") if rows else ""
    return section("Noise", table + f'<p class="muted">{esc(note)}</p>', "noise-section")


def session_rows(result: Mapping[str, Any]) -> list[tuple[Any, ...]]:
    """Rows ``(session, instrument, observations, frame)`` of the sessions table."""
    rows = []
    for s in result.get("sessions") or []:
        reg = s.get("registration")
        if reg is None:
            frame = "given" if s.get("varied") or s.get("instrument") != "pose" else "the base frame"
        else:
            angle = (
                f", orientation RMS {fmt(reg['angle_rms_rad'] * 1e3)} mrad" if "angle_rms_rad" in reg else ""
            )
            unit = "poses" if "tool" in reg else "points"
            frame = (
                f"auto: registered from {reg['points']} {unit}, residual RMS {fmt(reg['rms_mm'])} mm, "
                f"max {fmt(reg['max_mm'])} mm{angle}"
            )
        rows.append((s["label"], s["description"], s["observations"], frame))
    return rows


def setup_rows(session: Mapping[str, Any]) -> list[tuple[Any, ...]]:
    """Rows ``(name, value, std. error, unit)`` of a session's calibrated setup: degrees for
    the instrument angles, mm otherwise."""
    rows = []
    for name, item in session["setup"].items():
        if name in session["varied"]:
            unit = UNIT_WORDS[parameter_unit(name)]
            rows.append((name, display(name, item["value"]), display(name, item["stderr"]), unit))
    return rows


def _sessions_section(result: Mapping[str, Any]) -> str:
    sessions = result.get("sessions") or []
    if not sessions:
        return ""
    columns = ("session", "instrument", "observations", "instrument frame")
    parts = [data_table(columns, session_rows(result), sortable=False, table_id="sessions")]
    gauges = result.get("gauges") or []
    if gauges:
        parts.append(
            f"<p><strong>Gauge freedoms</strong>: {len(gauges)} combinations no data can determine "
            f"({esc(', '.join(gauges))}), removed by the {esc(result.get('convention', ''))}. Rank, standard "
            "errors and bounds are those of the gauge-fixed parameters.</p>"
        )
    else:
        parts.append("<p><strong>Gauge freedoms</strong>: none.</p>")
    for k, s in enumerate(sessions):
        rows = setup_rows(s)
        held = [n for n in s["setup"] if n not in s["varied"]]
        if rows:
            parts.append(f"<h3>Calibrated setup: {esc(s['label'])}</h3>")
            parts.append(
                data_table(
                    ("quantity", "value", "std. error", "unit"),
                    rows,
                    sortable=False,
                    table_id=f"setup-{k + 1}",
                )
            )
            if held:
                parts.append(f'<p class="muted">Held exactly: {esc(", ".join(held))}.</p>')
        elif held:
            parts.append(
                f'<p class="muted">{esc(s["label"])}: the instrument setup is held exactly '
                "(nothing of it is identified).</p>"
            )
    return section("Sessions", "\n".join(parts), "sessions-section")


def parameter_rows(result: Mapping[str, Any]) -> list[tuple[Any, ...]]:
    """Rows ``(name, unit, nominal, identified, change, stderr, bound)`` of the parameter
    table, in the display unit of each parameter (degrees for instrument angles); the
    identified value and the change shown to the precision of the standard error (its two
    significant digits: :func:`hexcal.report.html.to_precision`)."""
    names = result.get("names") or list(result.get("parameters", {}))
    start, values = result.get("start", {}), result.get("parameters", {})
    stderr, bound = result.get("stderr", {}), result.get("bound") or {}
    rows = []
    for name in names:
        value, nominal = values.get(name), start.get(name)
        change = value - nominal if value is not None and nominal is not None else None
        shown = [display(name, v) for v in (nominal, value, change, stderr.get(name), bound.get(name))]
        error = shown[3]
        shown[1], shown[2] = to_precision(shown[1], error), to_precision(shown[2], error)
        shown[3] = to_precision(error, error)
        rows.append((name, UNIT_WORDS[parameter_unit(name)], *shown))
    return rows


def _leg_model_section(result: Mapping[str, Any]) -> str:
    """The leg model and, for ``auto``, the cross-validation's candidates and scores."""
    choice = result.get("leg_model_choice")
    model = result.get("leg_model", "linear")
    if not choice:
        return "" if model == "linear" else section("Leg model", f"<p>{esc(model)}</p>", "leg-model")
    rows = [
        (
            name + (" (chosen)" if name == choice["choice"] else ""),
            s["leg_rms_mm"],
            s["position_rms_mm"],
            1e3 * s["orientation_rms_rad"],
            s["parameters"],
        )
        for name, s in choice["scores"].items()
    ]
    table = data_table(
        ("candidate", "held-out leg RMS (mm)", "position RMS (mm)", "orientation RMS (mrad)", "parameters"),
        rows,
        table_id="leg-model-scores",
    )
    text = (
        f"<p>{esc(model)}, chosen by cross-validation ({esc(choice['scheme'])}; {esc(choice['rule'])}).</p>"
    )
    return section("Leg model", text + table, "leg-model")


def _splits_section(result: Mapping[str, Any]) -> str:
    """Where sessions were split where their instrument moved."""
    splits = result.get("splits") or []
    if not splits:
        return ""
    body = f"<p>Sessions split before {esc(', '.join(splits))}.</p>"
    first = result.get("before_split")
    if first:
        body += "<p>The sessions as given:</p>" + verdict_block(
            first.get("verdict"), first.get("reasons", ())
        )
    return section("Splits", body, "splits")


def calibration_summary(result: Mapping[str, Any]) -> str:
    """A calibration in a notebook (``Calibration._repr_html_``): the verdict, the leg model and
    the parameters, as an HTML fragment of :func:`hexcal.report.calibration_dict`'s mapping."""
    table = data_table(
        ("parameter", "unit", "nominal", "identified", "change", "std. error", "Cramér–Rao σ"),
        parameter_rows(result),
        table_id="parameters",
    )
    head = (
        f"<p><b>Calibration</b>: {esc(result.get('poses'))} poses, {len(result.get('names') or ())} "
        f"parameters, estimator {esc(result.get('method'))}, "
        f"leg model {esc(result.get('leg_model', 'linear'))}</p>"
    )
    return "<div>" + head + _verdict(result) + table + "</div>"


def identification_page(report: Mapping[str, Any]) -> str:
    """The page of ``hexcal identify --html``: the verdict (failures first), statistics, noise,
    sessions, parameters, figures, inputs."""
    result = report.get("result", {})
    angles = any(is_angle(n) for n in result.get("names") or result.get("parameters", {}))
    units = "Lengths in mm, gains dimensionless" + (", instrument angles in degrees" if angles else "")
    sections = [
        _verdict(result),
        section("Fit statistics", key_value_table(fit_statistics(result)), "statistics"),
        _noise_section(result),
        _sessions_section(result),
        _leg_model_section(result),
        _splits_section(result),
        section(
            "Parameters",
            data_table(
                ("parameter", "unit", "nominal", "identified", "change", "std. error", "Cramér–Rao σ"),
                parameter_rows(result),
                table_id="parameters",
                scroll=True,
            )
            + f'<p class="muted">{units}. Click a column to sort.</p>',
            "parameters-section",
        ),
    ]
    figures = report.get("figures", {})
    if figures:
        grid = figure_grid(figures, IDENTIFICATION_CAPTIONS, report.get("wide", ()))
        sections.append(section("Figures", grid, "figures"))
    sections.append(section("Inputs", inputs_table(report.get("inputs", {})), "inputs"))
    title = report.get("title", "hexcal calibration report")
    return html_page(title, [s for s in sections if s], report.get("subtitle", ""))
