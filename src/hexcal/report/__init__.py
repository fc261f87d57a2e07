"""Presentation: results as plain dictionaries, rendered as text, strict JSON, CSV tables,
figures and self-contained HTML pages. ``render(kind, data, fmt)`` dispatches through the
registry ``RENDERERS``; ``*_dict`` functions turn the lower layers' results into those
dictionaries. Imports the layers below; the only layer that imports matplotlib (in
:mod:`hexcal.report.figures`); never touches files except through the paths its callers
give (figures through the command's output set, :mod:`hexcal.report.staging`).

Modules, by concept:

- ``convert`` (results to dictionaries), ``registry`` (the renderers), ``jsonout``;
- ``text`` (identification, validation, paper, study), ``plan`` (observability, select,
  error-map claims), ``instrument`` (planning with a setup): text renderers;
- ``tables``: CSV tables; ``units``: how a parameter is shown (units, degrees, blocks);
- ``html``: the page (escaping, sections, tables, the figure grid, the inputs, the shell);
- ``calibration_pages`` (identify), ``validation_pages`` (validate and its ISO tests),
  ``study_pages`` (paper, simulate),
  ``planning_pages`` (observability, select): each family's pages, data and page;
- ``figures``: every figure described once, drawn to PNG or SVG.

>>> from hexcal.report import render
>>> print(render("claims", {"lines": {}, "angles": {}, "workspace": {}}, "json"), end="")
{
  "lines": {},
  "angles": {},
  "workspace": {}
}

Public names
------------
- ``render``, ``render_html``, ``RENDERERS``, ``TEXT_RENDERERS``, ``formats``, ``register``:
  results rendered by kind and format (text, json, html), and how to add a renderer.
- ``calibration_dict``, ``identification_dict``, ``identification_report_dict``,
  ``validation_report_dict``, ``validation_dict``, ``validation_json``, ``json_text``: results
  as plain dictionaries and strict JSON (docs/formats.md "JSON outputs"), the first and the
  fourth the one schema of a calibration and of a validation, which every report of each
  renders; ``calibration_summary``, ``validation_summary``: a calibration and a validation as
  HTML fragments (a notebook's view).
- ``format_identification_report``, ``format_validation``, ``identification_text``,
  ``validation_text``, ``study_text``, ``paper_text``, ``observability_text``,
  ``select_text``: the text reports the commands print.
- ``identification_report``, ``validation_report``, ``identification_page``,
  ``validation_page``, ``study_report``, ``paper_report``, ``observability_report``,
  ``selection_report``: the HTML reports (``--html``), their data and pages.
- ``study_table``, ``validation_table``, ``errormap_tables``: CSV tables of results.
- ``plot_parameter_errors``, ``plot_validation_errors``, ``plot_study``,
  ``plot_selection_study``, ``plot_error_lines``, ``plot_error_angles``,
  ``plot_polar_deviation``: figures written as PNG files.
- ``iso_dict``, ``iso_text``, ``iso_report``, ``iso_page``: the ISO 230-4 circular test and
  the ISO 9283 pose figures (``hexcal validate --iso230-4``, ``--iso9283``) as a dictionary,
  text and page.

Other names of the lazy map below (the HTML building blocks, figure builders, captions and
layout constants) are shared with the command line and are not part of the API.
"""

from hexcal._lazy import attach

_NAMES = {
    "CORRELATION_REPORT": "text",
    "IDENTIFICATION_CAPTIONS": "calibration_pages",
    "POSE_COLUMNS": "tables",
    "RASTER_POINTS": "figures",
    "RENDERERS": "registry",
    "SELECT_JSON_KEYS": "plan",
    "STUDY_COLUMNS": "tables",
    "TEXT_RENDERERS": "registry",
    "Table": "tables",
    "VALIDATION_CAPTIONS": "validation_pages",
    "WEAK_SINGULAR_VALUE": "text",
    "check_html_target": "html",
    "claims_text": "plan",
    "conditions": "figures",
    "correlation": "figures",
    "data_table": "html",
    "errormap_tables": "tables",
    "esc": "html",
    "figure_grid": "html",
    "fit_statistics": "calibration_pages",
    "format_identification_report": "text",
    "format_paper_summary": "text",
    "format_validation": "text",
    "formats": "registry",
    "html_page": "html",
    "calibration_dict": "convert",
    "calibration_summary": "calibration_pages",
    "identification_dict": "convert",
    "identification_page": "calibration_pages",
    "identification_report": "calibration_pages",
    "identification_report_dict": "convert",
    "identification_summary": "text",
    "identification_text": "text",
    "inputs_table": "html",
    "iso_dict": "iso_summary",
    "iso_page": "validation_pages",
    "iso_report": "validation_pages",
    "iso_text": "iso_summary",
    "json_text": "jsonout",
    "key_value_table": "html",
    "number": "html",
    "observability_report": "planning_pages",
    "observability_text": "plan",
    "paper_figure_data": "convert",
    "paper_note": "study_pages",
    "paper_report": "study_pages",
    "paper_text": "text",
    "parameter_changes": "figures",
    "parameter_rows": "calibration_pages",
    "plot_error_angles": "figures",
    "plot_error_lines": "figures",
    "plot_parameter_errors": "figures",
    "plot_polar_deviation": "figures",
    "polar_deviation": "figures",
    "plot_selection_study": "figures",
    "plot_study": "figures",
    "plot_validation_errors": "figures",
    "pose_errors": "figures",
    "pose_residuals": "figures",
    "register": "registry",
    "render": "registry",
    "render_html": "registry",
    "save_png": "figures",
    "section": "html",
    "select_json": "plan",
    "select_text": "plan",
    "selection_report": "planning_pages",
    "singular_values": "figures",
    "strict": "jsonout",
    "study_note": "study_pages",
    "study_report": "study_pages",
    "study_table": "tables",
    "study_text": "text",
    "svg": "figures",
    "tables_page": "html",
    "validation_dict": "convert",
    "validation_json": "convert",
    "validation_distributions": "figures",
    "validation_errors": "figures",
    "validation_page": "validation_pages",
    "validation_per_pose": "convert",
    "validation_report": "validation_pages",
    "validation_report_dict": "convert",
    "validation_summaries": "units",
    "validation_summary": "validation_pages",
    "validation_table": "tables",
    "validation_text": "text",
    "verdict_block": "html",
    "workspace_poses": "figures",
}

__all__ = [
    "RENDERERS",
    "TEXT_RENDERERS",
    "calibration_dict",
    "calibration_summary",
    "errormap_tables",
    "format_identification_report",
    "format_validation",
    "formats",
    "identification_dict",
    "identification_page",
    "identification_report",
    "identification_report_dict",
    "identification_text",
    "iso_dict",
    "iso_page",
    "iso_report",
    "iso_text",
    "json_text",
    "observability_report",
    "observability_text",
    "paper_report",
    "paper_text",
    "plot_error_angles",
    "plot_error_lines",
    "plot_parameter_errors",
    "plot_polar_deviation",
    "plot_selection_study",
    "plot_study",
    "plot_validation_errors",
    "register",
    "render",
    "render_html",
    "select_text",
    "selection_report",
    "study_report",
    "study_table",
    "study_text",
    "validation_dict",
    "validation_json",
    "validation_page",
    "validation_report",
    "validation_report_dict",
    "validation_summary",
    "validation_table",
    "validation_text",
]

__getattr__, _dir, _names = attach(__name__, _NAMES)


def __dir__() -> list[str]:
    return sorted(__all__)
