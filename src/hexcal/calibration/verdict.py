"""The verdict of an identification: ``pass``, ``warn`` or ``fail``, with its reasons.

:func:`assess` judges a fit on five counts and names the likely cause of a bad one
(:mod:`hexcal.calibration.diagnosis`):

- **noise consistency**: the reduced chi-square against its χ² range for the degrees of
  freedom (a given noise model), the per-group test of a given noise
  (:func:`hexcal.estimation.noise_estimation.check_noise`), the convergence of the
  variance components (an estimated noise);
- **identifiability, statistically**: every parameter combination whose predicted σ (from
  the covariance of the fit, parameters in units of :data:`SIGMA_LIMITS`) exceeds its limit
  is poorly determined (``warn``), beyond :data:`FAIL_FACTOR` times it not determined by
  these data (``fail``), named;
- **plausibility**: a change larger than :data:`MAX_CHANGE` of the machine's size (base
  radius for ``u``, platform radius for ``s``, the larger for ``l0``; a gain change larger
  than :data:`MAX_CHANGE` itself) is ``fail``;
- **gross outliers**: observations whose residuals under a robust soft-L1 fit
  (:func:`hexcal.estimation.outliers.screen_poses`) exceed :data:`SCREEN_THRESHOLD` robust
  σ (``warn``), or :data:`GROSS_FACTOR` times that (``fail``), named by id;
- **predicted accuracy**: the position and orientation RMS error over the workspace after
  calibration, from the parameter covariance (the one formula of
  :func:`hexcal.calibration.accuracy.predicted_pose_accuracy`; ``info``), and of what each
  instrument in its own frame reads, in its own terms (target distances, tool position and
  angle: :func:`hexcal.calibration.accuracy.predicted_instrument_accuracy`; ``info``).

The same judgement holds for every instrument: the limits are per kind of parameter (lengths
in mm, angles in rad, gains relative to their nominal value), and an instrument's frame, which
the data register from anywhere, has no plausibility limit. A ``fail`` means the calibrated
geometry should not be used (the CLI writes it only with ``--force``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.calibration.accuracy import predicted_pose_accuracy
from hexcal.calibration.accuracy_reasons import accuracy_findings
from hexcal.calibration.diagnosis import likely_cause_first
from hexcal.calibration.limits import (
    FAIL_FACTOR,
    GROSS_FACTOR,
    MAX_CHANGE,
    SCREEN_THRESHOLD,
    SEQUENCE_ALPHA,
    SIGMA_LIMIT,
)
from hexcal.calibration.noise_judgement import noise_findings
from hexcal.calibration.reasons import Reason, Verdict
from hexcal.calibration.sequence import sequence_reasons
from hexcal.calibration.stroke_structure import stroke_findings
from hexcal.core.geometry import Geometry
from hexcal.errors import HexcalError, UsageError

#: Default limits of the predicted σ of a parameter combination (per unit of the
#: normalised combination): 1 mm for lengths, 1e-3 (relative) for gains, 1e-3 rad for an
#: instrument's angles. ``assess(sigma_limit=k)`` scales them by ``k``.
SIGMA_LIMITS = {"length": 1.0, "gain": 1e-3, "angle": 1e-3}

#: Names of instrument angles (frame and tool orientation).
_ANGLE_SUFFIXES = (".a", ".b", ".c")


def combination_name(vector: NDArray[np.float64], names: tuple[str, ...], top: int = 4) -> str:
    """Readable form of a unit parameter combination (its largest components)."""
    order = np.argsort(-np.abs(vector))[:top]
    return " ".join(f"{vector[k]:+.2f}·{names[k]}" for k in order if abs(vector[k]) > 0.05)


def _local(name: str) -> str:
    """A parameter name without its session prefix (``session2.frame.x`` -> ``frame.x``)."""
    return name.split(".", 1)[1] if name.startswith("session") and "." in name else name


def _kind(name: str) -> str:
    """``gain``, ``angle`` or ``length``: the unit of a parameter's limits."""
    local = _local(name)
    if local.startswith("g") and local[1:].isdigit():
        return "gain"
    if local.startswith(("frame.", "tool.")) and local.endswith(_ANGLE_SUFFIXES):
        return "angle"
    return "length"


def parameter_limits(
    names: tuple[str, ...], sigma_limit: float = 1.0, values: NDArray[np.float64] | None = None
) -> NDArray[np.float64]:
    """The σ limit of each named parameter (mm, rad, or relative to the gain's ``values``)."""
    out = []
    for k, n in enumerate(names):
        kind = _kind(n)
        limit = SIGMA_LIMITS[kind] * sigma_limit
        if kind == "gain" and values is not None and values[k] != 0:
            limit *= abs(float(values[k]))
        out.append(limit)
    return np.array(out)


