"""validate states what the calibration expected it to measure, and says when it does not.

identify records the identified machine's covariance, gauge directions and noise in the
geometry's ``calibration:`` mapping (``uncertainty``); validate predicts from them the RMS it
should measure at its own poses (:func:`hexcal.calibration.accuracy.expected_validation`) and
prints the ratio. The tolerances come from the scatter of an RMS: over ``m`` poses of ``k``
values the mean square has a relative standard deviation of about ``sqrt(2 / (m k))`` (the
noise part), plus the one draw of the calibration's own error (its part of the expected value,
about a quarter here), hence a band of 0.75 to 1.33 at these sizes.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from hexcal.calibration import estimate, validate
from hexcal.cli.main import main
from hexcal.core.noise import NoiseModel
from hexcal.core.presets import preset
from hexcal.instruments import Session, instrument_for
from hexcal.instruments.setup import Setup
from hexcal.io import save_geometry, save_setup_dict, write_session_data
from tracker_cases import poses, simulate

NOISE = NoiseModel(leg=0.01, position=0.02, orientation=1e-4, distribution="normal")
FRAME = np.array([1500.0, -900.0, 400.0, 0.2, -0.1, 2.5])
TOOL = np.array([15.0, -5.0, 70.0, 0.05, 0.02, 0.4])


@pytest.fixture(scope="module")
def campaign():
    nominal, true = preset("paper-hmt"), preset("paper-hmt-true")
    setup = Setup(FRAME, tool=TOOL)
    train = simulate(nominal, true, setup, poses(nominal, 60, 1), NOISE, 0.0, 2)
    start = Setup(None, tool=TOOL + [1.0, -1.0, 1.0, 0.0, 0.0, 0.0])
    result = estimate(nominal, Session(train, instrument_for(start)), "ml", noise=NOISE, fit="joints,l0")
    calibrated = result.geometry.replace(calibration=result.calibration_metadata())
    # the instrument set up again for the held-out session: another frame
    moved = Setup(FRAME + [40.0, 25.0, -30.0, 0.05, 0.0, -0.1], tool=TOOL)
    return nominal, true, result, calibrated, moved


def test_the_calibration_records_its_uncertainty(campaign):
    _, _, result, calibrated, _ = campaign
    record = calibrated.calibration["uncertainty"]
    assert len(record["names"]) == 42 and np.shape(record["covariance"]) == (42, 42)
    assert np.shape(record["gauge"]) == (42, len(result.gauges))
    assert record["noise"]["leg"] == pytest.approx(0.01)


def test_validate_measures_what_the_calibration_expected(campaign):
    nominal, true, _, calibrated, moved = campaign
    held = simulate(nominal, true, moved, poses(nominal, 60, 7), NOISE, 0.0, 8)
    check = validate(calibrated, Session(held, instrument_for(Setup(None, tool=TOOL))))
    expected = check.expected
    assert expected["noise"] == "calibration"
    for key, ratio in expected["measured_over_expected"].items():
        assert 0.75 < ratio < 1.33, (key, ratio, expected)
    assert expected["findings"] == []
    # the same with the noise learned on the session: close by construction
    own = expected["with_session_noise"]
    assert own["noise"] == "session"
    assert all(0.8 < r < 1.25 for r in own["measured_over_expected"].values()), own


def test_validate_says_when_the_machine_is_not_the_one_calibrated(campaign):
    nominal, true, _, calibrated, moved = campaign
    vec = true.to_vector(gains=True)
    vec[[0, 4, 8]] += [1.5, -1.5, 1.0]  # three base joints moved by a millimetre or so since
    changed = true.with_vector(vec)
    held = simulate(nominal, changed, moved, poses(nominal, 60, 7), NOISE, 0.0, 8)
    check = validate(calibrated, Session(held, instrument_for(Setup(None, tool=TOOL))))
    ratios = check.expected["measured_over_expected"]
    assert max(ratios.values()) > 1.5, ratios
    assert any("predicted worse than the calibration" in f for f in check.expected["findings"])


def _run(*args) -> int:
    return main([str(a) for a in args])


def test_cli_validate_json_nominal_and_folds(campaign, tmp_path, capsys):
    nominal, true, result, calibrated, moved = campaign
    data = simulate(nominal, true, moved, poses(nominal, 40, 7), NOISE, 0.0, 8)
    held = Session(data, instrument_for(moved))
    write_session_data(tmp_path / "held.csv", held, nominal.euler)
    save_geometry(calibrated, tmp_path / "cal.yaml")
    free = tmp_path / "free.yaml"
    tool = dict(zip("xyzabc", TOOL.tolist(), strict=True))
    save_setup_dict({"units": "mm", "instrument_frame": "auto", "tool": tool}, free)
    common = ["validate", "--geometry", tmp_path / "cal.yaml", "--data", tmp_path / "held.csv"]
    assert _run(*common, "--setup", free, "--nominal", "paper-hmt", "--json", tmp_path / "v.json") == 0
    out = capsys.readouterr().out
    assert "Re-registered on this session (12 quantities: frame, tool) by 5-fold" in out
    assert "measured / expected:" in out
    body = json.loads((tmp_path / "v.json").read_text())
    for key in ("position_rms_mm", "orientation_rms_rad", "leg_rms_mm", "registration", "expected"):
        assert key in body
    # the nominal machine, re-registered too, misses by far more than the calibrated one
    assert body["nominal"]["position_rms_mm"] > 5 * body["position_rms_mm"]
    assert body["nominal"]["registration"]["folds"] == 5
    # the per-pose table: the tool's own errors beside the platform's, every column named once
    assert _run(*common, "--setup", free, "--out", tmp_path / "per.csv") == 0
    header = next(
        line for line in (tmp_path / "per.csv").read_text().splitlines() if not line.startswith("#")
    )
    names = header.split(",")
    assert len(set(names)) == len(names) and "instrument_position_error" in names, names
    # another split of the folds: the same figures to a few percent
    assert _run(*common, "--setup", free, "--folds", 4, "--seed", 3, "--json", tmp_path / "w.json") == 0
    other = json.loads((tmp_path / "w.json").read_text())
    assert other["registration"]["folds"] == 4
    assert other["position_rms_mm"] == pytest.approx(body["position_rms_mm"], rel=0.15)
    # refused in one line: one fold; the nominal machine through quantities calibrated with the machine
    assert _run(*common, "--setup", free, "--folds", 1) != 0
    assert capsys.readouterr().err.strip().endswith("--folds must be at least 2, got 1")
    fixed = tmp_path / "fixed.yaml"
    own = result.calibrated_instruments()[0].setup_dict()  # identify's --setup-out, then held
    save_setup_dict(own | {"fixed": ["instrument_frame", "tool"]}, fixed)
    assert _run(*common, "--setup", fixed, "--nominal", "paper-hmt") != 0
    # (the frame turned 2.5 rad draws the reader's degree warning first: a warning, not an error)
    err = [line for line in capsys.readouterr().err.strip().splitlines() if "warning" not in line]
    assert len(err) == 1 and "--nominal with a calibrated setup whose quantities are all fixed" in err[0]
    assert not (tmp_path / "x.json").exists()
