"""Calibration: the one entry point of identification (``estimate``: registration, the fit,
the bound, the outlier check and the verdict), validation on held-out data, the predicted
accuracy (the one formula), the verdict and its diagnoses. Imports :mod:`hexcal.core`,
:mod:`hexcal.instruments` and :mod:`hexcal.estimation`.

Public names
------------
- ``estimate``, ``AUTO``: identify the machine (and each session's free instrument
  quantities) from one or several sessions; ``noise=AUTO`` learns the noise from the data.
- ``validate``, ``ValidationResult``: prediction errors of a calibration on held-out data.
- ``Verdict``, ``Reason``, ``SEVERITIES``, ``assess``, ``FAIL_FACTOR``, ``MAX_CHANGE``,
  ``SIGMA_LIMIT``, ``SIGMA_LIMITS``: the verdict (pass, warn or fail) and its reasons, as
  estimate attaches it to its result; its limits and defaults are in one module,
  hexcal.calibration.limits.
- ``group_references``, ``reference_noises``, ``noise_findings``: the learned noise held
  against what the instruments can do (model error), and the value a group the data cannot
  determine is held at.
- ``sequence_findings``, ``SequenceFinding``: steps (a bumped instrument) and drifts (warming
  legs) in each session's acquisition order; ``split_sessions``: a session split where its
  instrument moved.
- ``diagnose``, ``Quality``: the likely cause of a bad fit (degrees, gains, Euler sequence...).
- ``predicted_pose_accuracy``, ``predicted_pose_errors``, ``pose_error_map``: the predicted
  pose accuracy after calibration.
- ``poses_stroke_excess``, ``workspace_stroke_excess``: how far poses, or the workspace box,
  take legs beyond a stroke leg model's calibrated stroke (where it holds its curve).
- ``circular_test``, ``CircularTest``, ``pose_statistics``, ``PoseStatistics``,
  ``repeated_visits``: the ISO 230-4 circular test and the ISO 9283 pose accuracy and
  repeatability (docs/iso-tests.md); ``iso_validations``, ``IsoValidations``: the
  validations behind them, before and after calibration, the setup taken as each column needs
  it; ``circular_tests``, ``pose_tests``: the tests of those validations.

Other names of the lazy map below (limits, Jacobians and registration steps the verdict and
the planning layer share) are not part of the API.
"""

from hexcal._lazy import attach

_NAMES = {
    "AUTO": "identify",
    "BETTER": "diagnosis",
    "CircularTest": "iso_tests",
    "PoseStatistics": "iso_poses",
    "circular_test": "iso_tests",
    "circular_tests": "iso_validation",
    "IsoValidations": "iso_validation",
    "iso_validations": "iso_validation",
    "pose_statistics": "iso_poses",
    "pose_tests": "iso_validation",
    "repeated_visits": "iso_poses",
    "EULER_SEQUENCES": "diagnosis",
    "FAIL_FACTOR": "limits",
    "GROSS_FACTOR": "limits",
    "MAX_CHANGE": "limits",
    "SIGMA_LIMIT": "limits",
    "SequenceFinding": "sequence",
    "group_references": "noise_judgement",
    "noise_findings": "noise_judgement",
    "reference_noises": "noise_judgement",
    "sequence_findings": "sequence",
    "split_sessions": "splitting",
    "step_splits": "splitting",
    "Quality": "diagnosis",
    "Reason": "reasons",
    "SEVERITIES": "reasons",
    "SIGMA_LIMITS": "verdict",
    "ValidationResult": "validation",
    "Verdict": "reasons",
    "assess": "verdict",
    "change_limits": "verdict",
    "combination_name": "verdict",
    "diagnose": "diagnosis",
    "estimate": "identify",
    "instrument_poses": "validation",
    "machine_jacobian": "accuracy",
    "machine_size": "verdict",
    "parameter_limits": "verdict",
    "pose_error_map": "accuracy",
    "poses_stroke_excess": "accuracy",
    "predicted_pose_accuracy": "accuracy",
    "predicted_pose_errors": "accuracy",
    "register_sessions": "identify",
    "rotation_vector_map": "accuracy",
    "undetermined": "verdict",
    "validate": "validation",
    "workspace_stroke_excess": "accuracy",
}

__all__ = [
    "AUTO",
    "FAIL_FACTOR",
    "MAX_CHANGE",
    "SEVERITIES",
    "SIGMA_LIMIT",
    "SIGMA_LIMITS",
    "CircularTest",
    "IsoValidations",
    "PoseStatistics",
    "Quality",
    "Reason",
    "SequenceFinding",
    "ValidationResult",
    "Verdict",
    "assess",
    "circular_test",
    "circular_tests",
    "diagnose",
    "estimate",
    "group_references",
    "iso_validations",
    "noise_findings",
    "pose_error_map",
    "pose_statistics",
    "pose_tests",
    "poses_stroke_excess",
    "predicted_pose_accuracy",
    "predicted_pose_errors",
    "reference_noises",
    "repeated_visits",
    "sequence_findings",
    "split_sessions",
    "validate",
    "workspace_stroke_excess",
]

__getattr__, _dir, _names = attach(__name__, _NAMES)


def __dir__() -> list[str]:
    return sorted(__all__)
