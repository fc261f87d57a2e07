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
- ``calibration_pages`` (identify, validate), ``study_pages`` (paper, simulate),
  ``planning_pages`` (observability, select): each family's pages, data and page;
- ``figures``: every figure described once, drawn to PNG or SVG.

>>> from hexcal.report import render
>>> print(render("claims", {"lines": {}, "angles": {}, "workspace": {}}, "json"), end="")
{
  "lines": {},
  "angles": {},
  "workspace": {}
}
"""

from hexcal._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "CORRELATION_REPORT": "text",
        "IDENTIFICATION_CAPTIONS": "calibration_pages",
        "POSE_COLUMNS": "tables",
        "RASTER_POINTS": "figures",
        "RENDERERS": "registry",
        "SELECT_JSON_KEYS": "plan",
        "STUDY_COLUMNS": "tables",
        "TEXT_RENDERERS": "registry",
        "Table": "tables",
        "VALIDATION_CAPTIONS": "calibration_pages",
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
        "identification_dict": "convert",
        "identification_page": "calibration_pages",
        "identification_report": "calibration_pages",
        "identification_report_dict": "convert",
        "identification_summary": "text",
        "identification_text": "text",
        "inputs_table": "html",
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
        "validation_page": "calibration_pages",
        "validation_report": "calibration_pages",
        "validation_table": "tables",
        "validation_text": "text",
        "verdict_block": "html",
        "workspace_poses": "figures",
    },
)
