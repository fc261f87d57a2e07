"""Presentation: results as dictionaries rendered as text, JSON and figures (the only
layer that imports matplotlib). Imports the layers below; never touches files except
through the paths its callers give.
"""

from hexcal._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "CORRELATION_REPORT": "text",
        "PAPER_TABLE1": "text",
        "PAPER_VALIDATION": "text",
        "ROW_LABELS": "text",
        "WEAK_SINGULAR_VALUE": "text",
        "format_identification_report": "text",
        "format_paper_summary": "text",
        "format_validation": "text",
        "identification_summary": "text",
        "paper_summary": "text",
        "plot_error_angles": "figures",
        "plot_error_lines": "figures",
        "plot_parameter_errors": "figures",
        "plot_selection_study": "figures",
        "plot_study": "figures",
        "plot_validation_errors": "figures",
    },
)
