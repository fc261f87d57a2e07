"""The verdict's findings on accuracy: what the calibration predicts, as platform pose error
over the workspace, in each instrument's own terms, and as what ``validate`` should measure on a
new session (``info`` reasons of :func:`hexcal.calibration.verdict.assess`).

The formulas are :mod:`hexcal.calibration.accuracy`'s; this module picks the machine's block of
the fit's covariance and words the reasons.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.calibration.accuracy import (
    accuracy_geometry,
    expected_validation,
    machine_mask,
    predicted_instrument_accuracy,
    predicted_pose_accuracy,
)
from hexcal.calibration.reasons import Reason


def accuracy_findings(
    result: Any, problem: Any, noise: Any, names: tuple[str, ...]
) -> tuple[dict[str, Any] | None, list[Reason]]:
    """The predicted accuracy of a fit (None when its machine covariance is not finite) and
    its reasons: over the workspace, the expected validation (with ``noise``) and each
    instrument's own errors (with the sessions of ``problem``, when given)."""
    machine = set(result.start.machine_names())
    rows = np.array([n in machine for n in names])
    if not rows.any() or not np.all(np.isfinite(result.covariance[np.ix_(rows, rows)])):
        return None, []
    cov = result.covariance[np.ix_(rows, rows)]
    rigid = None if result.gauge_directions is None else result.gauge_directions[rows]
    mask = machine_mask(result.geometry, names=names)
    # over the workspace box, or the calibration poses' range where the geometry has none
    poses = None if problem is None or result.poses is not None else problem.measured_poses()
    geometry, where = accuracy_geometry(result.geometry, result.poses if poses is None else poses)
    acc = predicted_pose_accuracy(geometry, cov, mask, rigid=rigid) | {"over": where}
    reasons = [
        Reason(
            "predicted-accuracy",
            "info",
            f"predicted pose error after calibration over {where}{_rigid_note(rigid)}: "
            f"position RMS "
            f"{acc['position_rms_mm']:.3g} mm (worst {acc['position_max_mm']:.3g}), orientation RMS "
            f"{acc['orientation_rms_rad']:.3g} rad (worst {acc['orientation_max_rad']:.3g})"
            f"{_beyond_note(acc.get('beyond_stroke'))}",
            acc,
        )
    ]
    if problem is not None and noise is not None:
        acc["validation"] = _expected_validation(result, problem, noise, cov, mask, rigid)
        reasons.append(_validation_reason(acc["validation"]))
    if problem is not None:
        acc["instrument"] = _instrument_accuracy(result, problem, mask, geometry)
        reasons += [_instrument_reason(entry) for entry in acc["instrument"] if entry["own_frame"]]
    return acc, reasons


def _expected_validation(
    result: Any, problem: Any, noise: Any, cov: Any, mask: Any, rigid: Any
) -> dict[str, Any]:
    """:func:`~hexcal.calibration.accuracy.expected_validation` at the sessions' poses (the
    estimated true poses, else the measured ones) with their calibrated instruments."""
    from hexcal.estimation.likelihood import session_noises

    poses = result.poses if result.poses is not None else problem.measured_poses()
    noises = session_noises(problem, noise)
    instruments = result.instruments or tuple(p.instrument for p in problem.parts)
    sessions = [
        (inst, poses[part.rows], n) for part, inst, n in zip(problem.parts, instruments, noises, strict=True)
    ]
    return expected_validation(result.geometry, cov, sessions, mask, rigid)


def _validation_reason(expected: dict[str, Any]) -> Reason:
    own = expected["from_parameters"]
    if not np.isfinite(expected["position_rms_mm"]):  # a ballbar, one target: no pose to compare
        return Reason(
            "expected-validation",
            "info",
            f"expected from validate on a new session: no platform pose error (the instrument's "
            f"values do not give the pose; validate compares them in its own terms); the "
            f"parameters' part: {own['position_rms_mm']:.3g} mm, {own['orientation_rms_rad']:.3g} rad, "
            f"leg RMS {own['leg_rms_mm']:.3g} mm",
            expected,
        )
    return Reason(
        "expected-validation",
        "info",
        f"expected from validate on a new session at such poses (noise included, frames "
        f"re-registered): position RMS {expected['position_rms_mm']:.3g} mm, orientation RMS "
        f"{expected['orientation_rms_rad']:.3g} rad, leg RMS {expected['leg_rms_mm']:.3g} mm "
        f"(the parameters' part: {own['position_rms_mm']:.3g} mm, {own['orientation_rms_rad']:.3g} rad, "
        f"{own['leg_rms_mm']:.3g} mm)",
        expected,
    )


def _instrument_accuracy(result: Any, problem: Any, mask: NDArray, geometry: Any) -> list[dict[str, Any]]:
    """The predicted accuracy of what each session's instrument reads, in its own terms
    (:func:`hexcal.calibration.accuracy.predicted_instrument_accuracy`), per session."""
    if len(result.names) != problem.n_free:
        return []
    full = np.array(problem.full0)
    full[problem.mask] = result.values
    machine = problem.free_in(problem.machine)
    out = []
    for part in problem.parts:
        own = problem.free_in(part.block)
        rows = machine | own
        acc = predicted_instrument_accuracy(
            geometry,
            part.instrument,
            full[part.block],
            result.covariance[np.ix_(rows, rows)],
            mask,
            problem.mask[part.block],
        )
        own_frame = not part.instrument.constant_pose_jacobian  # not the platform pose itself
        out.append(
            {"session": part.label, "instrument": part.instrument.describe(), "own_frame": own_frame} | acc
        )
    return out


def _instrument_reason(entry: dict[str, Any]) -> Reason:
    values = [
        f"{key.split('_rms_')[0]} RMS {value:.3g} {key.split('_rms_')[1]} "
        f"(worst {entry[key.replace('_rms_', '_max_')]:.3g})"
        for key, value in entry.items()
        if "_rms_" in key
    ]
    return Reason(
        "predicted-instrument-accuracy",
        "info",
        f"predicted error of what the instrument reads after calibration ({entry['session']}): "
        + ", ".join(values),
        entry,
    )


def _beyond_note(beyond: dict[str, Any] | None) -> str:
    """How much of the prediction lies beyond the calibrated stroke (empty when none does)."""
    if not beyond or not beyond["beyond_rows"]:
        return ""
    return (
        f"; {beyond['beyond_share']:.0%} of its {beyond['rows']} test poses take a leg beyond the "
        f"calibrated stroke (by up to {beyond['largest_share_of_stroke']:.0%} of it, "
        f"{beyond['largest_mm']:.3g} mm), predicted there with the model's curve held"
    )


def _rigid_note(rigid: Any) -> str:
    return "" if rigid is None else " (up to the frames, re-registered as validate does)"