def undetermined(
    covariance: NDArray[np.float64],
    names: tuple[str, ...],
    sigma_limit: float = 1.0,
    values: NDArray[np.float64] | None = None,
) -> list[tuple[float, str]]:
    """Parameter combinations whose predicted σ exceeds the limit: ``[(σ, name), ...]``, worst
    first (σ in units of the limits)."""
    d = parameter_limits(names, sigma_limit, values)
    cov = covariance / np.outer(d, d)
    vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
    sig = np.sqrt(np.maximum(vals, 0.0))
    bad = np.flatnonzero(~(sig <= 1.0))[::-1]
    return [(float(sig[k]), combination_name(vecs[:, k], names)) for k in bad]


def limit_scale(geometry: Geometry, fraction: float | None = None) -> float:
    """The scale of :data:`SIGMA_LIMITS` (mm per unit) of a ``fraction`` of the platform radius
    (default :data:`SIGMA_LIMIT`)."""
    fraction = SIGMA_LIMIT if fraction is None else fraction
    if not fraction > 0:
        raise UsageError(f"sigma_limit must be > 0, got {fraction}")
    return fraction * machine_size(geometry)[1]


def machine_size(geometry: Geometry) -> tuple[float, float]:
    """Base and platform radius (mm): the largest joint distance from the frame's z axis."""
    rb = float(np.max(np.linalg.norm(geometry.base_joints[:, :2], axis=1)))
    rp = float(np.max(np.linalg.norm(geometry.platform_joints[:, :2], axis=1)))
    return rb, rp


def change_limits(
    geometry: Geometry,
    names: tuple[str, ...],
    fraction: float = MAX_CHANGE,
    values: NDArray[np.float64] | None = None,
) -> NDArray:
    """Largest plausible change of each named parameter: a fraction of the base radius for
    ``u``, of the platform radius for ``s`` and for what an instrument sees on the platform
    (a tool, targets), of the larger for the leg model's lengths, of the gain itself for a
    gain; none (inf) for an instrument's frame and angles, which the data register from
    anywhere."""
    rb, rp = machine_size(geometry)
    out = []
    for k, n in enumerate(names):
        local, kind = _local(n), _kind(n)
        if local.startswith("frame.") or kind == "angle":
            out.append(np.inf)
        elif kind == "gain":
            out.append(fraction * (abs(float(values[k])) if values is not None else 1.0))
        elif local.startswith("u"):
            out.append(fraction * rb)
        elif local.startswith(("s", "tool.", "t")):
            out.append(fraction * rp)
        else:
            out.append(fraction * max(rb, rp))
    return np.array(out)


def _chi_square_reasons(result: Any, alpha: float) -> list[Reason]:
    from scipy.special import chdtri

    dof, red = result.dof, result.reduced_chi2
    if result.method not in ("ml", "gls") or dof <= 0 or not np.isfinite(red):
        return []
    lo, hi = chdtri(dof, 1 - alpha / 2) / dof, chdtri(dof, alpha / 2) / dof
    data = {"reduced_chi_square": red, "range": [lo, hi], "dof": dof}
    if lo <= red <= hi:
        text = f"reduced chi-square {red:.3g} within [{lo:.3g}, {hi:.3g}]"
        return [Reason("chi-square", "info", text, data)]
    return [
        Reason(
            "chi-square",
            "warn",
            f"reduced chi-square {red:.4g} outside [{lo:.3g}, {hi:.3g}] for {dof} degrees of "
            "freedom: the noise model does not fit the data",
            data,
        )
    ]


