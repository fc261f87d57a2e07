"""The page of ``hexcal validate --iso230-4 --html`` (and ``--iso9283``): the ISO tests before
and after calibration, the validation's summary beside them, the inputs.

:func:`iso_report` gathers the figures (the polar plot, SVG) and the dictionaries into one
JSON-ready mapping; :func:`iso_page` turns it into the self-contained page (plain
dictionaries only, every text from an input escaped).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from hexcal.report.calibration_pages import summary_rows
from hexcal.report.figures.polar import polar_deviation
from hexcal.report.figures.render import svg
from hexcal.report.html import data_table, esc, figure_grid, html_page, inputs_table, section
from hexcal.report.iso_summary import POSE_COLUMNS, after_text, circle_rows, pose_rows

#: What the page says each figure is.
ISO_CAPTIONS = {
    "polar": "Radial deviation from the nominal circle (bold) about the commanded centre, magnified: "
    "counterclockwise run solid, clockwise run dashed; angles counterclockwise from the plane's u axis. "
    "Each plot has its own scale, stated above it (µm per division), as ballbar software does.",
}

#: The definitions the page states, by test (docs/iso-tests.md has them in full).
CIRCLE_DEFINITIONS = (
    "F (radial deviation): largest and smallest deviation of the actual path from the nominal circle, "
    "about the commanded centre.",
    "G (circular deviation): radial separation of the two concentric circles, centred on the actual "
    "path's least-squares circle, that enclose it; G(b) the same over both runs.",
    "H (circular hysteresis): largest radial difference between the CW and CCW runs at one angle.",
    "Commanded circle: the least-squares circle of each geometry's forward kinematics of the readings, "
    "every point commanded on it at its own angle.",
    "Before: the readings through the nominal model, the bar's setup held as given; after: what the "
    "calibrated model does not explain, with the bar's setup in the calibrated machine's frames "
    "(re-registered as validate does, or the calibrated setup: stated above the table); what compensation "
    "leaves, to first order.",
)
POSE_DEFINITIONS = (
    "Commanded pose: the forward kinematics of the readings through each geometry; attained pose: the "
    "instrument's, its setup in the calibrated machine's frames after calibration (stated above the tables).",
    "AP (ISO 9283 pose accuracy): barycentre of the attained poses minus the commanded pose; RP_l = "
    "l̄ + 3 S_l (l_j distance to the barycentre, S_l with n - 1); RP_a = ±3 S_a per angle.",
)


def iso_report(
    data: Mapping[str, Any],
    validation: Mapping[str, Mapping[str, Any]] | None = None,
    inputs: Mapping[str, Any] | None = None,
    title: str = "",
) -> dict[str, Any]:
    """Everything the ISO page shows: ``data`` (:func:`hexcal.report.iso_summary.iso_dict`), the
    validation summaries by geometry (``{name: {"summary": ...}}``), the inputs."""
    figures = {}
    circles = data.get("iso230_4")
    if circles:
        figures["polar"] = svg(polar_deviation(circles, data.get("labels")))
    what = "ISO 230-4 circular test" if circles else "ISO 9283 pose accuracy and repeatability"
    return {
        "kind": "iso",
        "title": title or what,
        "subtitle": " vs ".join(data.get("labels", {}).values())
        + (f" · {data['instrument']}" if data.get("instrument") else ""),
        "iso": dict(data),
        "validation": dict(validation or {}),
        "figures": figures,
        "inputs": dict(inputs or {}),
    }


def iso_page(report: Mapping[str, Any]) -> str:
    """The self-contained ISO page of :func:`iso_report`."""
    data = report.get("iso", {})
    labels = data.get("labels", {})
    sections = []
    after = after_text(data.get("after_setup"))
    after = after[:1].upper() + after[1:]
    after_note = f'<p class="muted" id="after-setup">{esc(after)}.</p>' if after else ""
    circles = data.get("iso230_4")
    if circles:
        columns = ("", *(labels.get(n, n) for n in circles))
        rows = [
            (label, *(None if v is None else 1e3 * v for v in values))
            for label, values in circle_rows(circles)
        ]
        body = figure_grid(report.get("figures", {}), ISO_CAPTIONS, wide=("polar",)) + after_note
        body += data_table(columns, rows, sortable=False, digits=4, table_id="iso230-4-table")
        sections.append(section("ISO 230-4 circular test", body, "iso230-4"))
    stats = data.get("iso9283")
    if stats:
        tables = []
        for name, table in stats.items():
            tables.append(f"<h3>{esc(labels.get(name, name))}</h3>")
            tables.append(data_table(POSE_COLUMNS, pose_rows(table), digits=3, table_id=f"iso9283-{name}"))
        tol = data.get("visit_tolerance_mm")
        note = (
            f'<p class="muted">Visits of one commanded pose: leg readings within {tol:g} mm.</p>'
            if tol
            else ""
        )
        body = after_note + "".join(tables) + note
        sections.append(section("ISO 9283 pose accuracy and repeatability", body, "iso9283"))
    elif data.get("iso9283_note"):
        sections.append(section("ISO 9283", f"<p>{esc(data['iso9283_note'])}</p>", "iso9283"))
    validation = report.get("validation", {})
    if validation:
        columns = ("", *(labels.get(n, n) for n in validation))
        table = data_table(columns, summary_rows(validation), sortable=False, table_id="summary-table")
        sections.append(section("Validation summary", table, "summary"))
    definitions = CIRCLE_DEFINITIONS if circles else POSE_DEFINITIONS
    items = "".join(f"<li>{esc(text)}</li>" for text in definitions)
    sections.append(section("Definitions", f"<ul>{items}</ul>", "definitions"))
    sections.append(section("Inputs", inputs_table(report.get("inputs", {})), "inputs"))
    return html_page(report.get("title", "hexcal ISO tests"), sections, report.get("subtitle", ""))
