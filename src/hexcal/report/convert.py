"""Results as plain dictionaries (JSON-ready), the input of every renderer.

Each ``<thing>_dict(result)`` turns a result object of a lower layer into the mapping that
the text, JSON and figure renderers read; where the JSON file of a command is that mapping,
its keys are exactly those of the file. Floats may be NaN or infinite here: the JSON
renderer writes them as ``null``. Imports numpy and the layers below (the names of parameter
combinations from :mod:`hexcal.calibration.verdict`), by duck typing on the results' attributes.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hexcal.calibration.verdict import combination_name


def identification_dict(
    result: Any, outliers: tuple[str, ...] = (), flagged: tuple[str, ...] = ()
) -> dict[str, Any]:
    """Machine-readable form of an identification (the ``hexcal identify --json`` file).

    ``result`` is an :class:`hexcal.estimation.IdentificationResult`. The keys of
    ``result.to_dict()`` (``verdict``, ``reasons``, ``parameters``, ``stderr``, ``bound``,
    ``reduced_chi_square``, ``noise`` as standard deviations with its ``source``, ``rank``,
    ``outliers``...; lengths in mm, angles in rad), after the identification's summary
    (``method``, ``poses``, ``parameters``, ``start``), plus ``noise_implied``: the
    instrument noise the estimated noise implies (σ and uniform half-widths, or None).
    """
    full = result.to_dict()
    out = {k: full[k] for k in ("method", "poses", "parameters", "start")}
    out |= {k: v for k, v in full.items() if k not in out}
    out["outliers"], out["flagged"] = list(outliers or full["outliers"]), list(flagged or full["flagged"])
    out["noise_implied"] = implied_noise(full["noise"])
    return out


def implied_noise(noise: dict[str, Any] | None) -> dict[str, Any] | None:
    """The instrument noise an estimated noise model implies: σ, uniform half-widths
    (σ·√3) and the ``--noise`` option that gives it (None for a given noise).

    >>> implied_noise({"leg": 0.01, "position": 0.1, "orientation": 0.001, "source": "estimated"})["option"]
    '--noise leg=0.01,pos=0.1,ang=0.001 --noise-dist normal'
    """
    if not noise or noise.get("source") != "estimated":
        return None
    keys = {"leg": "leg", "position": "pos", "orientation": "ang"}
    sigma = {k: float(noise[k]) for k in keys}
    option = ",".join(f"{keys[k]}={v:.3g}" for k, v in sigma.items())
    return {
        "sigma": sigma,
        "stderr": noise.get("stderr"),
        "uniform_half_width": {k: v * 3**0.5 for k, v in sigma.items()},
        "option": f"--noise {option} --noise-dist normal",
    }


def _weak_combinations(result: Any, count: int = 3) -> list[list[Any]]:
    """The smallest scaled singular values (relative to the largest) and the parameter
    combinations they belong to, named by the library's :func:`combination_name`."""
    sv = result.singular_values
    return [
        [float(sv[-1 - k] / sv[0]), combination_name(result.singular_vectors[-1 - k], tuple(result.names))]
        for k in range(min(count, sv.size))
    ]


def identification_report_dict(
    result: Any,
    outliers: tuple[str, ...] = (),
    flagged: tuple[str, ...] = (),
    max_correlations: int = 10,
) -> dict[str, Any]:
    """:func:`identification_dict` with what the text report adds.

    Extra keys: ``dof``, ``reduced_chi2``, ``noise_text`` (the noise model's description,
    or None),
    ``stderr_values`` and ``bound`` (lists in the order of ``parameters``; ``bound`` None
    without a noise model), ``correlations`` (the ``max_correlations`` strongest pairs
    ``[name, name, value]``) and ``weak`` (``[σ/σmax, combination]`` of the three
    smallest scaled singular values).
    """
    n = len(result.names)
    corr = result.correlation
    iu = np.triu_indices(n, 1)
    strong = np.argsort(-np.abs(corr[iu]))[:max_correlations]
    correlations = [
        [result.names[iu[0][k]], result.names[iu[1][k]], float(corr[iu[0][k], iu[1][k]])] for k in strong
    ]
    return {
        **identification_dict(result, outliers, flagged),
        "dof": result.dof,
        "reduced_chi2": float(result.reduced_chi2),
        "noise_text": None if result.noise is None else result.noise.describe(),
        "max_correlations": max_correlations,
        "correlations": correlations,
        "weak": _weak_combinations(result),
    }


def calibration_dict(calibration: Any) -> dict[str, Any]:
    """The one schema of a calibration (:class:`hexcal.Calibration`): what the text, JSON and
    HTML reports of ``hexcal identify`` render, and exactly its ``--json`` file.

    The keys of :func:`identification_report_dict` of its fit, plus ``leg_model`` (the model of
    the calibrated geometry), ``leg_model_choice`` (the cross-validation of ``auto``: scheme,
    candidates and scores; None otherwise), ``splits`` (``LABEL:ID`` where sessions were split),
    ``before_split`` (the verdict of the sessions as given, when ``split="auto"`` split them;
    else None) and ``inputs`` (the files and options, by label).
    """
    out = identification_report_dict(calibration.result)
    choice = calibration.leg_model_choice
    first = calibration.before_split
    out["leg_model"] = calibration.leg_model
    out["leg_model_choice"] = None if choice is None else choice.to_dict()
    out["splits"] = list(calibration.splits)
    out["before_split"] = (
        None
        if first is None
        else first.result.verdict.to_dict()
        | {
            "noise": first.result.noise_dict(),
            "leg_rms_after": first.result.leg_rms_after,
        }
    )
    out["inputs"] = dict(calibration.inputs)
    return out


