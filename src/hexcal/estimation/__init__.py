"""Estimators (a registry by name, one signature, one result type), the Fisher
information and Cramér–Rao bound, robust fitting and validation on held-out data. Imports
:mod:`hexcal.core` and :mod:`hexcal.models`.
"""

from hexcal._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "Compensation": "validation",
        "DEFAULT_ALPHA": "robust",
        "ESTIMATORS": "likelihood",
        "IdentificationResult": "identification",
        "LEG_SIGMA_FLOOR": "likelihood",
        "MAX_LEVERAGE": "robust",
        "METHODS": "identification",
        "POSE_VARIANCE_FLOOR": "likelihood",
        "PoseDiagnostics": "robust",
        "RobustResult": "robust",
        "SCREEN_THRESHOLD": "robust",
        "ValidationResult": "validation",
        "bound_mean_abs_error": "bounds",
        "bound_stderr": "likelihood",
        "check_data_size": "identification",
        "check_rank": "identification",
        "compensate": "validation",
        "cramer_rao_covariance": "bounds",
        "estimate": "likelihood",
        "finish_result": "identification",
        "fisher_information": "bounds",
        "identification_jacobian": "identification",
        "identification_residuals": "identification",
        "identify": "identification",
        "identify_gls": "likelihood",
        "identify_ml": "likelihood",
        "identify_robust": "robust",
        "parameter_unpacker": "identification",
        "planned_measurements": "bounds",
        "pose_diagnostics": "robust",
        "residual_covariances": "bounds",
        "screen_poses": "robust",
        "validate": "validation",
        "whitened_jacobian": "bounds",
        "whitening": "bounds",
    },
)
