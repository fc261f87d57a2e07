"""Text renderers of calibration results: identification report, validation, the paper's
Table I and the Monte Carlo study table. Each renders a plain dictionary (see
:mod:`hexcal.report.convert`); instrument angles in degrees and orientation errors in mrad,
as on the pages and figures (:mod:`hexcal.report.units`); standard library only at import.
"""

from __future__ import annotations

import math
from typing import Any

from hexcal.report.units import display, is_angle, parameter_unit, validation_rows, validation_summaries


def _label(method: str) -> str:
    """What an estimator minimises, from the estimator registry."""
    from hexcal.estimation.registry import ESTIMATORS  # names and labels only: no numpy

    return ESTIMATORS[method].label if method in ESTIMATORS else method


#: Correlations above this magnitude are listed in the report.
CORRELATION_REPORT = 0.9

#: A scaled singular value below this fraction of the largest draws an identifiability
#: warning (the parameter combination is determined ~1e4 times worse than the best).
WEAK_SINGULAR_VALUE = 1e-4


def paper_text(summary: dict[str, Any]) -> str:
    """Text table of a Table I summary (:meth:`hexcal.simulation.PaperExperiment.to_dict`) beside
    the paper."""
    t = summary["trials"]
    lines = [
        f"Table I: mean absolute error of the 42 parameters (mm), {t} trials; "
        f"the paper's rows use method {summary['method']!r}",
        f"  {'row':<46}{'hexcal mean':>12}{'std':>9}{'bound':>9}{'eff.':>8}{'paper':>9}",
    ]
    for key, label in summary["rows"].items():
        bound = summary["bound"].get(key)
        b_text = f"{bound['bound']:>9.4f} {bound['efficiency']:>7.2f}" if bound else f"{'':>17}"
        reference = summary.get("paper", {})
        paper = f"{reference[key]:>9.4f}" if key in reference else f"{'-':>9}"
        lines.append(f"  {label:<46}{summary[key]:>12.4f}{summary['std'][key]:>9.4f}{b_text}{paper}")
    lines.append(
        "  (bound: Cramér–Rao bound of the mean absolute error for the same poses and noise; "
        "eff.: error / bound)"
    )
    fails = summary["failures"]
    if any(fails.values()):
        lines.append(f"  identification failed in {fails} trials (left out of the means)")
    val = summary["validation"]
    lines += [
        "",
        "Validation on 10 further corners (boundary calibration):",
        f"  {'':<12}{'pos max mm':>12}{'pos rms mm':>12}{'ang max rad':>13}{'ang rms rad':>13}   paper",
    ]
    for key in ("before", "after"):
        v = val[key]
        paper = val["paper"][key]
        lines.append(
            f"  {key:<12}{v['position_max']:>12.4g}{v['position_rms']:>12.4g}"
            f"{v['orientation_max']:>13.3g}{v['orientation_rms']:>13.3g}"
            f"   {paper['position']}, {paper['orientation']}"
        )
    lines.append("  (max: per-trial maximum averaged over trials; rms: over all poses)")
    return "\n".join(lines)


def study_text(rows: list[dict[str, Any]]) -> str:
    """Text table of a study: the ``StudyCell.row()`` dictionaries, one line each.

    >>> row = {"strategy": "corners", "poses": 15, "noise": "x1", "method": "ml", "error_mean": 0.3,
    ...        "error_std": 0.1, "bound": 0.25, "efficiency": 1.2, "position_rms": 0.01,
    ...        "orientation_rms": 2e-6}
    >>> print(study_text([row]).splitlines()[-1])
      corners       15  x1        ml          0.3000  0.1000  0.2500    1.20          0.01         2e-06
    """
    head = (
        f"  {'strategy':<10}{'poses':>6}  {'noise':<10}{'method':<8}{'error mm':>10}{'std':>8}"
        f"{'bound':>8}{'eff.':>8}{'val. pos rms':>14}{'val. ang rms':>14}"
    )
    lines = ["Mean absolute parameter error over the trials, its Cramér–Rao bound and validation", head]
    for r in rows:
        lines.append(
            f"  {r['strategy']:<10}{r['poses']:>6}  {r['noise']:<10}{r['method']:<8}{r['error_mean']:>10.4f}"
            f"{r['error_std']:>8.4f}{r['bound']:>8.4f} {r['efficiency']:>7.2f}"
            f"{r['position_rms']:>14.4g}{r['orientation_rms']:>14.3g}"
        )
    return "\n".join(lines)


