"""Instruments: what an instrument measures at a platform pose (its parameters, the
residuals and their Jacobians with respect to the parameters and to the true pose, its noise
covariance, registration and simulation), the data it records and the sessions of a
campaign. Imports :mod:`hexcal.core`.
"""

from hexcal._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "ANGLE_SCALE": "setup",
        "FIXABLE": "setup",
        "FRAME_NAMES": "setup",
        "FramedModel": "framed",
        "FullPoseModel": "pose",
        "MODELS": "registry",
        "MeasurementModel": "base",
        "Measurements": "data",
        "POSE_SCALES": "setup",
        "Registration": "registration",
        "SETUP_KEYS": "setup",
        "Session": "base",
        "Setup": "setup",
        "TARGET_NAME": "setup",
        "TOOL_NAMES": "setup",
        "TargetMeasurements": "data",
        "TargetModel": "targets",
        "ToolModel": "pose",
        "cross_axes": "framed",
        "fk_start_poses": "framed",
        "frame_transform": "setup",
        "full_pose": "registry",
        "instrument_for": "registry",
        "matrix_to_euler": "setup",
        "model_by_name": "registry",
        "register_instrument": "registry",
        "register_pose_instrument": "registration",
        "register_targets": "registration",
        "rigid_fit": "registration",
        "rotation_vectors": "pose",
        "transform_frame": "setup",
    },
)
