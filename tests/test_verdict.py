"""The verdict of an identification and the traps a new user falls into (issue 10)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from tests.conftest import simulate_measurements

from hexcal.calibration.identify import estimate
from hexcal.calibration.verdict import predicted_pose_accuracy, undetermined
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import select_parameters
from hexcal.core.presets import preset
from hexcal.core.workspace import random_poses, workspace_corners
from hexcal.errors import IdentificationError
from hexcal.instruments.pose import Measurements

NOMINAL, TRUE = preset("paper-hmt"), preset("paper-hmt-true")
NOISE = NoiseModel()  # the seed paper's: the data below are simulated with it


def data(m=50, seed=0, true=TRUE, poses=None):
    rng = np.random.default_rng(seed)
    poses = random_poses(NOMINAL, m, rng) if poses is None else poses
    return simulate_measurements(NOMINAL, true, poses, NOISE, seed + 1)


def with_poses(d, poses):
    return Measurements(poses, d.readings, d.ids)


@pytest.fixture(scope="module")
def clean():
    return data()


def test_a_good_calibration_passes_with_its_predicted_accuracy(clean):
    result = estimate(NOMINAL, clean, noise=NOISE)
    assert result.verdict_status == "pass", result.verdict.reasons
    out = json.loads(json.dumps(result.to_dict()))
    assert out["verdict"] == "pass" and out["noise"]["source"] == "given"
    assert out["noise"]["leg"] == pytest.approx(NOISE.sigmas[0])  # a standard deviation
    assert {"reasons", "bound", "reduced_chi_square", "rank", "outliers", "stderr"} <= set(out)
    acc = out["accuracy"]
    # the calibrated machine should be about as accurate as the pose measurement itself
    assert 0.005 < acc["position_rms_mm"] < 0.2 and acc["position_max_mm"] >= acc["position_rms_mm"]
    assert 0 < acc["orientation_rms_rad"] < 2e-3


def test_one_typo_of_100_mm_fails_naming_the_pose_and_robust_removes_it(clean):
    poses = np.array(clean.poses)
    poses[7, 0] += 100.0
    typo = with_poses(clean, poses)
    result = estimate(NOMINAL, typo, noise="auto")
    assert result.failed
    reason = next(r for r in result.verdict.reasons if r.code == "gross-outlier")
    assert reason.data["poses"] == ["8"] and "--robust" in reason.message
    robust = estimate(NOMINAL, typo, noise="auto", robust=True)
    assert robust.outliers == ("8",) and not robust.failed
    assert "gross-outlier" not in robust.verdict.codes()


def test_radians_in_degree_columns_fail_and_the_cause_is_named(clean):
    # a_deg columns holding radians: read as degrees, every angle is 57 times too small
    poses = np.array(clean.poses)
    poses[:, 3:] *= np.pi / 180
    result = estimate(NOMINAL, with_poses(clean, poses), noise="auto")
    assert result.failed
    assert "implausible-change" in result.verdict.codes("fail")
    assert "angle-units-degrees" in result.verdict.codes("fail")


@pytest.mark.slow
def test_degrees_in_radian_columns_fail_and_the_cause_is_named(clean):
    poses = np.array(clean.poses)
    poses[:, 3:] *= 180 / np.pi
    result = estimate(NOMINAL, with_poses(clean, poses), noise=NOISE)
    assert result.failed and "angle-units-radians" in result.verdict.codes("fail")


def test_poses_that_barely_rotate_fail_naming_the_undetermined_combinations():
    rng = np.random.default_rng(5)
    poses = random_poses(NOMINAL, 50, rng)
    poses[:, 3:] = rng.normal(0.0, 2e-3, (50, 3))  # "never rotating" on a real machine
    # a limit of 1 mm (the platform radius is 125 mm): these poses leave combinations beyond 3 mm
    result = estimate(NOMINAL, data(poses=poses, seed=5), noise="auto", sigma_limit=0.008)
    assert result.failed
    fails = [r for r in result.verdict.reasons if r.code == "undetermined"]
    assert fails and all("·" in r.data["combination"] for r in fails)
    assert any(".z" in r.data["combination"] for r in fails)


def test_poses_that_never_rotate_are_refused_naming_the_combinations():
    poses = random_poses(NOMINAL, 30, 6)
    poses[:, 3:] = 0.0
    exact = data(poses=poses, seed=6)
    with pytest.raises(IdentificationError, match=r"undetermined combinations: .*·"):
        estimate(NOMINAL, with_poses(exact, poses))


def test_unfitted_gains_warn_with_the_fit_hint():
    true = TRUE.replace(leg_gains=TRUE.leg_gains * (1 + np.array([3, -2, 4, -3, 2, -4]) * 1e-3))
    result = estimate(NOMINAL, data(true=true, seed=2), noise="auto")
    reason = next(r for r in result.verdict.reasons if r.code == "unfitted-gains")
    assert reason.severity in ("warn", "fail") and "--fit joints,l0,gains" in reason.message
    mask = select_parameters("joints,l0,gains")
    fitted = estimate(NOMINAL, data(true=true, seed=2), noise="auto", mask=mask)
    assert "unfitted-gains" not in fitted.verdict.codes()


@pytest.mark.slow
def test_a_wrong_euler_sequence_is_named(clean):
    result = estimate(NOMINAL.replace(euler="ZYX"), clean, noise=NOISE)
    assert result.verdict_status in ("warn", "fail")
    reason = next(r for r in result.verdict.reasons if r.code == "euler-sequence")
    assert reason.data["euler"] == "XYZ"


@pytest.mark.slow
def test_a_wrong_given_noise_warns_with_a_chi_square_out_of_range(clean):
    result = estimate(NOMINAL, clean, noise=NoiseModel(0.001, 0.002, 0.0001))
    assert "chi-square" in result.verdict.codes("warn") and "noise-model" in result.verdict.codes("warn")


def test_predicted_accuracy_and_undetermined_combinations_are_first_order_consistent():
    # a covariance with one combination of σ 20 mm along u1.z + s1.z, the rest 0.01 mm
    names = ("u1.z", "s1.z", "l0_1")
    vec = np.array([1, 1, 0]) / np.sqrt(2)
    cov = 1e-4 * np.eye(3) + 400 * np.outer(vec, vec)
    worst = undetermined(cov, names, ("mm", "mm", "mm"))  # the units the parameters carry
    assert len(worst) == 1 and worst[0][0] == pytest.approx(20, rel=1e-6)
    assert "u1.z" in worst[0][1] and "s1.z" in worst[0][1]
    # a pure l0_1 error of 1 mm: the first-order map against the forward kinematics
    from hexcal.core.kinematics import forward_kinematics, inverse_kinematics

    mask = np.zeros(48, dtype=bool)
    mask[36] = True
    acc = predicted_pose_accuracy(NOMINAL, np.eye(1), mask, n_random=50, seed=1)
    poses = np.concatenate([workspace_corners(NOMINAL), random_poses(NOMINAL, 50, 1)])
    lengths = inverse_kinematics(NOMINAL, poses)
    # the legs are commanded for the nominal l0: the real leg is 1 mm longer
    moved = forward_kinematics(NOMINAL, lengths + np.eye(6)[0], guess=poses).poses
    dpos = np.linalg.norm(moved[:, :3] - poses[:, :3], axis=1)
    assert acc["position_rms_mm"] == pytest.approx(np.sqrt(np.mean(dpos**2)), rel=0.01)
    assert acc["position_max_mm"] == pytest.approx(dpos.max(), rel=0.01)
