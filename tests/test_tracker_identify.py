"""Identification with instrument setups: registration, gauges, recovery, equivalence."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conftest import simulate_measurements
from hexcal.calibration import estimate, validate
from hexcal.core.noise import NoiseModel
from hexcal.core.presets import preset
from hexcal.errors import IdentificationError
from hexcal.estimation import cramer_rao, problem_parameters
from hexcal.estimation.gauge import apply_convention, gauge_freedoms
from hexcal.estimation.problem import Problem
from hexcal.instruments import Session, ToolModel
from hexcal.instruments.registration import register_targets
from hexcal.instruments.setup import Setup
from hexcal.instruments.targets import TargetModel
from tracker_cases import general_machines, identify, poses, simulate, tracker_setups

NOISE = NoiseModel(leg=0.005, position=0.015, orientation=2e-5, distribution="normal")


@pytest.fixture(scope="module")
def machines():
    return general_machines()


@pytest.mark.parametrize("n_targets", [1, 3])
def test_noise_free_recovery_up_to_the_gauge(machines, n_targets):
    nominal, true = machines
    true_setup, start_setup = tracker_setups(n_targets)
    data = simulate(nominal, true, true_setup, poses(nominal, 50, 1), None, 0.1, 2)
    lost = np.isnan(data.targets[..., 0]).sum() + n_targets * (50 - len(data))
    assert 0 < lost < 0.2 * 50 * n_targets
    r = identify(nominal, data, start_setup, NOISE)
    assert len(r.gauges) == 12 and r.rank == len(r.names) - 12
    held = simulate(nominal, true, true_setup, poses(nominal, 40, 9), None, 0.0, 3)
    check = validate(r.geometry, Session(held, r.instruments[0]))
    errors = check.instrument_errors["target"]  # every target seen: a NaN fails
    assert errors.shape == (40, n_targets) and errors.max() < 1e-6  # gauge-invariant predictions, mm
    # the gauge-fixed parameters are the true machine moved to the convention's frames
    problem = Problem(nominal, data, TargetModel(true_setup))
    full_true = np.concatenate([true.to_vector(gains=True), true_setup.vector()])
    fixed_true = apply_convention(problem, full_true, gauge_freedoms(problem, problem.full0))
    got = np.concatenate([r.geometry.to_vector(gains=True), r.instruments[0].setup.vector()])
    np.testing.assert_allclose(got[:42], fixed_true[:42], atol=1e-5)


@pytest.mark.parametrize("seed", range(5))
def test_registration_from_an_arbitrary_frame(seed):
    machine = preset("paper-hmt")
    rng = np.random.default_rng(seed)
    angles = Rotation.random(random_state=seed).as_euler("XYZ")
    frame = np.concatenate([rng.uniform(-5000, 5000, 3), angles])
    setup = Setup(frame, {"t1": [10.0, 20.0, 60.0]})
    data = simulate(machine, machine, setup, poses(machine, 20, seed), None, 0.0, seed)
    reg = register_targets(machine, Setup(None, setup.targets), data)
    assert reg.rms < 1e-6 and reg.points == 20
    np.testing.assert_allclose(reg.frame[:3], frame[:3], atol=1e-6)
    rel = Rotation.from_euler("XYZ", reg.frame[3:]).inv() * Rotation.from_euler("XYZ", frame[3:])
    assert rel.magnitude() < 1e-9


def test_registration_refuses_collinear_points():
    machine = preset("paper-hmt")
    setup = Setup(np.zeros(6), {"t1": [0.0, 0.0, 0.0]})
    line = np.zeros((10, 6))
    line[:, 2] = np.linspace(720, 880, 10)
    data = simulate(machine, machine, setup, line, None, 0.0, 0)
    with pytest.raises(IdentificationError, match="on a line"):
        register_targets(machine, Setup(None, setup.targets), data)


def test_full_pose_setup_gives_the_full_pose_result():
    nominal, true = preset("paper-hmt"), preset("paper-hmt-true")
    meas = simulate_measurements(nominal, true, poses(nominal, 40, 1), NoiseModel(), 2)
    ref = estimate(nominal, meas, "ml", noise=NoiseModel(), with_bound=False)
    setup = Setup(np.zeros(6), tool=np.zeros(6), fixed=("instrument_frame", "tool"))
    r = identify(nominal, meas, setup, NoiseModel())  # ToolModel(setup): the rotation-vector residual
    assert r.gauges == () and r.names == ref.names
    # the orientation residual is a rotation vector, equal to the Euler difference to first order
    assert np.abs((r.values - ref.values) / ref.stderr).max() < 1e-2
    np.testing.assert_allclose(r.stderr, ref.stderr, rtol=1e-3)
    # with the Euler-angle residual it is the full-pose model exactly
    exact = estimate(
        nominal, Session(meas, ToolModel(setup, orientation="euler")), "ml", noise=NoiseModel(), verdict=False
    )
    # the same likelihood: equal to the solvers' tolerance (1e-6 of a standard error)
    assert np.abs((exact.values - ref.values) / ref.stderr).max() < 1e-5
    np.testing.assert_allclose(exact.stderr, ref.stderr, rtol=1e-6)
    np.testing.assert_allclose(exact.residuals, ref.residuals, atol=1e-6)


def test_fit_and_fix_accept_setup_groups(machines):
    nominal, true = machines
    true_setup, start = tracker_setups(3)
    data = simulate(nominal, true, true_setup, poses(nominal, 40, 1), None, 0.0, 2)
    params = problem_parameters(nominal, [Session(data, TargetModel(start))], fix=("frame", "t2.z"))
    assert not params.vary[params.index("frame.a")] and not params.vary[params.index("t2.z")]
    assert params.vary[params.index("t2.y")] and params.vary[params.index("u1.x")]
    held = problem_parameters(
        nominal, [Session(data, TargetModel(Setup(None, start.targets, fixed=("targets",))))], fit="joints,l0"
    )
    # the setup holds its targets; the frame (auto) still varies
    assert not held.vary[54:].any() and held.vary[48:54].all()
    # targets known exactly: only the base gauge is left
    known = Setup(None, true_setup.targets, fixed=("targets",))
    r = identify(nominal, data, known)
    assert len(r.gauges) == 6 and all(g.startswith("base") for g in r.gauges)


def test_tool_with_unknown_frame_noise_free(machines):
    nominal, true = machines
    frame = np.array([1800.0, 2200.0, -500.0, 0.4, 0.9, -2.0])
    true_setup = Setup(frame, tool=[20.0, -10.0, 80.0, 0.05, -0.02, 0.3])
    data = simulate(nominal, true, true_setup, poses(nominal, 30, 4), None, seed=0)
    start = Setup(None, tool=[22.0, -8.0, 78.0, 0.0, 0.0, 0.3])
    r = identify(nominal, data, start, NOISE)
    assert len(r.gauges) == 12
    held = simulate(nominal, true, true_setup, poses(nominal, 20, 8), None, seed=0)
    check = validate(r.geometry, Session(held, r.instruments[0]))
    assert check.instrument_errors["position"].max() < 1e-6  # tool position error, mm


def test_noisy_fit_is_consistent_with_its_bound(machines):
    nominal, true = machines
    true_setup, start_setup = tracker_setups(3)
    data = simulate(nominal, true, true_setup, poses(nominal, 80, 11), NOISE, 0.08, 12)
    res = identify(nominal, data, start_setup, NOISE)
    # whitened residual variance ~ chi2(dof)/dof: 5 sigma band
    assert abs(res.reduced_chi2 - 1) < 5 * np.sqrt(2 / res.dof)
    # standard errors are s * bound (same projected Jacobian)
    np.testing.assert_allclose(res.stderr, np.sqrt(res.reduced_chi2) * res.bound, rtol=1e-6)
    assert res.calibrated_instruments()[0].setup.calibration["stderr"]["t1.x"] > 0
    assert res.registrations[0] is not None and res.registrations[0].rms < 20
    # the bound at the truth agrees with the bound at the estimate to a few percent
    problem = Problem(nominal, data, TargetModel(res.instruments[0].setup))
    cov = cramer_rao(problem, NOISE)
    assert cov.shape == (len(res.names), len(res.names))
    assert np.median(np.sqrt(np.diag(cov))[:42] / res.bound[:42]) == pytest.approx(1, rel=0.05)


def test_too_few_poses_for_one_target_refused(machines):
    nominal, true = machines
    true_setup, start_setup = tracker_setups(1)
    data = simulate(nominal, true, true_setup, poses(nominal, 12, 1), None, 0.0, 2)
    with pytest.raises(IdentificationError):
        identify(nominal, data, start_setup, NOISE)


def test_model_bound_of_the_full_pose_model_is_the_existing_bound():
    from hexcal.estimation.uncertainty import cramer_rao_covariance, planned_measurements

    nominal = preset("paper-hmt")
    commanded = poses(nominal, 30, 3)
    data = planned_measurements(nominal, commanded)
    problem = Problem(nominal, data)
    noise = NoiseModel()
    ours = cramer_rao(problem, noise, problem.full0, commanded)
    ref = cramer_rao_covariance(nominal, commanded, noise, problem.machine_mask, data.readings)
    np.testing.assert_allclose(np.sqrt(np.diag(ours)), np.sqrt(np.diag(ref)), rtol=1e-6)
