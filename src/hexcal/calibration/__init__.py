"""Calibration: the one entry point of identification (``estimate``: registration, the fit,
the bound, the outlier check and the verdict), validation on held-out data, the predicted
accuracy (the one formula), the verdict and its diagnoses. Imports :mod:`hexcal.core`,
:mod:`hexcal.instruments` and :mod:`hexcal.estimation`.
"""

from hexcal._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "AUTO": "identify",
        "BETTER": "diagnosis",
        "EULER_SEQUENCES": "diagnosis",
        "FAIL_FACTOR": "verdict",
        "GROSS_FACTOR": "verdict",
        "MAX_CHANGE": "verdict",
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
        "predicted_pose_accuracy": "accuracy",
        "predicted_pose_errors": "accuracy",
        "register_sessions": "identify",
        "rotation_vector_map": "accuracy",
        "undetermined": "verdict",
        "validate": "validation",
    },
)
