"""Planning a campaign: candidate poses, observability indices, identifiability,
predicted accuracy, optimal pose selection and error maps. Imports the core, instruments,
estimation and calibration layers.

Modules, lowest first: ``candidates`` (candidate poses and their feasibility),
``identifiability`` (rank, null space, lost combinations by name), ``indices`` (O1–O5),
``accuracy`` (predicted covariances and pose errors), ``analysis`` (one pose set, all of it),
``criteria`` (optimality criteria and their rank-6 updates), ``selection`` (greedy and
exchange), ``planning`` (a selection with its predicted accuracy beside other strategies),
``pose_errors``, ``errormap`` and ``paper_claims`` (the seed paper's error maps),
``ballbar_plan`` (ballbar circles), ``ballbar_selection`` (their selection).

>>> from hexcal.design import criterion_value
>>> criterion_value([[1.0, 0.0], [0.0, 1.0]], "A")
-2.0

Public names
------------
- ``candidate_poses``, ``KINDS``, ``boundary_grid``, ``check_feasibility``, ``Feasibility``,
  ``singularity_distance``, ``MIN_SINGULARITY_DISTANCE``: candidate measurement poses
  (docs/formats.md "Candidate specs") and which of them may be measured.
- ``analyse_poses``, ``PoseSetAnalysis``, ``observability_indices``, ``ObservabilityIndices``,
  ``SCALINGS``, ``unidentifiable_combinations``, ``mean_abs_error``: observability,
  identifiability and predicted accuracy of a pose set (``hexcal observability``).
- ``plan_selection``, ``PoseSelection``, ``optimal_poses``, ``compare_strategies``,
  ``StrategyComparison``: measurement poses by a strategy with their predicted accuracy
  (``hexcal select``).
- ``select_poses``, ``SelectionResult``, ``greedy_selection``, ``exchange_selection``,
  ``information_blocks``, ``information_matrix``, ``CRITERIA``, ``criterion_value``: optimal
  design on per-pose information blocks (D, A, E, O4).
- ``ballbar_circles``, ``Circles``, ``select_circles``, ``CircleSelection``, ``circle_accuracy``:
  ballbar campaigns (docs/ballbar.md): feasible circles at pivots, the circles and pivots
  chosen for a machine, and their predicted accuracy (``hexcal candidates/select --ballbar``).
- ``error_maps``, ``ErrorMaps``, ``claims``: pose error maps of parameter errors (the seed
  paper's Figs. 4-9) and the numbers that test its claims.

Other names of the lazy map below (ridges, screening constants, scorers, samplers, Jacobian
and rank helpers) are shared with hexcal's other layers and are not part of the API.
"""

from hexcal._lazy import attach

_NAMES = {
    "CircleSelection": "ballbar_selection",
    "Circles": "ballbar_plan",
    "ballbar_circles": "ballbar_plan",
    "circle_accuracy": "ballbar_selection",
    "select_circles": "ballbar_selection",
    "ANGLE_PAIRS": "errormap",
    "AngleMap": "errormap",
    "COMPARISON_DRAWS": "planning",
    "CRITERIA": "criteria",
    "EIG_RTOL": "criteria",
    "ErrorMaps": "errormap",
    "Feasibility": "candidates",
    "GREEDY_RIDGE": "criteria",
    "KINDS": "candidates",
    "LINE_AXES": "errormap",
    "LineMap": "errormap",
    "MEAN_ABS_FACTOR": "accuracy",
    "MIN_SINGULARITY_DISTANCE": "candidates",
    "ObservabilityIndices": "indices",
    "PoseSelection": "planning",
    "PoseSetAnalysis": "analysis",
    "SCALINGS": "indices",
    "SCORING_RIDGE": "criteria",
    "SCREEN_DIMENSIONS": "criteria",
    "SCREEN_SHORTLIST": "criteria",
    "Scorer": "criteria",
    "SelectionResult": "selection",
    "StrategyComparison": "planning",
    "analyse_poses": "analysis",
    "angle_grid_poses": "errormap",
    "as_mask": "identifiability",
    "best_by_eigenvalues": "criteria",
    "boundary_grid": "candidates",
    "candidate_poses": "candidates",
    "check_criterion": "criteria",
    "check_feasibility": "candidates",
    "claims": "paper_claims",
    "column_scales": "indices",
    "compare_strategies": "planning",
    "criterion_value": "criteria",
    "describe_value": "criteria",
    "error_maps": "errormap",
    "exchange_selection": "selection",
    "feasible_corners": "planning",
    "format_combination": "identifiability",
    "full_rank": "criteria",
    "greedy_selection": "selection",
    "indices_from_singular_values": "indices",
    "information_blocks": "criteria",
    "information_matrix": "criteria",
    "least_squares_covariance": "accuracy",
    "length_mean_abs": "accuracy",
    "line_sweep_poses": "errormap",
    "mean_abs_error": "accuracy",
    "mean_pose_errors": "pose_errors",
    "null_space": "identifiability",
    "numerical_rank": "identifiability",
    "observability_indices": "indices",
    "optimal_poses": "planning",
    "parameter_error_draws": "pose_errors",
    "plan_selection": "planning",
    "planning_jacobian": "identifiability",
    "platform_radius": "candidates",
    "pose_error_samples": "pose_errors",
    "predicted_error": "planning",
    "random_subsets": "selection",
    "select_poses": "selection",
    "singularity_distance": "candidates",
    "unidentifiable_combinations": "identifiability",
}

__all__ = [
    "CRITERIA",
    "KINDS",
    "MIN_SINGULARITY_DISTANCE",
    "SCALINGS",
    "CircleSelection",
    "Circles",
    "ErrorMaps",
    "Feasibility",
    "ObservabilityIndices",
    "PoseSelection",
    "PoseSetAnalysis",
    "SelectionResult",
    "StrategyComparison",
    "analyse_poses",
    "ballbar_circles",
    "boundary_grid",
    "candidate_poses",
    "check_feasibility",
    "circle_accuracy",
    "claims",
    "compare_strategies",
    "criterion_value",
    "error_maps",
    "exchange_selection",
    "greedy_selection",
    "information_blocks",
    "information_matrix",
    "mean_abs_error",
    "observability_indices",
    "optimal_poses",
    "plan_selection",
    "select_circles",
    "select_poses",
    "singularity_distance",
    "unidentifiable_combinations",
]

__getattr__, _dir, _names = attach(__name__, _NAMES)


def __dir__() -> list[str]:
    return sorted(__all__)
