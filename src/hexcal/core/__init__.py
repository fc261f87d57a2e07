"""The foundation: conventions, geometry, parameters, kinematics, workspace, noise, the
linear-algebra rule and the presets. Imports numpy (scipy only where deferred) and
:mod:`hexcal.errors`; never a higher layer.

Public names
------------
- ``Geometry``, ``preset``, ``PRESETS``: the machine (joints, leg model, limits, workspace;
  docs/formats.md "Geometry file") and the built-in geometries by name.
- ``POSE_NAMES``, ``DEFAULT_EULER``, ``N_LEGS``, ``check_euler``, ``rotation_matrices``,
  ``orientation_error``: the pose convention ``(x, y, z, a, b, c)``, mm and rad, angles in a
  scipy Euler sequence (default XYZ, docs/formats.md "Conventions").
- ``Parameter``, ``ParameterSet``, ``PARAMETER_NAMES``, ``PARAMETER_GROUPS``, ``DEFAULT_FIT``,
  ``MIN_POSES``, ``N_BASE_PARAMETERS``, ``N_ALL_PARAMETERS``, ``parameter_names``,
  ``select_parameters``: the machine's named parameters and which of them a fit varies.
- ``inverse_kinematics``, ``forward_kinematics``, ``ForwardResult``, ``FK_TOLERANCE``,
  ``leg_lengths``, ``leg_readings``, ``leg_vectors``, ``pose_jacobian``, ``pose_errors``:
  kinematics (leg lengths of poses and back, readings and lengths through the leg model).
- ``LegModel``, ``LinearLegs``, ``StrokeLegs``, ``LEG_MODELS``, ``register_leg_model``,
  ``leg_model_from_dict``: leg models (docs/leg-models.md).
- ``stroke_excess``, ``StrokeExcess``, ``STROKE_MARGIN``: how far readings go beyond each leg's
  calibrated stroke (where a stroke model holds its curve), and the margin commands warn beyond.
- ``workspace_box``, ``workspace_corners``, ``box_corners``, ``random_poses``,
  ``random_interior``, ``is_feasible``, ``leg_limit_violations``, ``LEG_LIMIT_MARGIN``: the
  workspace box and the leg length limits.
- ``NoiseModel``: measurement noise (leg sensor, position, orientation).
- ``compensate``, ``Compensation``, ``correct_poses``, ``correct_path``, ``CorrectedPath``,
  ``PathError``: leg commands and corrected targets or paths for a calibrated machine.

Other names of the lazy map below (the linear-algebra rule, batched kinematics on arrays,
rotation layouts) are shared with hexcal's other layers and are not part of the API.
"""

from hexcal._lazy import attach

_NAMES = {
    "Compensation": "compensation",
    "CorrectedPath": "path_compensation",
    "DEFAULT_EULER": "conventions",
    "DEFAULT_FIT": "parameters",
    "FK_TOLERANCE": "kinematics",
    "ForwardResult": "kinematics",
    "Geometry": "geometry",
    "JOINT_SEPARATION": "geometry",
    "LEG_LIMIT_MARGIN": "workspace",
    "LEG_MODELS": "legs",
    "LegModel": "legs",
    "LinearLegs": "legs",
    "StrokeLegs": "stroke_legs",
    "STROKE_MARGIN": "stroke_legs",
    "StrokeExcess": "stroke_legs",
    "stroke_excess": "stroke_legs",
    "stroke_of": "stroke_legs",
    "with_leg_model": "stroke_legs",
    "MIN_POSES": "parameters",
    "Moves": "path_compensation",
    "N_ALL_PARAMETERS": "parameters",
    "N_BASE_PARAMETERS": "parameters",
    "N_LEGS": "conventions",
    "NoiseModel": "noise",
    "PARAMETER_GROUPS": "parameters",
    "PARAMETER_LEG": "parameters",
    "PARAMETER_NAMES": "parameters",
    "PARAMETER_SCALE": "parameters",
    "POSE_NAMES": "conventions",
    "PRESETS": "presets",
    "Parameter": "parameters",
    "ParameterSet": "parameters",
    "PathError": "path_compensation",
    "RANK_RTOL": "linalg",
    "ScaledSVD": "linalg",
    "as_box": "workspace",
    "as_poses": "conventions",
    "box_corners": "workspace",
    "check_euler": "conventions",
    "column_norms": "linalg",
    "compensate": "compensation",
    "correct_path": "path_compensation",
    "correct_poses": "path_compensation",
    "euler_axes": "conventions",
    "floored_whitener": "linalg",
    "forward_kinematics": "kinematics",
    "forward_kinematics_from_arrays": "kinematics",
    "gram_pinv": "linalg",
    "gram_pinv_diagonal": "linalg",
    "inverse_kinematics": "kinematics",
    "is_feasible": "workspace",
    "leg_lengths": "kinematics",
    "leg_model_from_dict": "legs",
    "leg_limit_violations": "workspace",
    "leg_readings": "kinematics",
    "leg_vectors": "kinematics",
    "leg_vectors_from_arrays": "kinematics",
    "null_space": "linalg",
    "numerical_rank": "linalg",
    "orientation_deviation": "path_compensation",
    "orientation_error": "conventions",
    "parameter_names": "parameters",
    "path_points": "path_compensation",
    "pose_errors": "kinematics",
    "pose_jacobian": "kinematics",
    "pose_jacobian_from_arrays": "kinematics",
    "preset": "presets",
    "random_interior": "workspace",
    "random_poses": "workspace",
    "reached_poses": "path_compensation",
    "register_leg_model": "legs",
    "repr_key": "geometry_mapping",
    "rotate_points": "kinematics",
    "rotation_and_axes_t": "conventions",
    "rotation_matrices": "conventions",
    "rotation_matrices_t": "conventions",
    "scaled_svd": "linalg",
    "select_parameters": "parameters",
    "whitening": "linalg",
    "workspace_box": "workspace",
    "workspace_corners": "workspace",
}

__all__ = [
    "DEFAULT_EULER",
    "DEFAULT_FIT",
    "FK_TOLERANCE",
    "LEG_LIMIT_MARGIN",
    "LEG_MODELS",
    "MIN_POSES",
    "N_ALL_PARAMETERS",
    "N_BASE_PARAMETERS",
    "N_LEGS",
    "PARAMETER_GROUPS",
    "PARAMETER_NAMES",
    "POSE_NAMES",
    "PRESETS",
    "STROKE_MARGIN",
    "Compensation",
    "CorrectedPath",
    "ForwardResult",
    "Geometry",
    "LegModel",
    "LinearLegs",
    "NoiseModel",
    "Parameter",
    "ParameterSet",
    "PathError",
    "StrokeExcess",
    "StrokeLegs",
    "box_corners",
    "check_euler",
    "compensate",
    "correct_path",
    "correct_poses",
    "forward_kinematics",
    "inverse_kinematics",
    "is_feasible",
    "leg_lengths",
    "leg_limit_violations",
    "leg_model_from_dict",
    "leg_readings",
    "leg_vectors",
    "orientation_error",
    "parameter_names",
    "pose_errors",
    "pose_jacobian",
    "preset",
    "random_interior",
    "random_poses",
    "register_leg_model",
    "rotation_matrices",
    "select_parameters",
    "stroke_excess",
    "workspace_box",
    "workspace_corners",
]

__getattr__, _dir, _names = attach(__name__, _NAMES)


def __dir__() -> list[str]:
    return sorted(__all__)
