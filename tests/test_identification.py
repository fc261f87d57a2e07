"""Identification: exact recovery without noise, analytic Jacobian, errors, and a coverage check."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy import stats

from hexcal.calibration.identify import estimate
from hexcal.core.kinematics import inverse_kinematics, leg_readings
from hexcal.core.machine import VARIANTS as METHODS
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import PARAMETER_NAMES, PARAMETER_SCALE, select_parameters
from hexcal.core.workspace import random_poses
from hexcal.errors import IdentificationError
from hexcal.estimation.uncertainty import identification_jacobian, identification_residuals
from hexcal.instruments.pose import Measurements

# true leg gains off by about 1e-3 (a leg moving 300 mm then errs by about 0.3 mm)
GAIN_ERRORS = 1e-3 * np.array([1.0, -1.0, 0.5, -0.5, 2.0, -1.5])
ALL_48 = select_parameters("joints,l0,gains")


@pytest.fixture
def true_with_gains(true_machine):
    return true_machine.replace(leg_gains=1 + GAIN_ERRORS)


# -- noise-free recovery ------------------------------------------------------------------


@pytest.mark.parametrize("method", METHODS)
def test_noise_free_identification_recovers_the_true_machine(
    nominal, true_machine, simulate, corner_poses, method
):
    data = simulate(nominal, true_machine, corner_poses)
    result = estimate(nominal, data, method, with_bound=False)
    assert result.names == PARAMETER_NAMES[:42]
    assert_allclose(result.values, true_machine.to_vector(), rtol=0, atol=1e-6)
    assert_allclose(
        result.geometry.to_vector(gains=True), true_machine.to_vector(gains=True), rtol=0, atol=1e-6
    )
    assert_array_equal(result.start_values, nominal.to_vector())
    assert result.rank == 42
    assert result.n_poses == 15
    assert result.leg_rms_before > 1.0  # mm: the nominal machine is millimetres off
    assert result.leg_rms_after < 1e-8
    assert result.status > 0
    # the identified geometry keeps everything that is not a parameter
    assert result.geometry.name == nominal.name
    assert_array_equal(result.geometry.workspace, nominal.workspace)


@pytest.mark.parametrize("method", METHODS)
def test_noise_free_identification_with_gains(nominal, true_with_gains, simulate, corner_poses, method):
    data = simulate(nominal, true_with_gains, corner_poses)
    result = estimate(nominal, data, method, ALL_48, with_bound=False)
    assert result.names == PARAMETER_NAMES
    assert_allclose(result.values[:42], true_with_gains.to_vector(), rtol=0, atol=1e-6)
    assert_allclose(result.values[42:], 1 + GAIN_ERRORS, rtol=0, atol=1e-9)
    assert_allclose(result.geometry.leg_gains, 1 + GAIN_ERRORS, rtol=0, atol=1e-9)


def test_noise_free_identification_with_an_extrinsic_convention(
    nominal, true_machine, simulate, corner_poses
):
    nominal, true_machine = nominal.replace(euler="zyx"), true_machine.replace(euler="zyx")
    data = simulate(nominal, true_machine, corner_poses)
    result = estimate(nominal, data, "length", with_bound=False)
    assert_allclose(result.values, true_machine.to_vector(), rtol=0, atol=1e-6)


def test_fixed_parameters_keep_their_start_values(nominal, true_machine, simulate, corner_poses):
    data = simulate(nominal, true_machine, corner_poses)
    start = nominal.with_vector(true_machine.to_vector())  # start at the truth, fix u1.x there
    mask = select_parameters(fix=("u1.x",))
    result = estimate(start, data, "length", mask, with_bound=False)
    assert "u1.x" not in result.names
    assert len(result.names) == 41
    assert result.geometry.base_joints[0, 0] == true_machine.base_joints[0, 0]


# -- the analytic Jacobian ---------------------------------------------------------------


def _numeric_identification_jacobian(geometry, data, method, mask):
    base = geometry.to_vector(gains=True)
    cols = []
    for k in np.flatnonzero(mask):
        h = 1e-4 * PARAMETER_SCALE[k]  # 1e-4 mm, or 1e-7 of gain
        plus, minus = base.copy(), base.copy()
        plus[k] += h
        minus[k] -= h
        diff = identification_residuals(geometry.with_vector(plus), data, method) - identification_residuals(
            geometry.with_vector(minus), data, method
        )
        cols.append(diff.ravel() / (2 * h))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("gains", [False, True], ids=["42", "48"])
def test_identification_jacobian_equals_central_differences(
    nominal, true_with_gains, simulate, method, gains
):
    data = simulate(nominal, true_with_gains, random_poses(nominal, 10, 3))
    # evaluate away from the solution and with gains not 1, so every term matters
    geometry = true_with_gains.with_vector(
        true_with_gains.to_vector(gains=True) + 0.5 * np.sin(np.arange(48)) * PARAMETER_SCALE
    )
    mask = ALL_48 if gains else None
    analytic = identification_jacobian(geometry, data, method, mask=mask)
    assert analytic.shape == (60, 48 if gains else 42)
    numeric = _numeric_identification_jacobian(
        geometry, data, method, ALL_48 if gains else select_parameters()
    )
    scale = np.max(np.abs(analytic), axis=0)
    assert np.all(np.abs(numeric - analytic) <= 1e-6 * scale)


def test_identification_residuals_units(nominal, true_machine, simulate, corner_poses):
    data = simulate(nominal, true_machine, corner_poses)
    length = identification_residuals(nominal, data, "length")
    paper = identification_residuals(nominal, data, "paper")
    assert length.shape == paper.shape == (15, 6)
    # |v|^2 - l^2 = (|v| - l)(|v| + l): the paper residual is about 2 l times the length residual
    model = nominal.initial_leg_lengths + data.readings
    assert_allclose(paper, length * (2 * model + length), rtol=1e-9)
    assert np.all(np.abs(identification_residuals(true_machine, data, "length")) < 1e-9)
    with pytest.raises(ValueError, match="method"):
        identification_residuals(nominal, data, "squared")


# -- errors -------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [3, 6])
def test_too_few_poses(nominal, true_machine, simulate, corner_poses, n):
    data = simulate(nominal, true_machine, corner_poses[:n])
    with pytest.raises(IdentificationError, match="poses"):
        estimate(nominal, data, "paper", with_bound=False)


def test_seven_poses_are_too_few_with_gains_and_exactly_determined_without(
    nominal, true_machine, simulate, corner_poses
):
    data = simulate(nominal, true_machine, corner_poses[:7])
    with pytest.raises(IdentificationError, match="poses"):
        estimate(nominal, data, "paper", ALL_48, with_bound=False)
    # 42 equations for 42 parameters: exactly determined (the smallest campaign of a pose-count
    # study). The fit solves the equations exactly, though not necessarily at the true
    # parameters (seven equations in seven unknowns per leg can have several roots); there is
    # no residual to estimate the noise from, so the standard errors are NaN, not made up
    result = estimate(nominal, data, "length", with_bound=False)
    assert result.leg_rms_after < 1e-9
    assert np.all(np.isnan(result.stderr))
    with pytest.raises(IdentificationError, match="poses"):
        estimate(nominal, data.subset(np.arange(6)), "paper", with_bound=False)


def test_poses_without_rotation_are_rank_deficient(true_machine):
    # measured poses that never rotate: only s_i - u_i enters the leg vectors, so u_i and s_i
    # cannot be told apart (the data are exact for the true machine, so this is not noise)
    poses = random_poses(true_machine, 20, 5)
    poses[:, 3:] = 0.0
    readings = leg_readings(true_machine, inverse_kinematics(true_machine, poses))
    with pytest.raises(IdentificationError, match="rank-deficient"):
        estimate(true_machine, Measurements(poses, readings), "paper", with_bound=False)
    with pytest.raises(IdentificationError, match="rank-deficient"):
        estimate(true_machine, Measurements(poses, readings), "length", with_bound=False)


def test_commanded_poses_without_rotation_still_identify(nominal, true_machine, simulate):
    # commanding no rotation is not enough to be rank-deficient: the true machine, driven by the
    # nominal controller, does rotate (by several degrees), and the measured poses show it
    poses = random_poses(nominal, 20, 5)
    poses[:, 3:] = 0.0
    data = simulate(nominal, true_machine, poses)
    assert np.max(np.abs(data.poses[:, 3:])) > np.deg2rad(1)
    result = estimate(nominal, data, "length", with_bound=False)
    assert result.rank == 42


def test_bad_method_and_mask(nominal, true_machine, simulate, corner_poses):
    data = simulate(nominal, true_machine, corner_poses)
    with pytest.raises(ValueError, match="method"):
        estimate(nominal, data, "squared", with_bound=False)
    with pytest.raises(ValueError, match=r"\(48,\)"):
        estimate(nominal, data, "paper", np.ones(42, dtype=bool), with_bound=False)


def test_identification_error_is_a_value_error():
    assert issubclass(IdentificationError, ValueError)


# -- statistics -----------------------------------------------------------------------------


def test_noisy_identification_result_schema(nominal, true_machine, simulate, corner_poses):
    data = simulate(nominal, true_machine, corner_poses, NoiseModel(), rng=11)
    result = estimate(nominal, data, "paper", with_bound=False)
    n = 42
    assert result.values.shape == result.stderr.shape == (n,)
    assert result.covariance.shape == result.correlation.shape == (n, n)
    assert_allclose(result.covariance, result.covariance.T, rtol=1e-10, atol=0)
    assert_allclose(np.sqrt(np.diag(result.covariance)), result.stderr)
    assert_allclose(np.diag(result.correlation), 1.0)
    assert np.all(np.abs(result.correlation) <= 1 + 1e-9)
    assert np.all(result.stderr > 0)
    assert result.singular_values.shape == (n,)
    assert np.all(np.diff(result.singular_values) <= 0)
    assert result.residuals.shape == (15, 6)
    assert result.rms_after < result.rms_before
    assert result.leg_rms_after < result.leg_rms_before
    assert result.cost == pytest.approx(0.5 * np.sum(result.residuals**2))
    assert set(result.parameters) == set(result.standard_errors) == set(PARAMETER_NAMES[:42])
    meta = result.calibration_metadata()
    assert meta["method"] == "paper"
    assert meta["poses"] == 15
    assert meta["stderr"]["u1.x"] == result.stderr[0]
    # with the paper's noise this data set gets every parameter within 1.4 mm (mean 0.24 mm) of
    # the truth and within 1.6 standard errors of it
    error = np.abs(result.values - true_machine.to_vector())
    assert error.max() < 2.0
    assert error.mean() < 0.5
    assert np.all(error <= 4 * result.stderr)


def test_standard_errors_cover_the_truth(nominal, true_machine, simulate, corner_poses):
    """Over 200 noisy data sets, |estimate - true| <= 2 stderr for about 95 % of the estimates.

    Expected fraction: 0.9545 (P(|Z| <= 2)) if the standard errors were exact. The stderr uses
    the residual variance with 6 * 15 - 42 = 48 degrees of freedom, so in the linear model
    (estimate - true) / stderr is Student-t with 48 dof: P(|t| <= 2) = 0.9488, the reference here.
    A known model difference remains: the six leg residuals of a pose share that pose's
    measurement noise, which the covariance (independent residuals, as curve_fit) ignores;
    with 3000 data sets (seed 1) the fraction is 0.9423 +- 0.0013, so 0.007 is allowed for it.

    Tolerance: 200 x 42 = 8400 indicators; if they were independent the binomial standard
    deviation of their mean would be sqrt(0.95 * 0.05 / 8400) = 0.0023. They are not: the 42
    estimates of one data set are strongly correlated (the joint coordinates of one leg, its
    l0...), which at the worst (all 42 move together) would give sqrt(0.95 * 0.05 / 200) =
    0.0147. The data sets themselves are independent, so the standard deviation is measured from
    the spread of the per-data-set fractions (about 0.005, a design effect of about 5, between
    those two bounds) and the test allows 4 of them plus the 0.007 above (~0.03 in all).
    """
    noise = NoiseModel(distribution="normal")  # the paper's magnitudes as standard deviations
    truth = true_machine.to_vector()
    estimates, stderrs = [], []
    for child in np.random.SeedSequence(2009).spawn(200):
        data = simulate(nominal, true_machine, corner_poses, noise, rng=np.random.default_rng(child))
        result = estimate(nominal, data, "length", with_bound=False)
        estimates.append(result.values)
        stderrs.append(result.stderr)
    estimates, stderrs = np.array(estimates), np.array(stderrs)
    covered = np.abs(estimates - truth) <= 2 * stderrs
    per_dataset = covered.mean(axis=1)
    sd = per_dataset.std(ddof=1) / np.sqrt(len(per_dataset))
    assert np.sqrt(0.95 * 0.05 / 8400) <= sd <= np.sqrt(0.95 * 0.05 / 200)
    expected_t = 2 * stats.t.cdf(2.0, df=6 * 15 - 42) - 1
    assert expected_t == pytest.approx(0.9488, abs=1e-4)
    assert abs(covered.mean() - expected_t) <= 4 * sd + 0.007
    # and the Monte Carlo spread matches the predicted standard errors: the ratio of the two
    # estimates a standard deviation to ~5 % (200 samples); with 3000 data sets the ratios lie
    # in 0.88..1.11 (the correlated residuals above), so allow 0.75..1.3 per parameter
    ratio = estimates.std(axis=0, ddof=1) / np.sqrt(np.mean(stderrs**2, axis=0))
    assert np.median(ratio) == pytest.approx(1.0, abs=0.1)
    assert np.all((ratio > 0.75) & (ratio < 1.3))


def test_measurements_validation():
    poses = np.zeros((3, 6))
    with pytest.raises(ValueError, match="shape"):
        Measurements(poses, np.zeros((3, 5)))
    bad = poses.copy()
    bad[1, 2] = np.nan
    with pytest.raises(ValueError, match="row 2"):
        Measurements(bad, np.zeros((3, 6)))
    data = Measurements(poses, np.zeros((3, 6)))
    assert data.ids == ("1", "2", "3")
    assert len(data.subset([0, 2])) == 2
    assert data.subset([0, 2]).ids == ("1", "3")
    assert not data.poses.flags.writeable
