"""Text renderers of calibration results: identification report, validation, the paper's
Table I and the Monte Carlo study table. Each renders a plain dictionary (see
:mod:`hexcal.report.convert`); standard library only at import.
"""

from __future__ import annotations

import math
from typing import Any


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
    """Text table of a Table I summary (:func:`hexcal.report.paper_summary`) beside the paper."""
    t = summary["trials"]
    lines = [
        f"Table I: mean absolute error of the 42 parameters (mm), {t} trials; "
        f"the paper's rows use method {summary['method']!r}",
        f"  {'row':<46}{'hexcal mean':>12}{'std':>9}{'bound':>9}{'eff.':>7}{'paper':>9}",
    ]
    for key, label in summary["rows"].items():
        bound = summary["bound"].get(key)
        b_text = f"{bound['bound']:>9.4f}{bound['efficiency']:>7.2f}" if bound else f"{'':>16}"
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
      corners       15  x1        ml          0.3000  0.1000  0.2500  1.20          0.01         2e-06
    """
    head = (
        f"  {'strategy':<10}{'poses':>6}  {'noise':<10}{'method':<8}{'error mm':>10}{'std':>8}"
        f"{'bound':>8}{'eff.':>6}{'val. pos rms':>14}{'val. ang rms':>14}"
    )
    lines = ["Mean absolute parameter error over the trials, its Cramér–Rao bound and validation", head]
    for r in rows:
        lines.append(
            f"  {r['strategy']:<10}{r['poses']:>6}  {r['noise']:<10}{r['method']:<8}{r['error_mean']:>10.4f}"
            f"{r['error_std']:>8.4f}{r['bound']:>8.4f}{r['efficiency']:>6.2f}"
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
    if data["noise"] is not None:
        lines.append(f"    noise model         {data['noise']}")
        if method in ("ml", "gls") and not 0.5 < data["reduced_chi2"] < 2.0:
            lines.append(
                "    warning: the reduced chi-square is far from 1: the noise model does not describe "
                "these data (give the instrument's noise with --noise)"
            )
    return lines


def identification_text(data: dict[str, Any]) -> str:
    """Text report of an identification, in the spirit of lmfit's ``fit_report``.

    ``data`` is :func:`hexcal.report.identification_report_dict` of the result.
    """
    unit = {"length": "mm", "paper": "mm²"}.get(data["method"], "whitened, 1")
    names = list(data["parameters"])
    n = len(names)
    lines = _fit_statistics(data, unit, data["outliers"])
    bound = data["bound"]
    header = f"    {'name':<8}{'nominal':>14}{'identified':>14}{'change':>12}{'stderr':>12}"
    lines += ["[[Parameters]]", header + (f"{'CR bound':>12}" if bound is not None else "")]
    for k, name in enumerate(names):
        start, value, err = data["start"][name], data["parameters"][name], data["stderr_values"][k]
        row = f"    {name:<8}{start:>14.6f}{value:>14.6f}{value - start:>+12.6f}{err:>12.6f}"
        lines.append(row + (f"{bound[k]:>12.6f}" if bound is not None else ""))
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
    if flagged:
        lines.append(
            f"    warning: implausible residuals at pose(s) {', '.join(flagged)}: a gross measurement "
            "error? (use --robust to identify without them)"
        )
    else:
        lines.append("    no pose with implausible residuals")
    return "\n".join(lines)


def validation_text(data: dict[str, Any]) -> str:
    """Side-by-side table of validation summaries (:func:`hexcal.report.validation_dict`).

    >>> s = dict(poses=3, leg_rms=0.01, leg_max=0.02, position_rms=0.1, position_max=0.2,
    ...          orientation_rms=1e-5, orientation_max=2e-5)
    >>> print(validation_text({"calibrated": s, "nominal": None}).splitlines()[4])
        position error RMS (mm)              0.1
    """
    calibrated, nominal = data["calibrated"], data.get("nominal")
    cols = [("calibrated", calibrated)] + ([("nominal", nominal)] if nominal else [])
    lines = [f"Validation on {calibrated['poses']} held-out pose(s)"]
    lines.append(f"    {'':<26}" + "".join(f"{name:>14}" for name, _ in cols))
    rows = [
        ("leg residual RMS (mm)", "leg_rms"),
        ("leg residual max (mm)", "leg_max"),
        ("position error RMS (mm)", "position_rms"),
        ("position error max (mm)", "position_max"),
        ("orientation RMS (rad)", "orientation_rms"),
        ("orientation max (rad)", "orientation_max"),
    ]
    for label, key in rows:
        lines.append(f"    {label:<26}" + "".join(f"{d[key]:>14.4g}" for _, d in cols))
    return "\n".join(lines)


# -- the former entry points, over the dictionaries -------------------------------------


def format_paper_summary(summary: dict[str, Any]) -> str:
    """Text table of :func:`hexcal.report.paper_summary` (same as :func:`paper_text`)."""
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
