"""The pages of ``hexcal validate --html``: the validation page, the ISO page of an ISO test
(``--iso230-4``, ``--iso9283``), and a validation's view in a notebook.

Each renders one validation's dictionary (:func:`hexcal.report.validation_report_dict`, what
``hexcal.validate(...).to_dict()`` returns and ``--json`` writes; the text report renders the
same): the figures side by side, what the calibration expected and the measured / expected
ratios, how the instrument was re-registered (the text's own sentences), the conditions, the
per-pose errors and their figures (SVG), the ISO tests, the inputs. :func:`validation_report`
and :func:`iso_report` gather one JSON-ready mapping (with the figures); :func:`validation_page`
and :func:`iso_page` turn it into the self-contained page (plain dictionaries only, every
text from an input escaped). Orientation errors in mrad, instrument angles in degrees.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from hexcal.report import figures as fig
from hexcal.report.figures.polar import polar_deviation
from hexcal.report.figures.render import svg
from hexcal.report.html import data_table, esc, figure_grid, html_page, inputs_table, key_value_table, section
from hexcal.report.iso_summary import POSE_COLUMNS, after_text, circle_rows, pose_rows
from hexcal.report.text import expected_lines, registration_lines
from hexcal.report.units import (
    OWN_NOTE,
    UNIT_WORDS,
    display,
    has_poses,
    own_rows,
    parameter_unit,
    validation_rows,
    validation_summaries,
)

VALIDATION_CAPTIONS = {
    "pose_errors": "Position (mm) and orientation (mrad) error of every held-out pose, per geometry.",
    "distributions": "Distribution of the held-out pose errors per geometry (geometries a decade or more "
    "apart: a logarithmic axis, each geometry with its own logarithmic bins, so both show their shape).",
}

#: At most this many rows in a per-pose table (the worst poses; a note says so).
MAX_POSE_ROWS = 2000

#: What the page says each ISO figure is.
ISO_CAPTIONS = {
    "polar": "Radial deviation from the nominal circle (bold) about the commanded centre, magnified: "
    "counterclockwise run solid, clockwise run dashed; angles counterclockwise from the plane's u axis. "
    "Each plot has its own scale, stated above it (µm per division), as ballbar software does.",
}

#: The definitions the ISO page states, by test (docs/iso-tests.md has them in full).
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

#: The expected figures a page shows: label, key of ``expected``, key of the summary, factor.
EXPECTED_ROWS = (
    ("position RMS (mm)", "position_rms_mm", "position_rms", 1.0),
    ("orientation RMS (mrad)", "orientation_rms_rad", "orientation_rms", 1e3),
    ("leg RMS (mm)", "leg_rms_mm", "leg_rms", 1.0),
)

#: Where each expectation's σ come from, as the column says it.
EXPECTED_SOURCES = {
    "calibration": "expected from the calibration",
    "session": "expected with this session's noise",
    "given": "expected with the noise given",
}


# -- the one dictionary, by column ---------------------------------------------------------------


def is_record(data: Any) -> bool:
    """Whether ``data`` is a validation's one dictionary (:func:`validation_report_dict`)."""
    return isinstance(data, Mapping) and "per_pose" in data


