"""Text renderers of campaign planning: observability of a pose set, a pose selection and
the error-map claims. Each renders a plain dictionary; standard library only at import.
"""

from __future__ import annotations

import math
from typing import Any


def _fmt(value: float | None, unit: str = "mm", digits: int = 4) -> str:
    """A number with its unit, or ``not identifiable`` (None, NaN or infinite)."""
    if value is None or not math.isfinite(value):
        return "not identifiable"
    return f"{value:.{digits}g} {unit}"


def _finite(value: float | None) -> bool:
    return value is not None and math.isfinite(value)


def observability_text(data: dict[str, Any], fit: str = "joints,l0") -> str:
    """The text report of ``hexcal observability``.

    ``data`` is :meth:`hexcal.design.PoseSetAnalysis.to_dict` of the analysis; ``fit`` names the
    parameter groups in the heading.
    """
    gauges = data.get("gauges", 0)
    n = data["n_parameters"] - gauges
    sv = data["singular_values"]
    noise = data["noise"]
    rank = data["rank"]
    # infinite (σmin = 0) when the dictionary was read back from JSON, where it is null
    condition = float("inf") if data["condition_number"] is None else data["condition_number"]
    verdict = "all identifiable" if rank == n else f"{n - rank} combination(s) NOT identifiable"
    instrument = data.get("instrument", "full pose in the base frame")
    jacobian = (
        "pose-eliminated noise-whitened Jacobian"
        if gauges or (instrument != "full pose in the base frame" and data["weighted"])
        else f"{'noise-whitened ' if data['weighted'] else ''}identification Jacobian"
    )
    lines = [
        f"Observability of {data['n_poses']} pose(s) for {data['n_parameters']} parameters ({fit}) "
        f"measured by the {instrument}; {jacobian}, column scaling {data['scaling']}",
    ]
    if gauges:
        lines.append(
            f"  {gauges} gauge freedoms (no data can determine them; fixed by the convention): "
            + ", ".join(data.get("gauge_labels", []))
        )
    lines += [
        f"  rank {rank} of {n}{' beyond the gauges' if gauges else ''}: {verdict}",
        f"  singular values: {sv[0]:.4g} ... {sv[-1]:.4g} (condition number {condition:.4g})",
        f"  O1 = {data['O1']:.4g}   geometric mean of the singular values (D-optimality; Borm & Menq 1991)",
        f"  O2 = {data['O2']:.4g}   σmin/σmax, inverse condition number (Driels & Pathre 1990)",
        f"  O3 = {data['O3']:.4g}   σmin (E-optimality; Nahvi, Hollerbach & Hayward 1994)",
        f"  O4 = {data['O4']:.4g}   σmin²/σmax, noise amplification index (Nahvi & Hollerbach 1996)",
        f"  O5 = {data['O5']:.4g}   1/Σ(1/σi) (A-optimality; Sun & Hollerbach 2008)",
    ]
    if data["unidentifiable"]:
        lines.append("  parameter changes these poses cannot see (each a direction δθ ∝ the sum):")
        lines += [f"    {c}" for c in data["unidentifiable"]]
    lines.append(noise_line(noise))
    predicted = data["predicted_mean_abs_error_mm"]
    lines.append(
        f"Predicted mean absolute parameter error: {_fmt(predicted['estimator'])} "
        f"(identify, method {data['method']}); Cramér-Rao bound {_fmt(predicted['bound'])}"
    )
    lines.append("Predicted standard deviation per parameter (estimator / bound; gains and angles x1e-3):")
    cells = []
    for name, std in data["parameters"].items():
        se, sb = std["std_estimator"], std["std_bound"]
        k = 1e3 if name.startswith("g") or name.split(".")[-1] in ("a", "b", "c") else 1.0
        cell = f"{name:>5} {se * k:.3f}/{sb * k:.3f}" if _finite(se) else f"{name:>5}  not identifiable"
        cells.append(cell)
    for start in range(0, len(cells), 6):
        lines.append("  " + "  ".join(cells[start : start + 6]))
    lines += stroke_lines(data.get("stroke_coverage"))
    test = data.get("test_poses")
    if test:
        mean_rot, max_rot = test["orientation_rms_mean_rad"], test["orientation_rms_max_rad"]
        lines.append(
            f"Predicted pose error after calibration at {test['n']} test pose(s), RMS: position mean "
            f"{_fmt(test['position_rms_mean_mm'])}, max {_fmt(test['position_rms_max_mm'])}; "
            "orientation mean "
            f"{_fmt(None if mean_rot is None else mean_rot * 1e3, 'mrad')}, "
            f"max {_fmt(None if max_rot is None else max_rot * 1e3, 'mrad')}"
        )
    return "\n".join(lines)


