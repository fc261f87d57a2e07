"""Measurement models: what an instrument measures at a platform pose, the residuals
and their Jacobians with respect to the parameters and to the true pose, and their noise
covariance. Imports :mod:`hexcal.core`.
"""

from hexcal._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "FullPoseModel": "pose",
        "MODELS": "registry",
        "MeasurementModel": "base",
        "Measurements": "pose",
        "VARIANTS": "legs",
        "check_variant": "legs",
        "leg_parameter_jacobian": "legs",
        "leg_residuals": "legs",
        "model_by_name": "registry",
        "pose_frames": "legs",
    },
)
