"""Estimation: the identification problem over sessions (:class:`Problem`, the one place that
maps solver variables to residuals), the estimators (a registry by name, one signature, one
result type), the gauge freedoms, the Cramér–Rao bound, the noise learned from the data,
outlier statistics and robust fitting, and the batched solvers of Monte Carlo studies.
Imports :mod:`hexcal.core` and :mod:`hexcal.instruments`; the entry point that adds the
verdict is :func:`hexcal.calibration.estimate`.

Public names
------------
- ``Problem``, ``IdentificationResult``: one identification (start geometry, sessions,
  parameters varied) and the outcome of one or of a batch.
- ``ESTIMATORS``, ``DEFAULT_ESTIMATOR``, ``Estimator``, ``register``, ``get_estimator``: the
  estimators by name (ml, gls, length, paper) and how to add one.
- ``identify_robust``, ``RobustResult``, ``pose_diagnostics``, ``PoseDiagnostics``,
  ``DEFAULT_ALPHA``: outlier statistics and fits without the outliers.
- ``estimate_noise``, ``NoiseEstimate``, ``NOISE_UNITS``, ``check_noise``, ``NoiseCheck``: the
  noise learned from the data, or a given noise tested against it.
- ``gauge_freedoms``, ``Gauge``: what no data can determine (an instrument in its own frame).
- ``cramer_rao``, ``fisher_information``, ``planned_measurements``, ``planned_session``: the
  Cramér–Rao bound and noise-free data of planned poses.
- ``estimate_batch``, ``BATCH_METHODS``: many simulated full-pose data sets identified at once
  (Monte Carlo studies), their result one over trials.

Other names of the lazy map below (the solvers' pieces: stacks, chunks, projections,
Jacobians, the gauge convention's algebra, the estimator functions behind the registry) are
shared with hexcal's other layers and are not part of the API.
"""

from hexcal._lazy import attach

_NAMES = {
    "BATCH_METHODS": "batched",
    "CONVENTION": "gauge",
    "DEFAULT_ALPHA": "outliers",
    "DEFAULT_ESTIMATOR": "registry",
    "ESTIMATORS": "registry",
    "Estimator": "registry",
    "GAUGE_LABELS": "gauge",
    "Gauge": "gauge",
    "GroupStatistics": "noise_estimation",
    "IdentificationResult": "result",
    "LEG_SIGMA_FLOOR": "equations",
    "MIN_REDUNDANCY": "noise_estimation",
    "NOISE_FLOORS": "noise_estimation",
    "NOISE_UNITS": "noise_estimation",
    "NoiseCheck": "noise_check",
    "NoiseEstimate": "noise_estimation",
    "POSE_VARIANCE_FLOOR": "equations",
    "Part": "problem",
    "PoseDiagnostics": "outliers",
    "PoseProjection": "likelihood",
    "Problem": "problem",
    "Projection": "likelihood",
    "RobustResult": "robust",
    "SCREEN_THRESHOLD": "outliers",
    "Stack": "stacked",
    "apply_convention": "gauge",
    "as_sessions": "problem",
    "bound_mean_abs_error": "uncertainty",
    "bound_stderr": "uncertainty",
    "check_noise": "noise_check",
    "complement_basis": "gauge",
    "cramer_rao": "uncertainty",
    "cramer_rao_covariance": "uncertainty",
    "estimate_batch": "batched",
    "estimate_noise": "noise_estimation",
    "estimate_stack": "batched",
    "finish_result": "covariance",
    "fisher_information": "uncertainty",
    "fit_gls": "gls",
    "fit_least_squares": "least_squares",
    "fit_length": "least_squares",
    "fit_ml": "likelihood",
    "fit_paper": "least_squares",
    "full_pose_stack": "batched",
    "gauge_fixed_covariance": "uncertainty",
    "gauge_freedoms": "gauge",
    "gauge_projector": "gauge",
    "get_estimator": "registry",
    "group_statistics": "noise_estimation",
    "identification_jacobian": "uncertainty",
    "identification_residuals": "uncertainty",
    "identify_chunk": "batched",
    "identify_robust": "robust",
    "information_blocks": "uncertainty",
    "information_rows": "uncertainty",
    "measurements_problem": "uncertainty",
    "planned_measurements": "uncertainty",
    "planned_session": "uncertainty",
    "pose_diagnostics": "outliers",
    "problem_parameters": "problem",
    "projected_jacobian": "uncertainty",
    "register": "registry",
    "residual_covariances": "uncertainty",
    "rms": "result",
    "screen_poses": "robust",
    "session_noises": "problem",
    "transform_parameters": "gauge",
    "unidentifiable": "gauge",
    "whitened_jacobian": "uncertainty",
}

__all__ = [
    "BATCH_METHODS",
    "DEFAULT_ALPHA",
    "DEFAULT_ESTIMATOR",
    "ESTIMATORS",
    "NOISE_UNITS",
    "Estimator",
    "Gauge",
    "IdentificationResult",
    "NoiseCheck",
    "NoiseEstimate",
    "PoseDiagnostics",
    "Problem",
    "RobustResult",
    "check_noise",
    "cramer_rao",
    "estimate_batch",
    "estimate_noise",
    "fisher_information",
    "gauge_freedoms",
    "get_estimator",
    "identify_robust",
    "planned_measurements",
    "planned_session",
    "pose_diagnostics",
    "register",
]

__getattr__, _dir, _names = attach(__name__, _NAMES)


def __dir__() -> list[str]:
    return sorted(__all__)
