"""The reporting layer: every renderer works from a plain (JSON-ready) dictionary, the
JSON is strict, and the registry lists the renderers."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from hexcal.calibration import estimate, validate
from hexcal.core import NoiseModel, preset, select_parameters, workspace_corners
from hexcal.design import analyse_poses
from hexcal.design.planning import StrategyComparison, compare_strategies, feasible_corners, optimal_poses
from hexcal.report import (
    RENDERERS,
    format_identification_report,
    formats,
    identification_dict,
    identification_report_dict,
    json_text,
    render,
    study_table,
    validation_dict,
    validation_table,
)
from hexcal.report.registry import register
from hexcal.simulation import simulate_measurements

KINDS = ("identification", "validation", "paper", "study", "observability", "select", "claims")


def _strict_loads(text: str):
    def refuse(token):
        raise AssertionError(f"invalid JSON token {token}")

    return json.loads(text, parse_constant=refuse)


def _round_trip(data):
    """``data`` as a reader of its JSON file sees it."""
    return _strict_loads(render("paper", data, "json"))


@pytest.fixture(scope="module")
def fit():
    nominal, true = preset("paper-hmt"), preset("paper-hmt-true")
    data = simulate_measurements(nominal, true, workspace_corners(nominal)[:20], NoiseModel(), rng=3)
    return estimate(nominal, data, "length", select_parameters("joints,l0"), NoiseModel()), data


# -- registry and strict JSON ---------------------------------------------------------------


def test_registry_lists_text_and_json_of_every_kind():
    for kind in KINDS:
        assert (kind, "text") in RENDERERS and (kind, "json") in RENDERERS
        assert {(kind, "json"), (kind, "text")} <= set(formats(kind))
    for kind in ("identification", "validation", "paper", "study"):
        assert (kind, "html") in RENDERERS
    with pytest.raises(KeyError, match="no renderer for 'claims' as 'html'"):
        render("claims", {}, "html")


def test_a_new_format_is_one_more_registration():
    register("validation", "markdown", lambda data: f"{data['calibrated']['poses']} poses")
    try:
        assert render("validation", {"calibrated": {"poses": 4}}, "markdown") == "4 poses"
    finally:
        del RENDERERS[("validation", "markdown")]


def test_json_is_strict_nan_and_infinity_become_null():
    data = {"a": float("nan"), "b": [1.5, float("inf"), -float("inf")], "c": {"d": np.float64("nan")}}
    text = json_text(data)
    assert "NaN" not in text and "Infinity" not in text
    assert _strict_loads(text) == {"a": None, "b": [1.5, None, None], "c": {"d": None}}
    assert text.endswith("}\n")
    # finite data: exactly what json.dump(..., indent=2) wrote
    finite = {"x": [1.0, 2.5e-7], "y": "z", "n": 3, "t": True, "none": None}
    assert json_text(finite) == json.dumps(finite, indent=2) + "\n"


# -- identification and validation ----------------------------------------------------------


def test_identification_renders_from_its_json_ready_dict(fit):
    result, _ = fit
    data = identification_report_dict(result, (), ("p3",))
    text = render("identification", data)
    assert text == format_identification_report(result, (), ("p3",))
    assert render("identification", _round_trip(data)) == text  # a plain dict is enough
    assert text.startswith("Verdict: ")  # the verdict in one line, its reasons first
    assert "[[Fit statistics]]\n    method              length: least squares" in text
    assert "[[Parameters]]" in text and "implausible residuals at pose(s) p3" in text
    summary = _strict_loads(render("identification", identification_dict(result), "json"))
    assert list(summary)[:4] == ["method", "poses", "parameters", "start"]
    assert summary["rank"] == 42 and len(summary["parameters"]) == 42


def test_validation_text_and_table(fit):
    result, data = fit
    calibrated, nominal = validate(result.geometry, data), validate(preset("paper-hmt"), data)
    text = render("validation", validation_dict(calibrated, nominal))
    lines = text.splitlines()
    assert lines[0] == f"Validation on {len(data)} held-out pose(s)"
    assert lines[1].split() == ["calibrated", "nominal"] and len(lines) == 8
    assert render("validation", {"calibrated": calibrated.summary()}).splitlines()[1].split() == [
        "calibrated"
    ]
    columns, rows, ids, comment = validation_table(calibrated, nominal, data.ids)
    assert columns[3:] == ["nominal_leg_rms", "nominal_position_error", "nominal_orientation_error"]
    assert rows.shape == (len(data), 6) and ids == list(data.ids) and "per-pose" in comment
    np.testing.assert_allclose(rows[:, 1], calibrated.position_error)


# -- paper and study tables -------------------------------------------------------------------


def test_paper_table_from_a_summary_dict():
    stats = dict(position_max=15.0, position_rms=10.0, orientation_max=0.05, orientation_rms=0.03)
    summary = {
        "trials": 10,
        "method": "paper",
        "before": 2.7,
        "boundary": 0.38,
        "rows": {"before": "before calibration", "boundary": "15 of the 64 corners"},
        "std": {"before": 0.1, "boundary": 0.05},
        "bound": {"boundary": {"bound": 0.3, "efficiency": 1.27}},
        "failures": {"boundary": 0},
        "paper": {"before": 2.6652, "interior": 0.7236, "boundary": 0.3752},
        "validation": {
            "before": stats,
            "after": stats,
            "paper": {
                "before": {"position": "15 mm", "orientation": "0.05 rad"},
                "after": {"position": "-", "orientation": "-"},
            },
        },
    }
    lines = render("paper", summary).splitlines()
    assert lines[0].startswith("Table I: mean absolute error of the 42 parameters (mm), 10 trials")
    assert lines[2].split()[-3:] == ["2.7000", "0.1000", "2.6652"]
    assert lines[3].split()[-5:] == ["0.3800", "0.0500", "0.3000", "1.27", "0.3752"]
    assert not any("identification failed" in line for line in lines)


def test_study_text_csv_and_json_from_rows():
    row = {
        "strategy": "corners",
        "poses": 7,
        "noise": "x1",
        "method": "paper",
        "error_mean": 0.5,
        "error_std": 0.2,
        "bound": 0.0,
        "efficiency": float("nan"),
        "position_rms": 0.01,
        "orientation_rms": 3e-6,
        "failures": 1,
    }
    lines = render("study", [row]).splitlines()
    assert len(lines) == 3 and lines[2].split()[:6] == ["corners", "7", "x1", "paper", "0.5000", "0.2000"]
    assert "nan" in lines[2]
    columns, values, ids, _comment = study_table([row])
    assert columns[0] == "poses" and values.shape == (1, 7) and ids == ["corners/x1/paper"]
    assert _strict_loads(render("study", {"cells": [row]}, "json"))["cells"][0]["efficiency"] is None


# -- planning ---------------------------------------------------------------------------------


def test_observability_text_from_its_dict_and_from_its_json():
    geometry = preset("paper-hmt")
    mask = select_parameters("joints,l0,gains")
    analysis = analyse_poses(geometry, workspace_corners(geometry)[:8], NoiseModel(), mask)
    data = analysis.to_dict()
    assert data["rank"] < 48 and "test_poses" not in data
    text = render("observability", data, fit="joints,l0,gains")
    assert text.splitlines()[0].startswith("Observability of 8 pose(s) for 48 parameters (joints,l0,gains)")
    assert "NOT identifiable" in text and "not identifiable" in text
    assert render("observability", _round_trip(data), fit="joints,l0,gains") == text
    assert "NaN" not in render("observability", data, "json")


def test_select_text_and_json_keys():
    geometry = preset("paper-hmt")
    corners, _ = feasible_corners(geometry)
    chosen = np.random.default_rng(0).permutation(len(corners))[:15]
    comparison = compare_strategies(geometry, corners[chosen], NoiseModel(), rng=1, corners=corners)
    assert isinstance(comparison, StrategyComparison) and comparison.gain is not None
    data = {
        "strategy": "paper",
        "criterion": None,
        "n": 15,
        "seed": 1,
        "candidates": "corners",
        "ids": [f"c{k:02d}" for k in chosen],
        "indices": None,
        "value": None,
        "greedy_value": None,
        "swaps": 0,
        "seconds": 0.0,
        **comparison.to_dict(),
        "label": "15 corners",
    }
    lines = render("select", data).splitlines()
    assert lines[0] == "Selected 15 poses: 15 corners"
    assert lines[1] == "  ids: " + " ".join(data["ids"])
    assert [line.split()[0] for line in lines[3:]] == ["selected", "15", "15"]
    written = _strict_loads(render("select", data, "json"))
    assert list(written) == list(data)[:12] and "label" not in written


def test_claims_text_renders_the_same_from_json():
    from hexcal.design import claims, error_maps

    maps = error_maps(preset("paper-hmt"), levels=3, points=5, grid=3, draws=4, rng=0)
    summary = claims(maps)
    text = render("claims", summary)
    assert text.startswith("Boundary claim") and "Height claim" in text
    assert render("claims", _round_trip(summary)) == text


def test_optimal_poses_are_feasible_corners_of_the_grid_and_reproducible():
    geometry = preset("paper-hmt")
    first = optimal_poses(geometry, 10, NoiseModel(), 4)
    assert first.shape == (10, 6)
    np.testing.assert_array_equal(first, optimal_poses(geometry, 10, NoiseModel(), 4))
    lo, hi = np.asarray(geometry.workspace, dtype=float).T
    assert np.all((first >= lo - 1e-9) & (first <= hi + 1e-9))
    assert math.isfinite(compare_strategies(geometry, first, NoiseModel()).rows["selected"][0])
