"""Measurement models: what an instrument measures at a platform pose, the residuals
and their Jacobians with respect to the parameters and to the true pose, and their noise
covariance. Imports :mod:`hexcal.core`.
"""

from hexcal._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "ANGLE_SCALE": "setup",
        "FIXABLE": "setup",
        "FRAME_NAMES": "setup",
        "FramedModel": "targets",
        "FullPoseModel": "pose",
        "InstrumentValidation": "instrument_data",
        "MODELS": "registry",
        "MeasurementModel": "base",
        "Measurements": "pose",
        "POSE_SCALES": "setup",
        "Registration": "registration",
        "SETUP_KEYS": "setup",
        "Setup": "setup",
        "TARGET_NAME": "setup",
        "TOOL_AXIS_LENGTH": "registration",
        "TOOL_NAMES": "setup",
        "TargetMeasurements": "targets",
        "TargetModel": "targets",
        "ToolModel": "tool",
        "VARIANTS": "legs",
        "check_variant": "legs",
        "cross_axes": "targets",
        "fk_start_poses": "targets",
        "frame_transform": "setup",
        "instrument_model": "instrument_data",
        "leg_parameter_jacobian": "legs",
        "leg_residuals": "legs",
        "matrix_to_euler": "setup",
        "model_by_name": "registry",
        "pose_frames": "legs",
        "predict_instrument": "instrument_data",
        "register_frame": "registration",
        "rigid_fit": "registration",
        "rotation_vectors": "tool",
        "simulate_target_measurements": "instrument_data",
        "simulate_tool_measurements": "instrument_data",
        "transform_frame": "setup",
        "true_poses": "instrument_data",
        "validate_instrument": "instrument_data",
    },
)