def assess(
    result: Any,
    problem: Any = None,
    *,
    noise_estimate: Any = None,
    noise_check: Any = None,
    sigma_limit: float = 1.0,
    max_change: float = MAX_CHANGE,
    alpha: float = 0.01,
    robust: bool = False,
    diagnose: Any = None,
    accuracy: bool = True,
    noise: Any = None,
    reference: NDArray[np.float64] | None = None,
    sequence: bool = True,
    alpha_sequence: float = SEQUENCE_ALPHA,
) -> Verdict:
    """The verdict of an identification (module docstring).

    Parameters
    ----------
    result : IdentificationResult
    problem : Problem, optional
        The data fitted: needed for the outlier screening.
    noise_estimate : NoiseEstimate, optional
        The noise learned from the data (``noise="auto"``).
    noise_check : NoiseCheck, optional
        The given noise tested against the data.
    sigma_limit : float
        Scale of :data:`SIGMA_LIMITS` (a combination with a larger predicted σ is undetermined).
    max_change : float
        Largest plausible change as a fraction of the machine's size.
    alpha : float
        Level of the statistical tests.
    robust : bool
        The fit left outliers out already (the screening then only reports).
    diagnose : callable, optional
        ``diagnose(bad) -> list of Reason``: the likely causes of a bad fit found by refitting
        variants (:func:`hexcal.calibration.diagnosis.diagnose`).
    accuracy : bool
        Compute the predicted pose accuracy over the workspace.
    noise : NoiseModel or sequence, optional
        The noise the screening of instruments that do not give the pose whitens with.
    reference : ndarray, optional
        The values changes are measured from (the setups as given, before registration);
        default the start values.
    sequence : bool
        Look for steps and drifts in each session's acquisition order
        (:mod:`hexcal.calibration.sequence`).
    alpha_sequence : float
        Level of that test, per session.
    """
    reasons: list[Reason] = []
    reasons += _chi_square_reasons(result, alpha) if noise_estimate is None else []
    instruments = [p.instrument for p in problem.parts] if problem is not None else []
    reasons += noise_findings(noise_estimate, noise_check, instruments)
    names = result.names
    start_values = np.asarray(result.start_values)
    for sig, combo in undetermined(result.covariance, names, sigma_limit, start_values)[:5]:
        severity = "fail" if sig > FAIL_FACTOR else "warn"
        reasons.append(
            Reason(
                "undetermined" if severity == "fail" else "weakly-determined",
                severity,
                f"{'not' if severity == 'fail' else 'poorly'} determined by these data: {combo} "
                f"(predicted σ {sig:.3g} × the limit of {sigma_limit:g} mm, "
                f"{sigma_limit * 1e-3:g} relative for gains, {sigma_limit * 1e-3:g} rad for angles)",
                {"combination": combo, "sigma_over_limit": sig},
            )
        )
    change = np.asarray(result.values) - (start_values if reference is None else reference)
    limits = change_limits(result.start, names, max_change, start_values)
    over = np.flatnonzero(np.abs(change) > limits)
    if over.size:
        worst = over[np.argsort(-np.abs(change[over]) / limits[over])][:4]
        listed = ", ".join(f"{names[k]} {change[k]:+.4g}" for k in worst)
        reasons.append(
            Reason(
                "implausible-change",
                "fail",
                f"{over.size} parameter(s) changed beyond {max_change:.0%} of the machine's size: {listed}",
                {"parameters": [names[k] for k in over]},
            )
        )
    if result.outliers:
        text = f"poses left out as outliers: {', '.join(result.outliers)}"
        reasons.append(Reason("outliers-removed", "info", text))
    if result.flagged:
        text = f"poses with implausible residuals: {', '.join(result.flagged)}"
        reasons.append(Reason("flagged", "warn", text))
    outlying: list[int] = []
    if problem is not None and not robust:
        found, outlying = _outlier_reasons(result, problem, noise)
        reasons += found
    if problem is not None and sequence:
        reasons += sequence_reasons(problem, result, noise, outlying, alpha=alpha_sequence)
    acc = None
    if accuracy:
        acc, found = accuracy_findings(result, problem, noise, names)
        reasons += found
    reasons += [Reason(*finding) for finding in stroke_findings(result, problem)]
    verdict = Verdict(tuple(reasons), acc)
    if diagnose is not None:
        extra = diagnose(verdict.status == "fail")
        # the likely cause (radians in degree columns, swapped columns) before its consequences
        verdict = Verdict(tuple(likely_cause_first([*reasons, *extra])), acc)
    return verdict


def _outlier_reasons(result: Any, problem: Any, noise: Any) -> tuple[list[Reason], list[int]]:
    """The outlier screen's reasons, and the observations beyond its threshold (by row)."""
    from hexcal.estimation.robust import screen_poses

    if len(problem) != result.n_poses:
        return [], []
    try:
        scores = screen_poses(result.start, problem=problem, noise=noise, studentized=True)
        # a gross error drags the least-squares-like studentized fit towards itself: the plain
        # screen's score (soft L1, bounded influence) decides a fail too; its false alarms of
        # small campaigns lie near the warning threshold, far below a gross error's
        plain = screen_poses(result.start, problem=problem, noise=noise)
    except (HexcalError, ValueError, np.linalg.LinAlgError):  # the screening is advisory
        return [], []
    out = []
    gross = SCREEN_THRESHOLD * GROSS_FACTOR
    scores = np.where(plain > gross, np.maximum(scores, plain), scores)
    ids = problem.ids
    for sev, lo, hi in (("fail", gross, np.inf), ("warn", SCREEN_THRESHOLD, gross)):
        idx = np.flatnonzero((scores > lo) & (scores <= hi))
        if idx.size:
            idx = idx[np.argsort(-scores[idx])]
            listed = ", ".join(f"{ids[k]} ({scores[k]:.0f} σ)" for k in idx[:10])
            out.append(
                Reason(
                    "gross-outlier" if sev == "fail" else "outlier",
                    sev,
                    f"pose(s) with residuals far beyond the robust scale: {listed}; "
                    "check them or fit with --robust",
                    {"poses": [ids[k] for k in idx]},
                )
            )
    return out, np.flatnonzero(scores > SCREEN_THRESHOLD).tolist()


__all__ = ["Reason", "Verdict", "assess", "predicted_pose_accuracy", "undetermined"]
