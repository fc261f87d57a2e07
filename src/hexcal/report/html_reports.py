"""The import path ``hexcal.report.html_reports`` of the command line (no code of its own).

The HTML reports are organised by concept: the page in :mod:`hexcal.report.html`, the
pages of identify and validate in :mod:`hexcal.report.calibration_pages`, of paper and
simulate in :mod:`hexcal.report.study_pages`, of observability and select in
:mod:`hexcal.report.planning_pages`. Every name below is importable from
:mod:`hexcal.report` as well; this module keeps the command line's imports working until
they name :mod:`hexcal.report` (then it goes).
"""

from hexcal.report.calibration_pages import identification_report, validation_report
from hexcal.report.html import check_html_target
from hexcal.report.planning_pages import observability_report, selection_report
from hexcal.report.registry import render_html
from hexcal.report.study_pages import paper_note, paper_report, study_note, study_report

__all__ = [
    "check_html_target",
    "identification_report",
    "observability_report",
    "paper_note",
    "paper_report",
    "render_html",
    "selection_report",
    "study_note",
    "study_report",
    "validation_report",
]
