"""Planning a campaign: candidate poses, observability indices, identifiability,
predicted accuracy, optimal pose selection and error maps. Imports the core, models and
estimation layers.

Modules, lowest first: ``candidates`` (candidate poses and their feasibility),
``identifiability`` (rank, null space, lost combinations by name), ``indices`` (O1–O5),
``accuracy`` (predicted covariances and pose errors), ``analysis`` (one pose set, all of it),
``criteria`` (optimality criteria and their rank-6 updates), ``selection`` (greedy and
exchange), ``pose_errors``, ``errormap`` and ``paper_claims`` (the seed paper's error maps).

>>> from hexcal.design import criterion_value
>>> criterion_value([[1.0, 0.0], [0.0, 1.0]], "A")
-2.0
"""

from hexcal._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "ANGLE_PAIRS": "errormap",
        "AngleMap": "errormap",
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
        "PoseSetAnalysis": "analysis",
        "SCALINGS": "indices",
        "SCORING_RIDGE": "criteria",
        "SCREEN_DIMENSIONS": "criteria",
        "SCREEN_SHORTLIST": "criteria",
        "SelectionResult": "selection",
        "analyse_poses": "analysis",
        "angle_grid_poses": "errormap",
        "boundary_grid": "candidates",
        "candidate_poses": "candidates",
        "check_criterion": "criteria",
        "check_feasibility": "candidates",
        "claims": "paper_claims",
        "column_scales": "indices",
        "criterion_value": "criteria",
        "describe_value": "criteria",
        "error_maps": "errormap",
        "exchange_selection": "selection",
        "format_claims": "paper_claims",
        "format_combination": "identifiability",
        "full_rank": "criteria",
        "greedy_selection": "selection",
        "indices_from_singular_values": "indices",
        "information_blocks": "criteria",
        "information_matrix": "criteria",
        "least_squares_covariance": "accuracy",
        "line_sweep_poses": "errormap",
        "mean_abs_error": "accuracy",
        "mean_pose_errors": "pose_errors",
        "null_space": "identifiability",
        "numerical_rank": "identifiability",
        "observability_indices": "indices",
        "parameter_error_draws": "pose_errors",
        "parameter_names": "accuracy",
        "planning_jacobian": "identifiability",
        "platform_radius": "candidates",
        "pose_error_map": "accuracy",
        "pose_error_samples": "pose_errors",
        "predicted_pose_errors": "accuracy",
        "random_subsets": "selection",
        "rotation_vector_map": "accuracy",
        "select_poses": "selection",
        "singularity_distance": "candidates",
        "unidentifiable_combinations": "identifiability",
    },
)
