"""Outliers of tracker data: one target observation, or a whole pose."""

from __future__ import annotations

import numpy as np
import pytest

from hexcal.core.noise import NoiseModel
from hexcal.estimation import pose_diagnostics
from hexcal.instruments import Session, instrument_for
from hexcal.instruments.targets import TargetMeasurements
from tracker_cases import general_machines, identify, poses, simulate, tracker_setups

NOISE = NoiseModel(leg=0.005, position=0.015, orientation=2e-5, distribution="normal")


@pytest.fixture(scope="module")
def campaign():
    nominal, true = general_machines()
    true_setup, start = tracker_setups(3)
    data = simulate(nominal, true, true_setup, poses(nominal, 60, 1), NOISE, 0.08, 2)
    return nominal, start, data


def test_clean_data_flag_nothing(campaign):
    nominal, start, data = campaign
    result = identify(nominal, data, start, NOISE)
    diag = pose_diagnostics(result, data=Session(data, instrument_for(start)), noise=NOISE)
    assert diag.worst() is None and diag.flagged_labels(data.ids) == ()
    assert np.nanmin(diag.pvalue) > diag.limit and np.nanmin(diag.value_pvalue) > diag.limit


def test_one_bad_target_observation_is_left_out(campaign):
    nominal, start, data = campaign
    targets = np.array(data.targets)
    j = 10
    i = int(np.flatnonzero(data.seen[j])[0])
    targets[j, i] += [0.3, -0.2, 0.1]  # 0.4 mm: 25 sigma
    bad = TargetMeasurements(data.readings, targets, data.names, data.ids)
    robust = identify(nominal, bad, start, NOISE, robust=True)
    assert robust.outliers == (f"{data.ids[j]} target {data.names[i]}",)
    assert robust.n_poses == len(data) and robust.ids == data.ids


def test_bad_leg_reading_removes_the_pose(campaign):
    nominal, start, data = campaign
    readings = np.array(data.readings)
    readings[20, 2] += 0.5  # a leg reading 0.5 mm off: every target of the pose moves
    bad = TargetMeasurements(readings, data.targets, data.names, data.ids)
    robust = identify(nominal, bad, start, NOISE, robust=True)
    assert robust.outliers == (data.ids[20],) and robust.n_poses == len(data) - 1
    assert data.ids[20] not in robust.ids
