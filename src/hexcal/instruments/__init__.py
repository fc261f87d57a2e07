"""Instruments: what an instrument measures at a platform pose (its parameters, the
residuals and their Jacobians with respect to the parameters and to the true pose, its noise
covariance, registration and simulation), the data it records and the sessions of a
campaign. Imports :mod:`hexcal.core`.

Public names
------------
- ``MeasurementModel``, ``FramedModel``, ``FullPoseModel``, ``ToolModel``, ``TargetModel``:
  the instruments (the platform pose in the base frame; a tool frame's pose or target
  positions in the instrument's own frame).
- ``BallbarModel``, ``BallbarSetup``, ``BallbarMeasurements``: the ballbar (one distance per
  pose between a base pivot and a platform ball; docs/ballbar.md), its setup and its data.
- ``MODELS``, ``instrument_for``, ``full_pose``, ``model_by_name``, ``register_instrument``:
  instruments by name; the instrument a setup describes.
- ``Setup``, ``SETUP_KEYS``, ``FIXABLE``, ``TARGET_NAME``: the instrument setup (docs/formats.md
  "Setup file"): instrument frame or auto, targets or tool, fixed quantities.
- ``Measurements``, ``TargetMeasurements``, ``Session``: the data an instrument records and
  a session (data and instrument; one machine, several sessions per calibration).
- ``Covariates``, ``COVARIATE_COLUMNS``: what the data carry beside the readings, per row
  (time, the legs' temperatures, the payload; docs/formats.md "Covariates").
- ``Registration``, ``register_targets``, ``register_pose_instrument``: an auto
  instrument frame registered from the data before the fit.

Other names of the lazy map below (frame transforms, scales, Jacobian helpers) are shared
with hexcal's other layers and are not part of the API.
"""

from hexcal._lazy import attach

_NAMES = {
    "BallbarMeasurements": "ballbar_setup",
    "BallbarModel": "ballbar",
    "BallbarSetup": "ballbar_setup",
    "COVARIATE_COLUMNS": "covariates",
    "Covariates": "covariates",
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
}

__all__ = [
    "COVARIATE_COLUMNS",
    "FIXABLE",
    "MODELS",
    "SETUP_KEYS",
    "TARGET_NAME",
    "BallbarMeasurements",
    "BallbarModel",
    "BallbarSetup",
    "Covariates",
    "FramedModel",
    "FullPoseModel",
    "MeasurementModel",
    "Measurements",
    "Registration",
    "Session",
    "Setup",
    "TargetMeasurements",
    "TargetModel",
    "ToolModel",
    "full_pose",
    "instrument_for",
    "model_by_name",
    "register_instrument",
    "register_pose_instrument",
    "register_targets",
]

__getattr__, _dir, _names = attach(__name__, _NAMES)


def __dir__() -> list[str]:
    return sorted(__all__)
