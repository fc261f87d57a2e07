"""Presentation: results as plain dictionaries, rendered as text, strict JSON, CSV tables
and figures. ``render(kind, data, fmt)`` dispatches through the registry ``RENDERERS``
(an HTML renderer is one more module); ``*_dict`` functions turn the lower layers'
results into those dictionaries. The only layer that imports matplotlib (in
:mod:`hexcal.report.figures`). Imports the layers below; never touches files except
through the paths its callers give.

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
        "IDENTIFICATION_CAPTIONS": "html_pages",
        "POSE_COLUMNS": "tables",
        "RASTER_POINTS": "figures_report",
        "RENDERERS": "registry",
        "SELECT_JSON_KEYS": "plan",
        "STUDY_COLUMNS": "tables",
        "TEXT_RENDERERS": "registry",
        "Table": "tables",
        "VALIDATION_CAPTIONS": "html_pages",
        "WEAK_SINGULAR_VALUE": "text",
        "claims_text": "plan",
        "correlation": "figures_report",
        "data_table": "html",
        "errormap_tables": "tables",
        "esc": "html",
        "figure_grid": "html",
        "fit_statistics": "html_pages",
        "format_identification_report": "text",
        "format_paper_summary": "text",
        "format_validation": "text",
        "formats": "registry",
        "html_page": "html",
        "identification_dict": "convert",
        "identification_page": "html_pages",
        "identification_report": "html_reports",
        "identification_report_dict": "convert",
        "identification_summary": "text",
        "identification_text": "text",
        "inputs_table": "html",
        "json_text": "jsonout",
        "key_value_table": "html",
        "number": "html",
        "observability_text": "plan",
        "paper_figure_data": "convert",
        "paper_text": "text",
        "parameter_changes": "figures_report",
        "parameter_rows": "html_pages",
        "plot_error_angles": "figures",
        "plot_error_lines": "figures",
        "plot_parameter_errors": "figures",
        "plot_selection_study": "figures",
        "plot_study": "figures",
        "plot_validation_errors": "figures",
        "pose_residuals": "figures_report",
        "register": "registry",
        "render": "registry",
        "render_html": "html_reports",
        "section": "html",
        "select_json": "plan",
        "select_text": "plan",
        "singular_values": "figures_report",
        "strict": "jsonout",
        "study_table": "tables",
        "study_text": "text",
        "svg": "figures_report",
        "tables_page": "html_pages",
        "validation_dict": "convert",
        "validation_distributions": "figures_report",
        "validation_errors": "figures_report",
        "validation_page": "html_pages",
        "validation_report": "html_reports",
        "validation_table": "tables",
        "validation_text": "text",
        "verdict_block": "html",
        "workspace_poses": "figures_report",
    },
)
