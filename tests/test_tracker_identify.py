"""Identification with instrument setups: registration, gauges, recovery, equivalence."""

from __future__ import annotations

import numpy as np
import pytest
from hexcal.estimation.instrument import identify_instrument, instrument_parameters
from hexcal.instruments.instrument_data import (
    predict_instrument,
    simulate_target_measurements,
    simulate_tool_measurements,
    validate_instrument,
)
from hexcal.instruments.tool import ToolModel
from scipy.spatial.transform import Rotation

from conftest import simulate_measurements
from hexcal.calibration import estimate
from hexcal.core.noise import NoiseModel
from hexcal.core.presets import preset
from hexcal.errors import IdentificationError
from hexcal.estimation.gauge import apply_convention, gauge_freedoms
from hexcal.estimation.problem import Problem
from hexcal.estimation.uncertainty import model_cramer_rao
from hexcal.instruments.registration import register_frame
from hexcal.instruments.setup import Setup
from hexcal.instruments.targets import TargetModel
from tracker_cases import general_machines, poses, tracker_setups

NOISE = NoiseModel(leg=0.005, position=0.015, orientation=2e-5, distribution="normal")


@pytest.fixture(scope="module")
def machines():
    return general_machines()


@pytest.mark.parametrize("n_targets", [1, 3])
def test_noise_free_recovery_up_to_the_gauge(machines, n_targets):
    nominal, true = machines
    true_setup, start_setup = tracker_setups(n_targets)
    data = simulate_target_measurements(nominal, true, true_setup, poses(nominal, 50, 1), None, 0.1, 2)
    lost = np.isnan(data.targets[..., 0]).sum() + n_targets * (50 - len(data))
    assert 0 < lost < 0.2 * 50 * n_targets
    out = identify_instrument(nominal, data, start_setup, NOISE)
    assert len(out.gauges) == 12 and out.result.rank == len(out.result.names) - 12
    held = simulate_target_measurements(nominal, true, true_setup, poses(nominal, 40, 9), None, 0.0, 3)
    pred = predict_instrument(out.geometry, out.setup, held.readings)
    assert np.abs(pred - held.targets).max() < 1e-6  # gauge-invariant predictions, mm
    # the gauge-fixed parameters are the true machine moved to the convention's frames
    problem = Problem(nominal, data, TargetModel(true_setup))
    full_true = np.concatenate([true.to_vector(gains=True), true_setup.vector()])
    fixed_true = apply_convention(problem, full_true, gauge_freedoms(problem, problem.full0))
    got = np.concatenate([out.geometry.to_vector(gains=True), out.setup.vector()])
    np.testing.assert_allclose(got[:42], fixed_true[:42], atol=1e-5)


@pytest.mark.parametrize("seed", range(5))
def test_registration_from_an_arbitrary_frame(seed):
    machine = preset("paper-hmt")
    rng = np.random.default_rng(seed)
    angles = Rotation.random(random_state=seed).as_euler("XYZ")
    frame = np.concatenate([rng.uniform(-5000, 5000, 3), angles])
    setup = Setup(frame, {"t1": [10.0, 20.0, 60.0]})
    data = simulate_target_measurements(machine, machine, setup, poses(machine, 20, seed), None, 0.0, seed)
    reg = register_frame(machine, Setup(None, setup.targets), data)
    assert reg.rms < 1e-6 and reg.points == 20
    np.testing.assert_allclose(reg.frame[:3], frame[:3], atol=1e-6)
    rel = Rotation.from_euler("XYZ", reg.frame[3:]).inv() * Rotation.from_euler("XYZ", frame[3:])
    assert rel.magnitude() < 1e-9


def test_registration_refuses_collinear_points():
    machine = preset("paper-hmt")
    setup = Setup(np.zeros(6), {"t1": [0.0, 0.0, 0.0]})
    line = np.zeros((10, 6))
    line[:, 2] = np.linspace(720, 880, 10)
    data = simulate_target_measurements(machine, machine, setup, line, None, 0.0, 0)
    with pytest.raises(IdentificationError, match="on a line"):
        register_frame(machine, Setup(None, setup.targets), data)