def validation_dict(calibrated: Any, nominal: Any | None = None) -> dict[str, Any]:
    """Summaries of validations (:class:`hexcal.calibration.ValidationResult`), side by side,
    and what the instrument is."""
    return {
        "calibrated": calibrated.summary(),
        "nominal": nominal.summary() if nominal is not None else None,
        "instrument": calibrated.instrument,
        "registration": calibrated.registration,
        "expected": calibrated.expected,
    }


def validation_json(calibrated: Any, nominal: Any | None = None) -> dict[str, Any]:
    """The JSON of ``hexcal validate --json``: the calibrated machine's figures with their units
    in the keys (``position_rms_mm``, ``orientation_rms_rad``, ``leg_rms_mm``, their maxima, the
    instrument's own errors as ``instrument_<what>_rms_mm``), ``poses``, ``instrument``, ``registration``,
    ``expected``, and the same figures of the ``nominal`` machine when given.

    >>> from types import SimpleNamespace as NS
    >>> s = dict(poses=3, leg_rms=0.01, leg_max=0.02, position_rms=0.1, position_max=0.2,
    ...          orientation_rms=1e-5, orientation_max=2e-5, instrument_target_rms=0.05)
    >>> v = NS(summary=lambda: s, instrument="one target", registration=None, expected=None)
    >>> body = validation_json(v)
    >>> body["position_rms_mm"], body["orientation_rms_rad"], body["instrument_target_rms_mm"]
    (0.1, 1e-05, 0.05)
    """

    def figures(result: Any) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key, value in result.summary().items():
            if key == "poses":
                out[key] = value
                continue
            unit = "rad" if key.removeprefix("instrument_").startswith("orientation") else "mm"
            out[f"{key}_{unit}"] = value
        return out

    body = figures(calibrated) | {
        "instrument": calibrated.instrument,
        "registration": calibrated.registration,
        "expected": calibrated.expected,
    }
    body["nominal"] = None if nominal is None else figures(nominal) | {"registration": nominal.registration}
    return body


def validation_per_pose(calibrated: Any, nominal: Any | None = None) -> dict[str, Any]:
    """The per-observation errors of validations side by side: ``ids``, ``value_labels`` (the
    columns of a per-value error: the targets ``t1``, ...) and, for the ``calibrated`` and the
    ``nominal`` machine (None when not validated), ``leg_rms`` (of the six leg residuals),
    ``position_error``, ``orientation_error`` and ``instrument_errors`` (mm and rad, NaN where
    the instrument gives no value)."""

    def columns(result: Any) -> dict[str, Any]:
        d = result.to_dict()
        return {k: d[k] for k in ("leg_rms", "position_error", "orientation_error", "instrument_errors")}

    return {
        "ids": list(calibrated.ids),
        "value_labels": list(calibrated.value_labels),
        "calibrated": columns(calibrated),
        "nominal": None if nominal is None else columns(nominal),
    }


def validation_report_dict(validation: Any) -> dict[str, Any]:
    """The one schema of a validation (:class:`hexcal.Validation`): what the text, JSON and HTML
    reports, the per-pose table and the polar figure of ``hexcal validate`` render, and exactly
    its ``--json`` file.

    The keys of :func:`validation_json` (the calibrated machine's figures with their units in
    the keys, ``instrument``, ``registration``, ``expected``, ``nominal``), plus ``iso`` (the ISO
    figures of :func:`hexcal.report.iso_dict`, or None), ``per_pose``
    (:func:`validation_per_pose`), ``conditions`` (the names of the calibrated and the nominal
    geometry, the held-out ``observations``, the ``folds`` and ``seed`` of a re-registration),
    ``warnings`` (one line each) and ``inputs`` (the files and options, by label).
    """
    from hexcal.report.iso_summary import iso_dict

    calibrated, nominal, tests = validation.calibrated, validation.nominal, validation.iso
    out = validation_json(calibrated, nominal)
    out["iso"] = None
    if tests is not None:
        out["iso"] = iso_dict(
            tests.circular, tests.poses, note=tests.note, tolerance=tests.tolerance,
            instrument=calibrated.instrument, names=list(tests.names), after=tests.after,
        )  # fmt: skip
    out["per_pose"] = validation_per_pose(calibrated, nominal)
    other = validation.nominal_geometry
    out["conditions"] = {
        "geometry": validation.geometry.name,
        "nominal_geometry": None if other is None else other.name,
        "observations": len(calibrated.ids),
        "folds": validation.folds,
        "seed": validation.seed,
    }
    out["warnings"] = list(validation.warnings)
    beyond = getattr(validation, "beyond_stroke", None)
    out["beyond_stroke"] = None if beyond is None else beyond.to_dict()
    out["inputs"] = dict(validation.inputs)
    return out


def paper_figure_data(experiment: Any) -> dict[str, Any]:
    """The arrays of the paper's Figs. 10 and 11 (see :mod:`hexcal.report.figures`).

    ``before``, ``interior``, ``boundary``: mean absolute error (mm) of each of the 42
    parameters over the trials; ``validation_before`` and ``validation_after``: the first
    trial's position (mm) and orientation (rad) errors at the validation poses.
    """
    true = experiment.true_vectors
    return {
        "trials": experiment.trials,
        "before": np.abs(experiment.nominal_vector - true).mean(axis=0),
        "interior": np.nanmean(np.abs(experiment.interior_vectors - true), axis=0),
        "boundary": np.nanmean(np.abs(experiment.boundary_vectors - true), axis=0),
        "validation_before": {k: experiment.validation_before[k][0] for k in ("position", "orientation")},
        "validation_after": {k: experiment.validation_after[k][0] for k in ("position", "orientation")},
    }
