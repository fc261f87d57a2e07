"""Summaries and text reports of hexcal's results."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.estimation.result import IdentificationResult
from hexcal.simulation.campaign import PaperExperiment

#: The seed paper's Table I (mean absolute parameter error, mm) and its validation claims.
PAPER_TABLE1 = {"before": 2.6652, "interior": 0.7236, "boundary": 0.3752}
PAPER_VALIDATION = {
    "before": {"position": "about 15 mm", "orientation": "about 0.05 rad"},
    "after": {"position": "below 0.03 mm", "orientation": "below 3e-6 rad"},
}


def _pose_error_stats(errors: dict[str, NDArray[np.float64]]) -> dict[str, float]:
    """Per-trial max averaged over trials, and RMS over all poses of all trials."""
    out: dict[str, float] = {}
    for key in ("position", "orientation"):
        e = errors[key]
        out[f"{key}_max"] = float(np.nanmean(np.nanmax(e, axis=1)))
        out[f"{key}_rms"] = float(np.sqrt(np.nanmean(e**2)))
        out[f"{key}_max_worst"] = float(np.nanmax(e))
    return out


#: Labels of the rows of ``hexcal paper``.
ROW_LABELS = {
    "before": "before calibration",
    "interior": "15 random poses inside the workspace",
    "boundary": "15 of the 64 corners",
    "boundary_ml": "15 of the 64 corners, maximum likelihood",
    "selected_ml": "15 optimally selected poses, max. likelihood",
}


def paper_summary(experiment: PaperExperiment, **meta: Any) -> dict[str, Any]:
    """The Table I reproduction as a JSON-ready mapping (see ``hexcal paper``).

    Every row (``interior``, ``boundary`` and any extra rows) has its mean absolute
    parameter error (mm) as a top-level number, its standard deviation over trials in
    ``std``, and, under ``bound``, the Cramér–Rao bound of that error and the
    efficiency (error / bound).
    """
    errors = experiment.mean_abs_errors()
    summary: dict[str, Any] = dict(meta)
    bounds = {}
    for row in errors:
        b = experiment.bound_of(row)
        if b is not None:
            bound = float(np.mean(b))
            bounds[row] = {"bound": bound, "efficiency": float(np.nanmean(errors[row])) / bound}
    summary.update(
        {
            "trials": experiment.trials,
            "method": experiment.method,
            **{row: float(np.nanmean(values)) for row, values in errors.items()},
            "rows": {row: ROW_LABELS.get(row, row) for row in errors},
            "std": {k: float(np.nanstd(v)) for k, v in errors.items()},
            "bound": bounds,
            "failures": experiment.failures,
            "paper": dict(PAPER_TABLE1),
            "validation": {
                "before": _pose_error_stats(experiment.validation_before),
                "after": _pose_error_stats(experiment.validation_after),
                "paper": PAPER_VALIDATION,
                "statistics": "max: per-trial maximum over the validation poses, averaged over "
                "trials; rms: over all validation poses of all trials; max_worst: over all",
            },
        }
    )
    return summary


def format_paper_summary(summary: dict[str, Any]) -> str:
    """Text table of :func:`paper_summary` beside the paper's figures."""
    t = summary["trials"]
    lines = [
        f"Table I: mean absolute error of the 42 parameters (mm), {t} trials; "
        f"the paper's rows use method {summary['method']!r}",
        f"  {'row':<46}{'hexcal mean':>12}{'std':>9}{'bound':>9}{'eff.':>7}{'paper':>9}",
    ]
    for key, label in summary["rows"].items():
        bound = summary["bound"].get(key)
        b_text = f"{bound['bound']:>9.4f}{bound['efficiency']:>7.2f}" if bound else f"{'':>16}"
        paper = f"{PAPER_TABLE1[key]:>9.4f}" if key in PAPER_TABLE1 else f"{'-':>9}"
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
        paper = PAPER_VALIDATION[key]
        lines.append(
            f"  {key:<12}{v['position_max']:>12.4g}{v['position_rms']:>12.4g}"
            f"{v['orientation_max']:>13.3g}{v['orientation_rms']:>13.3g}"
            f"   {paper['position']}, {paper['orientation']}"
        )
    lines.append("  (max: per-trial maximum averaged over trials; rms: over all poses)")
    return "\n".join(lines)


# -- identification ------------------------------------------------------------------

#: Correlations above this magnitude are listed in the report.
CORRELATION_REPORT = 0.9

#: A scaled singular value below this fraction of the largest draws an identifiability
#: warning (the parameter combination is determined ~1e4 times worse than the best).
WEAK_SINGULAR_VALUE = 1e-4


def identification_summary(
    result: IdentificationResult,
    outliers: tuple[str, ...] = (),
    flagged: tuple[str, ...] = (),
) -> dict[str, Any]:
    """Machine-readable form of an identification (the ``--json`` file)."""
    return {
        "method": result.method,
        "poses": result.n_poses,
        "parameters": result.parameters,
        "start": dict(zip(result.names, result.start_values.tolist(), strict=True)),
        "stderr": result.standard_errors,
        "rank": result.rank,
        "n_parameters": len(result.names),
        "singular_values": result.singular_values.tolist(),
        "leg_rms_before": result.leg_rms_before,
        "leg_rms_after": result.leg_rms_after,
        "rms_before": result.rms_before,
        "rms_after": result.rms_after,
        "cost": result.cost,
        "iterations": result.njev,
        "function_evaluations": result.nfev,
        "status": result.status,
        "message": result.message,
        "outliers": list(outliers),
        "flagged": list(flagged),
        "ids": list(result.ids),
    }