def test_full_pose_setup_gives_the_full_pose_result():
    nominal, true = preset("paper-hmt"), preset("paper-hmt-true")
    meas = simulate_measurements(nominal, true, poses(nominal, 40, 1), NoiseModel(), 2)
    ref = estimate(nominal, meas, "ml", with_bound=False)
    setup = Setup(np.zeros(6), tool=np.zeros(6), fixed=("instrument_frame", "tool"))
    out = identify_instrument(nominal, meas, setup, NoiseModel())
    assert out.gauges == () and out.result.names == ref.names
    # the orientation residual is a rotation vector, equal to the Euler difference to first order
    assert np.abs((out.result.values - ref.values) / ref.stderr).max() < 1e-2
    np.testing.assert_allclose(out.result.stderr, ref.stderr, rtol=1e-3)
    # with the Euler-angle residual it is the full-pose model exactly
    exact = identify_instrument(
        nominal, meas, setup, NoiseModel(), model=ToolModel(setup, orientation="euler")
    )
    # the same likelihood: equal to the solvers' tolerance (1e-6 of a standard error)
    assert np.abs((exact.result.values - ref.values) / ref.stderr).max() < 1e-5
    np.testing.assert_allclose(exact.result.stderr, ref.stderr, rtol=1e-6)
    np.testing.assert_allclose(exact.result.residuals, ref.residuals, atol=1e-6)


def test_fit_and_fix_accept_setup_groups(machines):
    nominal, true = machines
    true_setup, start = tracker_setups(3)
    data = simulate_target_measurements(nominal, true, true_setup, poses(nominal, 40, 1), None, 0.0, 2)
    params = instrument_parameters(nominal, start, fix=("frame", "t2.z"))
    assert not params.vary[params.index("frame.a")] and not params.vary[params.index("t2.z")]
    assert params.vary[params.index("t2.y")] and params.vary[params.index("u1.x")]
    held = instrument_parameters(
        nominal, Setup(None, start.targets, fixed=("targets",)), fit="joints,l0,targets"
    )
    assert not held.vary[48:].any()
    # targets known exactly: only the base gauge is left
    known = Setup(None, true_setup.targets, fixed=("targets",))
    out = identify_instrument(nominal, data, known)
    assert len(out.gauges) == 6 and all(g.startswith("base") for g in out.gauges)


def test_tool_with_unknown_frame_noise_free(machines):
    nominal, true = machines
    frame = np.array([1800.0, 2200.0, -500.0, 0.4, 0.9, -2.0])
    true_setup = Setup(frame, tool=[20.0, -10.0, 80.0, 0.05, -0.02, 0.3])
    data = simulate_tool_measurements(nominal, true, true_setup, poses(nominal, 30, 4), None, 0)
    start = Setup(None, tool=[22.0, -8.0, 78.0, 0.0, 0.0, 0.3])
    out = identify_instrument(nominal, data, start, NOISE)
    assert len(out.gauges) == 12
    held = simulate_tool_measurements(nominal, true, true_setup, poses(nominal, 20, 8), None, 0)
    check = validate_instrument(out.geometry, out.setup, held)
    assert check.max < 1e-6


def test_noisy_fit_is_consistent_with_its_bound(machines):
    nominal, true = machines
    true_setup, start_setup = tracker_setups(3)
    data = simulate_target_measurements(nominal, true, true_setup, poses(nominal, 80, 11), NOISE, 0.08, 12)
    out = identify_instrument(nominal, data, start_setup, NOISE)
    res = out.result
    # whitened residual variance ~ chi2(dof)/dof: 5 sigma band
    assert abs(res.reduced_chi2 - 1) < 5 * np.sqrt(2 / res.dof)
    # standard errors are s * bound (same projected Jacobian)
    np.testing.assert_allclose(res.stderr, np.sqrt(res.reduced_chi2) * res.bound, rtol=1e-6)
    assert out.setup.calibration["stderr"]["t1.x"] > 0
    assert out.registration is not None and out.registration.rms < 20
    # the bound at the truth agrees with the bound at the estimate to a few percent
    problem = Problem(nominal, data, TargetModel(out.setup))
    cov = model_cramer_rao(problem, NOISE)
    assert cov.shape == (len(res.names), len(res.names))
    assert np.median(np.sqrt(np.diag(cov))[:42] / res.bound[:42]) == pytest.approx(1, rel=0.05)


def test_too_few_poses_for_one_target_refused(machines):
    nominal, true = machines
    true_setup, start_setup = tracker_setups(1)
    data = simulate_target_measurements(nominal, true, true_setup, poses(nominal, 12, 1), None, 0.0, 2)
    with pytest.raises(IdentificationError):
        identify_instrument(nominal, data, start_setup, NOISE)


def test_model_bound_of_the_full_pose_model_is_the_existing_bound():
    from hexcal.estimation.uncertainty import cramer_rao_covariance, planned_measurements

    nominal = preset("paper-hmt")
    commanded = poses(nominal, 30, 3)
    data = planned_measurements(nominal, commanded)
    problem = Problem(nominal, data)
    noise = NoiseModel()
    ours = model_cramer_rao(problem, noise, problem.full0, commanded)
    ref = cramer_rao_covariance(nominal, commanded, noise, problem.machine_mask, data.readings)
    np.testing.assert_allclose(np.sqrt(np.diag(ours)), np.sqrt(np.diag(ref)), rtol=1e-6)