def _fit_statistics(data: dict[str, Any], unit: str, outliers: list[str]) -> list[str]:
    method = data["method"]
    n = data["n_parameters"]
    lines = [
        "[[Fit statistics]]",
        f"    method              {method}: {_label(method)}",
        f"    residual unit       {unit}",
        f"    poses               {data['poses']}"
        + (f" (outliers removed: {', '.join(outliers)})" if outliers else ""),
        f"    parameters          {n} varied",
        f"    degrees of freedom  {data['dof']}",
        f"    leg RMS before      {data['leg_rms_before']:.6g} mm",
        f"    leg RMS after       {data['leg_rms_after']:.6g} mm",
        f"    cost                {data['cost']:.6g}",
        (
            f"    reduced chi-square  {data['reduced_chi2']:.4g}"
            if method in ("ml", "gls")
            else f"    residual std dev    {math.sqrt(data['reduced_chi2']):.4g} {unit}"
        ),
        f"    iterations          {data['iterations']} (function evaluations {data['function_evaluations']})",
        f"    status              {data['status']}: {data['message']}",
        f"    rank                {data['rank']} of {n}",
    ]
    if data.get("noise_text") is not None:
        if not data.get("noise"):  # else the [[Noise]] section says it, group by group
            lines.append(f"    noise model         {data['noise_text']}")
        given = (data.get("noise") or {}).get("source") != "estimated"
        if given and method in ("ml", "gls") and not 0.5 < data["reduced_chi2"] < 2.0:
            lines.append(
                "    warning: the reduced chi-square is far from 1: the noise model does not describe "
                "these data (learn it from the data: --noise auto)"
            )
    return lines


#: What a validation of a full pose measured in the base frame says of its instrument.
_FULL_POSE = "full pose in the base frame"

#: The unit column of the parameter table (gains are pure numbers).
_UNIT_TEXT = {"mm": "mm", "deg": "deg", "1": "-"}

#: Order of the reasons in the report: failures first.
_SEVERITY_ORDER = {"fail": 0, "warn": 1, "info": 2}


def verdict_lines(data: dict[str, Any]) -> list[str]:
    """The verdict in one line (its failing and warning reasons first), then every reason.

    >>> reasons = [{"severity": "info", "message": "fine"}, {"severity": "fail", "message": "bad"}]
    >>> verdict_lines({"verdict": "fail", "reasons": reasons})[:2]
    ['Verdict: FAIL: bad', '[[Verdict]]']
    """
    verdict = data.get("verdict")
    if verdict is None:
        return []
    reasons = sorted(data.get("reasons") or [], key=lambda r: _SEVERITY_ORDER.get(r["severity"], 3))
    serious = [r["message"] for r in reasons if r["severity"] in ("fail", "warn")]
    head = f"Verdict: {verdict.upper()}" + (f": {'; '.join(serious)}" if serious else "")
    lines = [head, "[[Verdict]]"]
    lines += [f"    {r['severity']:<5} {r['message']}" for r in reasons] or ["    no finding"]
    return lines


def noise_lines(data: dict[str, Any]) -> list[str]:
    """The noise model used: estimated (with its uncertainty and the instrument noise it
    implies; every group of every session) or given (and which groups disagree with the data,
    by how much)."""
    noise = data.get("noise")
    if not noise:
        return []
    units = {"leg": "mm", "position": "mm", "orientation": "rad"}
    lines = ["[[Noise]]"]
    stderr = noise.get("stderr") or {}
    groups = noise.get("groups")
    if noise.get("source") == "estimated":
        lines.append("    estimated from the data (--noise auto: the default without --noise)")
        if groups:
            parts = [
                f"{g['label']} σ {g['sigma']:.4g}"
                + (f" ± {g['stderr']:.2g}" if g["estimated"] and math.isfinite(g["stderr"]) else "")
                + f" {g['unit']}"
                + ("" if g["estimated"] else " (not estimated: too few data)")
                for g in groups
            ]
            lines.append("    " + ", ".join(parts))
        implied = data.get("noise_implied")
        if implied and len(data.get("sessions") or ()) <= 1:
            half = ", ".join(f"{k} {v:.3g}" for k, v in implied["uniform_half_width"].items())
            lines.append(f"    instrument noise implied: {implied['option']} (uniform half-widths {half})")
        return lines
    parts = []
    for group, unit in units.items():
        err = f" ± {stderr[group]:.2g}" if group in stderr else ""
        parts.append(f"{group} σ {noise[group]:.4g}{err} {unit}")
    lines.append("    given: " + ", ".join(parts) + " (standard deviations)")
    covariance = noise.get("pose_covariance", (noise.get("given") or {}).get("pose_covariance"))
    if covariance is not None:
        lines.append(
            "    position and orientation: the RMS of the given 6x6 pose covariance's diagonal (the fit "
            "uses the whole matrix)"
        )
    check = data.get("noise_check")
    if check:
        bad = [g for g, c in check.items() if c.get("disagrees")]
        for group in bad:
            c = check[group]
            unit = units.get(group.split()[-1], "")
            lines.append(
                f"    disagrees: {group} σ from the data {c['given'] * c['ratio']:.3g} {unit}, "
                f"given {c['given']:.3g} (× {c['ratio']:.3g}, p {c['p_value']:.1e})"
            )
        if not bad:
            lines.append("    the data agree with the given noise (every group)")
    return lines


