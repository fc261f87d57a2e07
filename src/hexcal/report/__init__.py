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
        "METHOD_DESCRIPTIONS": "text",
        "PAPER_TABLE1": "text",
        "PAPER_VALIDATION": "text",
        "RENDERERS": "registry",
        "ROW_LABELS": "text",
        "SELECT_JSON_KEYS": "plan",
        "STUDY_COLUMNS": "tables",
        "WEAK_SINGULAR_VALUE": "text",
        "analysis_dict": "convert",
        "claims_text": "plan",
        "errormap_tables": "tables",
        "format_identification_report": "text",
        "format_paper_summary": "text",
        "format_validation": "text",
        "formats": "registry",
        "identification_dict": "convert",
        "identification_report_dict": "convert",
        "identification_summary": "text",
        "identification_text": "text",
        "json_text": "jsonout",
        "observability_text": "plan",
        "paper_figure_data": "convert",
        "paper_summary": "convert",
        "paper_text": "text",
        "plot_error_angles": "figures",
        "plot_error_lines": "figures",
        "plot_parameter_errors": "figures",
        "plot_selection_study": "figures",
        "plot_study": "figures",
        "plot_validation_errors": "figures",
        "register": "registry",
        "render": "registry",
        "select_json": "plan",
        "select_text": "plan",
        "strict": "jsonout",
        "study_table": "tables",
        "study_text": "text",
        "validation_dict": "convert",
        "validation_table": "tables",
        "validation_text": "text",
    },
)