def noise_line(noise: dict[str, Any]) -> str:
    """The noise a prediction assumes, as given and as standard deviations (``sigmas`` a list
    or a mapping by group).

    >>> line = noise_line({"leg": 0.01, "position": 0.025, "orientation": 0.001,
    ...                    "distribution": "uniform", "sigmas": [0.00577, 0.0144, 0.000577]})
    >>> line.split("; ")[1]
    'standard deviations 0.00577, 0.0144, 0.000577'
    """
    sigmas = noise["sigmas"]
    values = [sigmas[g] for g in ("leg", "position", "orientation")] if isinstance(sigmas, dict) else sigmas
    return (
        f"Noise ({noise['distribution']}): legs {noise['leg']:g} mm, position {noise['position']:g} mm, "
        f"orientation {noise['orientation']:g} rad; standard deviations "
        + ", ".join(f"{s:.3g}" for s in values)
    )


def stroke_lines(coverage: dict[str, Any] | None) -> list[str]:
    """The stroke coverage of a pose set (a leg model with a curve of the stroke): the share
    of each leg's stroke its readings cover, and the findings (poorly covered legs)."""
    if not coverage:
        return []
    shares = "  ".join(f"leg {k + 1} {c:.0%}" for k, c in enumerate(coverage["covered"]))
    lines = [f"Stroke covered by the poses' readings (the stroke terms are determined there): {shares}"]
    lines += [f"  warning: {finding}" for finding in coverage["findings"]]
    return lines


#: Keys of the ``hexcal select --json`` file, in order.
SELECT_JSON_KEYS = (
    "strategy",
    "criterion",
    "n",
    "seed",
    "candidates",
    "ids",
    "indices",
    "value",
    "greedy_value",
    "swaps",
    "seconds",
    "predicted_mean_abs_error_mm",
)


def select_json(data: dict[str, Any]) -> dict[str, Any]:
    """The ``hexcal select --json`` file: the keys :data:`SELECT_JSON_KEYS` of ``data``, then
    ``noise`` (assumed) and ``instrument`` where the selection records them, and
    ``stroke_coverage`` for a leg model with a curve of the stroke."""
    extra = {key: data[key] for key in ("noise", "instrument") if data.get(key) is not None}
    if data.get("stroke_coverage"):
        extra["stroke_coverage"] = data["stroke_coverage"]
    return {key: data[key] for key in SELECT_JSON_KEYS} | extra