def _setup_value(name: str, value: float | None) -> tuple[str, str]:
    """A setup parameter for the report: angles in degrees, lengths in mm."""
    unit = " deg" if is_angle(name) else " mm"
    if value is None or not math.isfinite(value):
        return "n/a", unit
    return f"{display(name, value):.6f}", unit


def session_lines(data: dict[str, Any]) -> list[str]:
    """The sessions: each instrument, the registration of an unknown frame, the gauge freedoms
    and the calibrated instrument quantities (nothing for one full-pose session)."""
    sessions = data.get("sessions") or []
    if len(sessions) == 1 and not sessions[0]["varied"] and sessions[0]["registration"] is None:
        return []
    lines = ["[[Sessions]]"]
    for s in sessions:
        lines.append(f"    {s['label']}: {s['description']}, {s['observations']} observation(s)")
        reg = s["registration"]
        if reg is not None:
            angle = (
                f", orientation RMS {reg['angle_rms_rad'] * 1e3:.3g} mrad" if "angle_rms_rad" in reg else ""
            )
            unit = "poses" if "tool" in reg else "points"
            lines.append(
                f"      instrument frame auto: registered from {reg['points']} {unit}, residual RMS "
                f"{reg['rms_mm']:.3f} mm, max {reg['max_mm']:.3f} mm{angle} (nominal machine and setup)"
            )
        held = [n for n in s["setup"] if n not in s["varied"]]
        if held and s["varied"]:
            lines.append(f"      held exactly: {', '.join(held)}")
    lines.append("[[Gauge freedoms]]")
    gauges = data.get("gauges") or []
    if gauges:
        lines.append(f"    {len(gauges)} combinations no data can determine: {', '.join(gauges)}")
        lines.append(f"    removed by the {data.get('convention')}")
        lines.append("    (rank, standard errors and bounds above are those of the gauge-fixed parameters)")
    else:
        lines.append("    none")
    weak = [r for r in data.get("reasons") or [] if r.get("code") == "undetermined"]
    lines.append(
        "    beyond the gauges: "
        + ("every varied parameter is identified" if not weak else "not determined: see the verdict")
    )
    for s in sessions:
        if not s["varied"]:
            continue
        title = "[[Calibrated setup]]" if len(sessions) == 1 else f"[[Calibrated setup: {s['label']}]]"
        lines += [title, f"    {'name':<10}{'value':>16}{'stderr':>12}"]
        for name, item in s["setup"].items():
            value, unit = _setup_value(name, item["value"])
            err, _ = _setup_value(name, item["stderr"])
            lines.append(f"    {name:<10}{value:>16}{err:>12}{unit}")
    return lines


def _number(value: Any) -> float:
    """A figure of the dict (None where the JSON has null) as a float."""
    return float("nan") if value is None else float(value)


def leg_model_lines(data: dict[str, Any]) -> list[str]:
    """The leg model, and the cross-validation that chose it (``leg_model="auto"``)."""
    from hexcal.calibration.leg_model_choice import choice_lines

    choice = data.get("leg_model_choice")
    if not choice and data.get("leg_model", "linear") == "linear":
        return []
    lines = ["[[Leg model]]", f"    {data.get('leg_model', '')}"]
    if choice:
        lines += [f"    {line}" for line in choice_lines(choice)]
    return lines


def split_lines(data: dict[str, Any]) -> list[str]:
    """Where sessions were split, and what the sessions as given showed."""
    if not data.get("splits"):
        return []
    lines = ["[[Splits]]", "    sessions split before " + ", ".join(data["splits"])]
    first = data.get("before_split")
    if first:
        lines.append(
            f"    as given: verdict {first['verdict']}, leg RMS after {first['leg_rms_after']:.4g} mm "
            f"(split: {data['leg_rms_after']:.4g} mm)"
        )
    return lines