def columns_of(data: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """Each validated geometry's summary and per-pose errors (``calibrated``, then ``nominal``
    when validated), as ``ValidationResult.to_dict()`` has them, from the one dictionary."""
    summaries = validation_summaries(dict(data))
    per = data["per_pose"]
    out = {}
    for name in ("calibrated", "nominal"):
        if per.get(name) is not None:
            out[name] = {"summary": summaries[name], "ids": per["ids"], **per[name]}
    return out


def _record_of(results: Mapping[str, Any]) -> dict[str, Any]:
    """The one dictionary's shape of validation results by name (the former argument of
    :func:`validation_report`: ``{"calibrated": ValidationResult, "nominal": ...}``)."""
    dicts = {name: r.to_dict() for name, r in results.items()}
    first_result = next(iter(results.values()))
    first = next(iter(dicts.values()))
    return {
        "instrument": getattr(first_result, "instrument", ""),
        "registration": first.get("registration"),
        "expected": first.get("expected"),
        "warnings": [],
        "iso": None,
        "conditions": {
            "instrument": getattr(first_result, "instrument", ""),
            "observations": len(first["ids"]),
        },
        "columns": dicts,
    }


# -- shared sections ---------------------------------------------------------------------------


def summary_rows(results: Mapping[str, Mapping[str, Any]]) -> list[tuple[Any, ...]]:
    """Rows of the validate summary, one column per geometry (orientation in mrad); a row
    no geometry has a value for is left out, the instrument's own errors follow."""
    summaries = [r["summary"] for r in results.values()]
    rows = validation_rows(list(summaries[0]) if summaries else [])
    out = []
    for label, key, scale in rows:
        values = [s.get(key) for s in summaries]
        finite = [v for v in values if isinstance(v, int | float) and v == v and abs(v) != float("inf")]
        if finite:
            out.append((label, *(None if v is None else v * scale for v in values)))
    return out


def _finite(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def expected_table(expected: Mapping[str, Any] | None, summary: Mapping[str, Any]) -> tuple[list, list]:
    """``(columns, rows)`` of what the calibration expected beside what was measured: each
    expectation (from the calibration's noise; with this session's noise) and the ratio of the
    measured RMS to it; none for an expectation without a pose (a ball bar), as in the text."""
    if not expected:
        return [], []
    entries = [
        e for e in (expected, expected.get("with_session_noise")) if e and _finite(e["position_rms_mm"])
    ]
    if not entries:
        return [], []
    columns = ["", "measured"]
    for entry in entries:
        columns += [EXPECTED_SOURCES.get(entry.get("noise"), "expected"), "measured / expected"]
    rows = []
    for label, key, own, scale in EXPECTED_ROWS:
        measured = summary.get(own)
        row: list[Any] = [label, measured * scale if _finite(measured) else None]
        for entry in entries:
            value = entry.get(key)
            ratio = (entry.get("measured_over_expected") or {}).get(key)
            row += [value * scale if _finite(value) else None, ratio if _finite(ratio) else None]
        rows.append(tuple(row))
    return columns, rows


def expected_section(expected: Mapping[str, Any] | None, summary: Mapping[str, Any]) -> str:
    """What the calibration expected this validation to measure, its sentences as the text
    says them, the table, and the warnings its comparison gives."""
    columns, rows = expected_table(expected, summary)
    if not rows:
        return ""
    lines = expected_lines(dict(expected or {}))
    said = [ln for ln in lines if not ln.strip().startswith(("measured /", "warning:"))]
    warnings = [ln.strip().removeprefix("warning: ") for ln in lines if ln.strip().startswith("warning:")]
    body = data_table(columns, rows, sortable=False, digits=4, table_id="expected-table")
    body += "".join(f'<p class="muted">{esc(line)}.</p>' for line in said)
    if warnings:
        body += (
            '<ul class="reasons">' + "".join(f'<li class="warn">{esc(w)}</li>' for w in warnings) + "</ul>"
        )
    return section("Expected from the calibration", body, "expected")


def registration_rows(record: Mapping[str, Any]) -> list[tuple[Any, ...]]:
    """Rows ``(quantity, value, std. error, unit)`` of the re-registration on all the poses
    (degrees for instrument angles)."""
    values, stderr = record.get("values") or {}, record.get("stderr") or {}
    return [
        (
            name,
            display(name, values.get(name)),
            display(name, stderr.get(name)),
            UNIT_WORDS[parameter_unit(name)],
        )
        for name in record.get("quantities") or []
    ]


def registration_section(record: Mapping[str, Any] | None) -> str:
    """How the instrument's free quantities were re-registered on the session: the text's
    sentence, and the quantities fitted on all the poses."""
    if not record:
        return ""
    sentence = " ".join(registration_lines(dict(record)))
    body = f"<p>{esc(sentence)}.</p>"
    rows = registration_rows(record)
    if rows:
        body += data_table(
            ("quantity", "value", "std. error", "unit"), rows, sortable=False, table_id="registration-table"
        )
    return section("Re-registration", body, "registration")


def _warnings_section(warnings: list[str]) -> str:
    if not warnings:
        return ""
    items = "".join(f'<li class="warn">{esc(w)}</li>' for w in warnings)
    return section("Warnings", f'<ul class="reasons">{items}</ul>', "warnings")


def conditions_rows(data: Mapping[str, Any]) -> dict[str, Any]:
    """The conditions of a validation in words: the geometries, the instrument, the held-out
    observations, how the setup was taken (re-registered, with the folds and seed, or as
    given)."""
    conditions = data.get("conditions") or {}
    record = data.get("registration")
    rows: dict[str, Any] = {}
    if "geometry" in conditions:
        rows["calibrated geometry"] = conditions.get("geometry") or "unnamed"
        rows["nominal geometry"] = (
            (conditions.get("nominal_geometry") or "unnamed") if data.get("nominal") else "not validated"
        )
    rows["instrument"] = conditions.get("instrument") or data.get("instrument") or "-"
    rows["held-out observations"] = conditions.get("observations")
    if record:
        kinds = sorted({str(q).split(".")[0] for q in record.get("quantities") or []})
        rows["instrument setup"] = (
            f"re-registered on this session ({', '.join(kinds)}): {record.get('folds')}-fold "
            f"cross-validation, seed {record.get('seed')}"
        )
        if record.get("held"):
            rows["held as given"] = ", ".join(map(str, record["held"]))
    else:
        rows["instrument setup"] = "as given (every quantity fixed)"
    return {k: v for k, v in rows.items() if v is not None}


def _conditions_section(data: Mapping[str, Any]) -> str:
    return section("Conditions", key_value_table(conditions_rows(data)), "conditions")


# -- the validation page -----------------------------------------------------------------------


def validation_report(
    validation: Any, inputs: Mapping[str, Any] | None = None, title: str = ""
) -> dict[str, Any]:
    """Everything the validate page shows, from a validation (:class:`hexcal.Validation`, or
    its ``to_dict()``: the text's and the JSON's schema); the ISO page's (:func:`iso_report`)
    for a validation with an ISO test. Also takes validation results by geometry name
    (``{"calibrated": ValidationResult, "nominal": ...}``). ``inputs`` names the files and
    options (default the validation's own)."""
    if hasattr(validation, "calibrated") and hasattr(validation, "to_dict"):  # a Validation
        validation = validation.to_dict()
    if is_record(validation):
        data = dict(validation)
        inputs = data.get("inputs") if inputs is None else inputs
        if data.get("iso"):
            return iso_report(data["iso"], inputs=inputs, title=title, record=data)
        results = columns_of(data)
    else:
        data = _record_of(validation)
        results = data.pop("columns")
    first = next(iter(results.values()))
    figures = {}
    if any(has_poses(d) for d in results.values()):  # none for a ballbar or one target: no pose
        figures = {
            "pose_errors": svg(fig.validation_errors(first["ids"], results)),
            "distributions": svg(fig.validation_distributions(results)),
        }
    instrument = data.get("instrument") or ""
    return {
        "kind": "validation",
        "title": title or "Validation on held-out measurements",
        "subtitle": f"{len(first['ids'])} held-out poses" + (f" ({instrument})" if instrument else ""),
        "instrument": instrument,
        "results": results,
        "record": {k: data.get(k) for k in ("registration", "expected", "warnings", "conditions", "nominal")},
        "figures": figures,
        "inputs": dict(inputs or {}),
    }


def _per_pose_section(results: Mapping[str, Mapping[str, Any]]) -> str:
    first = next(iter(results.values()))
    if not any(has_poses(r) for r in results.values()):  # a ballbar
        cols, rows = own_rows(results, first)
        table = data_table(cols, rows[:MAX_POSE_ROWS], table_id="poses", scroll=True)
        return section("Per pose", table + f'<p class="muted">{OWN_NOTE}</p>', "poses")
    per_pose = [
        (
            pid,
            *(
                v
                for r in results.values()
                for v in (
                    r["position_error"][k],
                    None if r["orientation_error"][k] is None else r["orientation_error"][k] * 1e3,
                )
            ),
        )
        for k, pid in enumerate(first["ids"])
    ]
    cols = ["pose"] + [f"{name} {q}" for name in results for q in ("position (mm)", "orientation (mrad)")]
    note = ""
    if len(per_pose) > MAX_POSE_ROWS:
        # a table of 10,000 rows slows the page down: keep the worst poses, say so
        per_pose = sorted(per_pose, key=lambda row: -row[1])[:MAX_POSE_ROWS]
        note = (
            f'<p class="muted" id="poses-note">The {MAX_POSE_ROWS} poses with the largest '
            f"{esc(next(iter(results)))} position error of {len(first['ids'])}; the full table: "
            "<code>hexcal validate --out FILE</code>.</p>"
        )
    table = data_table(cols, per_pose, table_id="poses", scroll=True)
    return section("Per pose", table + note, "poses")


def _record_sections(record: Mapping[str, Any], summary: Mapping[str, Any]) -> list[str]:
    """What the text says besides the figures: the expectation, the re-registration, warnings."""
    return [
        expected_section(record.get("expected"), summary),
        registration_section(record.get("registration")),
        _warnings_section(list(record.get("warnings") or [])),
    ]


def validation_page(report: Mapping[str, Any]) -> str:
    """The page of ``hexcal validate --html``: summary side by side, what the calibration
    expected, the re-registration, per-pose table, figures, conditions, inputs (orientation
    errors in mrad in the tables as in the figures)."""
    results = report.get("results", {})
    record = report.get("record") or {}
    columns = ("", *results)
    summary = data_table(columns, summary_rows(results), sortable=False, table_id="summary-table")
    sections = [section("Summary", summary, "summary")]
    first = next(iter(results.values()), None)
    if first is not None:
        sections += _record_sections(record, first["summary"])
        sections.append(_per_pose_section(results))
    figures = report.get("figures", {})
    if figures:
        sections.append(section("Figures", figure_grid(figures, VALIDATION_CAPTIONS), "figures"))
    sections.append(_conditions_section(dict(record) | {"instrument": report.get("instrument")}))
    sections.append(section("Inputs", inputs_table(report.get("inputs", {})), "inputs"))
    title = report.get("title", "hexcal validation report")
    return html_page(title, [s for s in sections if s], report.get("subtitle", ""))


# -- the ISO page --------------------------------------------------------------------------------


def iso_report(
    data: Mapping[str, Any],
    validation: Mapping[str, Mapping[str, Any]] | None = None,
    inputs: Mapping[str, Any] | None = None,
    title: str = "",
    record: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Everything the ISO page shows: ``data`` (:func:`hexcal.report.iso_summary.iso_dict`) and
    the polar figure (SVG), the validation (``record``: its one dictionary, whose summaries,
    expectation and re-registration the page shows beside the tests; or only the summaries by
    geometry, ``{name: {"summary": ...}}``), the inputs."""
    figures = {}
    circles = data.get("iso230_4")
    if circles:
        figures["polar"] = svg(polar_deviation(circles, data.get("labels")))
    what = "ISO 230-4 circular test" if circles else "ISO 9283 pose accuracy and repeatability"
    extra: dict[str, Any] = {}
    if record is not None:
        summaries = validation_summaries(dict(record))
        by_role = {"calibrated": summaries["calibrated"], "geometry": summaries["calibrated"]}
        by_role["nominal"] = summaries["nominal"]
        labels = data.get("labels") or {}
        validation = {n: {"summary": by_role[n]} for n in labels if by_role.get(n) is not None}
        extra = {
            "record": {
                k: record.get(k) for k in ("registration", "expected", "warnings", "conditions", "nominal")
            }
            | {"instrument": record.get("instrument")},
            "calibrated_summary": summaries["calibrated"],
        }
    return {
        "kind": "iso",
        "title": title or what,
        "subtitle": " vs ".join(data.get("labels", {}).values())
        + (f" · {data['instrument']}" if data.get("instrument") else ""),
        "iso": dict(data),
        "validation": dict(validation or {}),
        "figures": figures,
        "inputs": dict(inputs or {}),
    } | extra


def iso_sections(data: Mapping[str, Any], figures: Mapping[str, str] | None = None) -> list[str]:
    """The sections of the ISO tests: the circular test's table (and its polar figure, when
    drawn), the ISO 9283 tables, how the after column took the setup."""
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
        body = figure_grid(figures, ISO_CAPTIONS, wide=("polar",)) if figures else ""
        body += after_note + data_table(columns, rows, sortable=False, digits=4, table_id="iso230-4-table")
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
    return sections


def iso_page(report: Mapping[str, Any]) -> str:
    """The self-contained ISO page of :func:`iso_report`."""
    data = report.get("iso", {})
    labels = data.get("labels", {})
    sections = iso_sections(data, report.get("figures", {}))
    validation = report.get("validation", {})
    if validation:
        columns = ("", *(labels.get(n, n) for n in validation))
        table = data_table(columns, summary_rows(validation), sortable=False, table_id="summary-table")
        sections.append(section("Validation summary", table, "summary"))
    record = report.get("record")
    if record is not None:
        sections += _record_sections(record, report.get("calibrated_summary") or {})
    definitions = CIRCLE_DEFINITIONS if data.get("iso230_4") else POSE_DEFINITIONS
    items = "".join(f"<li>{esc(text)}</li>" for text in definitions)
    sections.append(section("Definitions", f"<ul>{items}</ul>", "definitions"))
    if record is not None:
        sections.append(_conditions_section(record))
    sections.append(section("Inputs", inputs_table(report.get("inputs", {})), "inputs"))
    return html_page(
        report.get("title", "hexcal ISO tests"), [s for s in sections if s], report.get("subtitle", "")
    )


# -- a notebook's view -----------------------------------------------------------------------------


def validation_summary(data: Mapping[str, Any]) -> str:
    """A validation in a notebook (``Validation._repr_html_``): the figures side by side, what
    the calibration expected, the re-registration and the ISO tables, as an HTML fragment of
    the one dictionary (no figure drawn)."""
    results = columns_of(data)
    calibrated = results["calibrated"]["summary"]
    instrument = data.get("instrument") or ""
    head = (
        f"<p><b>Validation</b> on {esc(calibrated.get('poses'))} held-out observation(s)"
        + (f" ({esc(instrument)})" if instrument else "")
        + "</p>"
    )
    table = data_table(("", *results), summary_rows(results), sortable=False, table_id="summary-table")
    parts = [head, table, *_record_sections(data, calibrated)]
    if data.get("iso"):
        parts += iso_sections(data["iso"])
    return "<div>" + "".join(p for p in parts if p) + "</div>"