def select_text(data: dict[str, Any]) -> str:
    """What ``hexcal select`` prints.

    ``data`` has the keys of :data:`SELECT_JSON_KEYS` and ``label`` (what was selected),
    ``greedy_text`` and ``value_text`` (the criterion values in words, for the optimal
    strategy) and ``comparisons`` (description of each compared strategy).
    """
    n, rows = data["n"], data["predicted_mean_abs_error_mm"]
    lines = [f"Selected {n} poses: {data['label']}"]
    if data["indices"] is not None:
        lines.append(
            f"  greedy {data['greedy_text']} -> after {data['swaps']} exchange(s) "
            f"{data['value_text']} ({data['seconds']:.2f} s)"
        )
        lines.append(f"  candidate indices: {' '.join(str(int(k)) for k in data['indices'])}")
    lines.append(f"  ids: {' '.join(data['ids'])}")
    if data.get("instrument"):
        lines.append(f"Measured by the {data['instrument']}")
    if data.get("noise"):
        lines.append(noise_line(data["noise"]))
    method = data.get("method", "length")
    lines.append(
        f"Predicted mean absolute parameter error (mm): identify (method {method}) | Cramér-Rao bound"
    )
    selected = rows["selected"]
    lines.append(f"  {'selected poses':<58} {selected['estimator']:8.4f} | {selected['bound']:.4f}")
    for key, text in data["comparisons"].items():
        lines.append(f"  {text:<58} {rows[key]['estimator']:8.4f} | {rows[key]['bound']:.4f}")
    if "paper" in rows and data["strategy"] == "optimal":
        gain = 1 - selected["estimator"] / rows["paper"]["estimator"]
        word = "lower" if gain >= 0 else "higher"
        lines.append(f"  selected vs the paper's strategy: {abs(gain):.0%} {word} predicted error")
    lines += stroke_lines(data.get("stroke_coverage"))
    return "\n".join(lines)


def _both(by_key: dict[str, Any], key: str, spec: str) -> str:
    """``position / orientation`` values of ``key`` in format ``spec``."""
    return f"{by_key['position'][key]:{spec}} / {by_key['orientation'][key]:{spec}}"


def claims_text(summary: dict[str, Any]) -> str:
    """The numbers of the error-map claims (:func:`hexcal.design.claims`) as a short report
    on the seed paper's boundary and height claims."""
    lines_ = ["Boundary claim (errors largest on the workspace boundary):"]
    for axis, by_key in summary["lines"].items():
        p, o = by_key["position"], by_key["orientation"]
        lines_.append(
            f"  {axis} sweep: max at an end in {p['max_at_an_end']:.0%} (position) / "
            f"{o['max_at_an_end']:.0%} (orientation) of the mean curves, "
            f"{_both(by_key, 'max_at_an_end_single_draws', '.0%')} of single draws; "
            f"end / centre = {_both(by_key, 'end_over_centre', '.3f')}"
        )
    for name, by_key in summary["angles"].items():
        lines_.append(
            f"  {name} grid: max on the boundary at {_both(by_key, 'max_on_boundary', '.0%')} "
            f"of z levels (at a corner {_both(by_key, 'max_at_a_corner', '.0%')}); "
            f"max / centre = {_both(by_key, 'max_over_centre', '.3f')}"
        )
    wp, wo = summary["workspace"]["position"], summary["workspace"]["orientation"]
    lines_.append(
        f"  64 corners vs random interior poses: {wp['corners_mean']:.4f} vs {wp['interior_mean']:.4f} mm "
        f"(x{wp['corners_over_interior']:.3f}), {wo['corners_mean'] * 1e3:.4f} vs "
        f"{wo['interior_mean'] * 1e3:.4f} mrad (x{wo['corners_over_interior']:.3f}); "
        f"{_both(summary['workspace'], 'interior_above_corner_mean', '.0%')} of interior "
        "poses exceed the corners' mean"
    )
    lines_.append("Height claim (errors larger at larger z):")
    for axis in ("x", "y"):
        by_key = summary["lines"][axis]
        lines_.append(
            f"  {axis} sweeps: rank correlation of z with the curve mean "
            f"{_both(by_key, 'level_rank_correlation', '+.3f')}; "
            f"top z / bottom z = {_both(by_key, 'top_level_over_bottom_level', '.3f')}"
        )
    lines_.append(
        "  z sweeps: max at the upper end (largest z) in "
        f"{_both(summary['lines']['z'], 'max_at_upper_end', '.0%')} of the curves"
    )
    for name, by_key in summary["angles"].items():
        ratio = _both(by_key, "top_level_over_bottom_level", ".3f")
        lines_.append(f"  {name} grids: top z / bottom z = {ratio}")
    ratio = _both(summary["workspace"], "corners_top_z_over_bottom_z", ".3f")
    lines_.append(f"  corners at the top z / bottom z: {ratio}")
    return "\n".join(lines_)