def identification_text(data: dict[str, Any]) -> str:
    """Text report of an identification, in the spirit of lmfit's ``fit_report``.

    ``data`` is :func:`hexcal.report.identification_report_dict` of the result.
    """
    unit = {"length": "mm", "paper": "mm²"}.get(data["method"], "whitened, 1")
    names = list(data["parameters"])
    n = len(names)
    lines = verdict_lines(data) + _fit_statistics(data, unit, data["outliers"]) + noise_lines(data)
    lines += session_lines(data)
    lines += leg_model_lines(data) + split_lines(data)
    bound = data["bound"]
    header = f"    {'name':<8}{'nominal':>14}{'identified':>14}{'change':>12}{'stderr':>12}"
    header += f"{'CR bound':>12}" if bound is not None else ""
    lines += ["[[Parameters]]", header + "  unit"]
    for name in names:
        start, value, err = data["start"][name], data["parameters"][name], data["stderr"][name]
        start, value, err = (display(name, _number(v)) for v in (start, value, err))
        row = f"    {name:<8}{start:>14.6f}{value:>14.6f}{value - start:>+12.6f}{err:>12.6f}"
        row += f"{display(name, _number(bound[name])):>12.6f}" if bound is not None else ""
        lines.append(row + f"  {_UNIT_TEXT[parameter_unit(name)]}")
    if bound is not None:
        lines.append(
            "    (stderr: from the fit; CR bound: Cramér–Rao σ of any unbiased estimator under the "
            "noise model)"
        )
    most = data["max_correlations"]
    lines.append(f"[[Correlations]] (|C| > {CORRELATION_REPORT:g}, strongest {most})")
    listed = 0
    for first, second, c in data["correlations"]:
        if abs(c) < CORRELATION_REPORT:
            break
        lines.append(f"    C({first}, {second}) = {c:+.4f}")
        listed += 1
    if not listed:
        lines.append("    none")
    lines.append("[[Identifiability]]")
    sv = data["singular_values"]
    lines.append(
        f"    numerical rank {data['rank']} of {n}; condition number of the column-scaled Jacobian "
        f"{sv[0] / sv[-1]:.3g}"
    )
    lines.append("    smallest scaled singular values (σ/σmax) and their parameter combinations:")
    for ratio, combo in data["weak"]:
        mark = "  WEAK" if ratio < WEAK_SINGULAR_VALUE else ""
        lines.append(f"      {ratio:.3g}{mark}: {combo}")
    if sv[-1] / sv[0] < WEAK_SINGULAR_VALUE:
        lines.append(
            "    warning: some parameter combinations are barely determined by these poses; "
            "add poses with larger rotations or fix parameters (--fix)"
        )
    lines.append("[[Pose check]]")
    flagged = data["flagged"]
    if data["outliers"]:
        lines.append("    left out as outliers (--robust): " + ", ".join(data["outliers"]))
    if flagged:
        lines.append(
            f"    warning: implausible residuals at pose(s) {', '.join(flagged)}: a gross measurement "
            "error? (use --robust to identify without them)"
        )
    screened = [r for r in data.get("reasons") or [] if r.get("code") in ("gross-outlier", "outlier")]
    for reason in screened:
        lines.append(f"    {reason['severity']}: {reason['message']}")
    if not flagged and not screened and not data["outliers"]:
        lines.append("    no pose with implausible residuals")
    return "\n".join(lines)


def validation_text(data: dict[str, Any]) -> str:
    """The report of a validation: the figures side by side (a row the instrument cannot give,
    a platform pose from one target, is left out), the re-registration, what the calibration
    expected, then the ISO figures (:func:`hexcal.report.iso_text`) of an ISO test.

    ``data`` is a validation's one dictionary (:func:`hexcal.report.validation_report_dict`:
    ``hexcal.validate(...).to_dict()``), or the summaries side by side of
    :func:`hexcal.report.validation_dict`.

    >>> s = dict(poses=3, leg_rms=0.01, leg_max=0.02, position_rms=0.1, position_max=0.2,
    ...          orientation_rms=1e-5, orientation_max=2e-5)
    >>> print(validation_text({"calibrated": s, "nominal": None}).splitlines()[4])
        position error RMS (mm)                  0.1
    """
    if isinstance(data.get("calibrated"), dict):  # the summaries side by side
        calibrated, nominal = data["calibrated"], data.get("nominal")
    else:
        columns = validation_summaries(data)
        calibrated, nominal = columns["calibrated"], columns["nominal"]
    cols = [("calibrated", calibrated)] + ([("nominal", nominal)] if nominal else [])
    what = data.get("instrument") or _FULL_POSE
    lines = [
        f"Validation on {calibrated['poses']} held-out pose(s)"
        if what in ("pose", _FULL_POSE)
        else f"Validation on {calibrated['poses']} held-out observation(s) ({what})"
    ]
    lines.append(f"    {'':<30}" + "".join(f"{name:>14}" for name, _ in cols))
    for label, key, scale in validation_rows(list(calibrated)):
        values = [_number(d.get(key)) for _, d in cols]
        if all(not math.isfinite(v) for v in values):
            continue
        lines.append(f"    {label:<30}" + "".join(f"{v * scale:>14.4g}" for v in values))
    lines += registration_lines(data.get("registration"))
    lines += expected_lines(data.get("expected"))
    iso = data.get("iso")
    if iso:
        from hexcal.report.iso_summary import iso_text

        lines.append(iso_text(iso))
    return "\n".join(lines)