def _weak_combinations(result: IdentificationResult, count: int = 3) -> list[tuple[float, str]]:
    """The smallest scaled singular values and the parameter combinations they belong to."""
    out = []
    sv = result.singular_values
    for k in range(min(count, sv.size)):
        vec = result.singular_vectors[-1 - k]
        order = np.argsort(-np.abs(vec))[:4]
        combo = " ".join(f"{vec[i]:+.2f}·{result.names[i]}" for i in order if abs(vec[i]) >= 0.05)
        out.append((float(sv[-1 - k] / sv[0]), combo))
    return out


def format_identification_report(
    result: IdentificationResult,
    outliers: tuple[str, ...] = (),
    flagged: tuple[str, ...] = (),
    max_correlations: int = 10,
) -> str:
    """Text report of an identification, in the spirit of lmfit's ``fit_report``."""
    unit = {"length": "mm", "paper": "mm²"}.get(result.method, "whitened, 1")
    n = len(result.names)
    m = result.n_poses
    described = {
        "ml": "maximum likelihood (errors in variables)",
        "gls": "generalised least squares (propagated pose covariance)",
        "length": "least squares on leg lengths",
        "paper": "least squares on squared leg lengths (the seed paper's eq. 3)",
    }
    lines = [
        "[[Fit statistics]]",
        f"    method              {result.method}: {described.get(result.method, result.method)}",
        f"    residual unit       {unit}",
        f"    poses               {m}" + (f" (outliers removed: {', '.join(outliers)})" if outliers else ""),
        f"    parameters          {n} varied",
        f"    degrees of freedom  {result.dof}",
        f"    leg RMS before      {result.leg_rms_before:.6g} mm",
        f"    leg RMS after       {result.leg_rms_after:.6g} mm",
        f"    cost                {result.cost:.6g}",
        (
            f"    reduced chi-square  {result.reduced_chi2:.4g}"
            if result.method in ("ml", "gls")
            else f"    residual std dev    {np.sqrt(result.reduced_chi2):.4g} {unit}"
        ),
        f"    iterations          {result.njev} (function evaluations {result.nfev})",
        f"    status              {result.status}: {result.message}",
        f"    rank                {result.rank} of {n}",
    ]
    if result.noise is not None:
        lines.append(f"    noise model         {result.noise.describe()}")
        if result.method in ("ml", "gls") and not 0.5 < result.reduced_chi2 < 2.0:
            lines.append(
                "    warning: the reduced chi-square is far from 1: the noise model does not describe "
                "these data (give the instrument's noise with --noise)"
            )
    bound = result.bound
    header = f"    {'name':<8}{'nominal':>14}{'identified':>14}{'change':>12}{'stderr':>12}"
    lines += ["[[Parameters]]", header + (f"{'CR bound':>12}" if bound is not None else "")]
    for k, (name, start, value, err) in enumerate(
        zip(result.names, result.start_values, result.values, result.stderr, strict=True)
    ):
        row = f"    {name:<8}{start:>14.6f}{value:>14.6f}{value - start:>+12.6f}{err:>12.6f}"
        lines.append(row + (f"{bound[k]:>12.6f}" if bound is not None else ""))
    if bound is not None:
        lines.append(
            "    (stderr: from the fit; CR bound: Cramér–Rao σ of any unbiased estimator under the "
            "noise model)"
        )
    corr = result.correlation
    iu = np.triu_indices(n, 1)
    strong = np.argsort(-np.abs(corr[iu]))[:max_correlations]
    lines.append(f"[[Correlations]] (|C| > {CORRELATION_REPORT:g}, strongest {max_correlations})")
    listed = 0
    for k in strong:
        c = corr[iu[0][k], iu[1][k]]
        if abs(c) < CORRELATION_REPORT:
            break
        lines.append(f"    C({result.names[iu[0][k]]}, {result.names[iu[1][k]]}) = {c:+.4f}")
        listed += 1
    if not listed:
        lines.append("    none")
    lines.append("[[Identifiability]]")
    sv = result.singular_values
    lines.append(
        f"    numerical rank {result.rank} of {n}; condition number of the column-scaled Jacobian "
        f"{sv[0] / sv[-1]:.3g}"
    )
    lines.append("    smallest scaled singular values (σ/σmax) and their parameter combinations:")
    for ratio, combo in _weak_combinations(result):
        mark = "  WEAK" if ratio < WEAK_SINGULAR_VALUE else ""
        lines.append(f"      {ratio:.3g}{mark}: {combo}")
    if sv[-1] / sv[0] < WEAK_SINGULAR_VALUE:
        lines.append(
            "    warning: some parameter combinations are barely determined by these poses; "
            "add poses with larger rotations or fix parameters (--fix)"
        )
    lines.append("[[Pose check]]")
    if flagged:
        lines.append(
            f"    warning: implausible residuals at pose(s) {', '.join(flagged)}: a gross measurement "
            "error? (use --robust to identify without them)"
        )
    else:
        lines.append("    no pose with implausible residuals")
    return "\n".join(lines)


def format_validation(calibrated: dict[str, float], nominal: dict[str, float] | None = None) -> str:
    """Side-by-side table of validation summaries."""
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
