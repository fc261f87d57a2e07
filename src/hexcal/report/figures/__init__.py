"""Figures: the only part of hexcal that imports matplotlib.

Each figure is described once, by a function of plain data (``to_dict()`` values, study
rows, arrays, an error map) that returns a matplotlib ``Figure``; :func:`save_png` writes
it as a file through the command's output set and :func:`svg` gives it as inline SVG for
an HTML page, so that a PNG and a page never show two versions of one figure. The
``plot_*`` functions are those figures written as PNG files.

- :mod:`~hexcal.report.figures.render`: PNG and SVG output, the conditions line, the
  shared conventions (legends off the data, round ticks, no mathtext from inputs);
- :mod:`~hexcal.report.figures.parameters`: per-parameter figures (identified changes,
  the paper's Fig. 10), correlations, singular values;
- :mod:`~hexcal.report.figures.poses`: residuals per pose, poses in the workspace, pose
  errors (the validate page and the paper's Fig. 11) and their distributions;
- :mod:`~hexcal.report.figures.campaigns`: studies of calibration campaigns;
- :mod:`~hexcal.report.figures.maps`: error maps (the paper's Figs. 4-9);
- :mod:`~hexcal.report.figures.polar`: the polar plot of an ISO 230-4 circular test.

Imports numpy, matplotlib, :mod:`hexcal.core` and :mod:`hexcal.report.units`.
"""

from hexcal.report.figures.campaigns import (
    plot_selection_study,
    plot_study,
    selection_study_figure,
    study_figure,
)
from hexcal.report.figures.maps import (
    error_angles_figure,
    error_lines_figure,
    plot_error_angles,
    plot_error_lines,
)
from hexcal.report.figures.parameters import (
    correlation,
    parameter_changes,
    parameter_errors_figure,
    plot_parameter_errors,
    singular_values,
)
from hexcal.report.figures.polar import plot_polar_deviation, polar_deviation
from hexcal.report.figures.poses import (
    plot_validation_errors,
    pose_errors,
    pose_residuals,
    validation_distributions,
    validation_errors,
    validation_errors_figure,
    workspace_poses,
)
from hexcal.report.figures.render import RASTER_POINTS, conditions, plain, save_png, svg

__all__ = [
    "RASTER_POINTS",
    "conditions",
    "correlation",
    "error_angles_figure",
    "error_lines_figure",
    "parameter_changes",
    "parameter_errors_figure",
    "plain",
    "plot_error_angles",
    "plot_error_lines",
    "plot_parameter_errors",
    "plot_polar_deviation",
    "plot_selection_study",
    "plot_study",
    "plot_validation_errors",
    "polar_deviation",
    "pose_errors",
    "pose_residuals",
    "save_png",
    "selection_study_figure",
    "singular_values",
    "study_figure",
    "svg",
    "validation_distributions",
    "validation_errors",
    "validation_errors_figure",
    "workspace_poses",
]