def registration_lines(record: dict[str, Any] | None) -> list[str]:
    """How validation re-registered the instrument (:func:`hexcal.calibration.validate`)."""
    if not record:
        return []
    quantities = record.get("quantities") or []
    kinds = sorted({q.split(".")[0] for q in quantities})
    held = record.get("held") or []
    kept = f"; held as given, not determined by this session: {', '.join(held)}" if held else ""
    return [
        f"Re-registered on this session ({len(quantities)} quantities: {', '.join(kinds)}{kept}) by "
        f"{record['folds']}-fold cross-validation (seed {record['seed']}): each pose judged by frames "
        f"fitted to the other folds; the registration on all poses leaves legs at "
        f"{_number(record['leg_rms_mm']):.3g} mm RMS ({record['noise']})"
    ]


def expected_lines(expected: dict[str, Any] | None) -> list[str]:
    """What the calibration's own uncertainty says validation should measure, and the ratio;
    the same with this session's noise when both are known."""
    if not expected:
        return []
    shown = {"position_rms_mm": "position", "orientation_rms_rad": "orientation", "leg_rms_mm": "legs"}
    lines = []
    what = {
        "calibration": "Expected from the calibration (its uncertainty, the noise of its own sessions)",
        "session": "Expected with this session's noise (learned by its registration)",
        "given": "Expected from the calibration (its uncertainty, the noise given)",
    }
    for entry in (expected, expected.get("with_session_noise")):
        if not entry or not math.isfinite(_number(entry["position_rms_mm"])):  # no pose (a ballbar)
            continue
        position, orientation, leg = (
            _number(entry[k]) for k in ("position_rms_mm", "orientation_rms_rad", "leg_rms_mm")
        )
        figures = (
            f"position RMS {position:.3g} mm, orientation RMS {orientation * 1e3:.3g} mrad, "
            f"leg RMS {leg:.3g} mm"
        )
        ratio = entry.get("measured_over_expected") or {}
        ratios = ", ".join(f"{shown[k]} {v:.2f}" for k, v in ratio.items() if math.isfinite(_number(v)))
        lines.append(f"{what.get(entry['noise'], 'Expected')}: {figures}")
        if ratios:
            lines.append(f"    measured / expected: {ratios}")
    lines += [f"    warning: {finding}" for finding in expected.get("findings") or []]
    return lines


# -- the former entry points, over the dictionaries -------------------------------------


def format_paper_summary(summary: dict[str, Any]) -> str:
    """Text table of :meth:`hexcal.simulation.PaperExperiment.to_dict` (same as :func:`paper_text`)."""
    return paper_text(summary)


def format_validation(calibrated: dict[str, float], nominal: dict[str, float] | None = None) -> str:
    """Side-by-side table of validation summaries (``ValidationResult.summary()``)."""
    return validation_text({"calibrated": calibrated, "nominal": nominal})


def identification_summary(
    result: Any, outliers: tuple[str, ...] = (), flagged: tuple[str, ...] = ()
) -> dict[str, Any]:
    """Machine-readable form of an identification (:func:`hexcal.report.identification_dict`)."""
    from hexcal.report.convert import identification_dict

    return identification_dict(result, outliers, flagged)


def format_identification_report(
    result: Any, outliers: tuple[str, ...] = (), flagged: tuple[str, ...] = (), max_correlations: int = 10
) -> str:
    """Text report of an identification result (:func:`identification_text` of its dict)."""
    from hexcal.report.convert import identification_report_dict

    return identification_text(identification_report_dict(result, outliers, flagged, max_correlations))
