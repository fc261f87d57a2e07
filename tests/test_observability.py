"""Observability indices, identifiability and predicted accuracy (design: indices, accuracy).

Provenance of the reference values:
- O1-O5 follow their definitions (Sun & Hollerbach 2008, doi:10.1109/ROBOT.2008.4543242)
  on Jacobians built from chosen singular values;
- a pose set that never rotates sees each leg only through ``o + s_i - u_i``, so moving
  ``s_i`` and ``u_i`` together (3 directions per leg) is invisible: 18 of the 42 joint and
  l0 parameters are lost (rank 24);
- the least-squares covariance is the textbook sandwich of an unweighted linear
  estimator with correlated residuals; the Cramér-Rao bound never exceeds it (GLS is
  the best linear unbiased estimator).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from hexcal.calibration import estimate, pose_error_map, predicted_pose_errors, rotation_vector_map
from hexcal.core import (
    PARAMETER_NAMES,
    NoiseModel,
    forward_kinematics,
    inverse_kinematics,
    select_parameters,
    workspace_corners,
)
from hexcal.design import (
    analyse_poses,
    column_scales,
    format_combination,
    least_squares_covariance,
    mean_abs_error,
    null_space,
    numerical_rank,
    observability_indices,
    planning_jacobian,
    unidentifiable_combinations,
)
from hexcal.errors import IdentificationError
from hexcal.estimation import cramer_rao_covariance, residual_covariances

NAMES42 = PARAMETER_NAMES[:42]


def jacobian_with_singular_values(sv, rows, seed=0):
    """A (rows, len(sv)) matrix with exactly the singular values ``sv``."""
    rng = np.random.default_rng(seed)
    n = len(sv)
    u, _ = np.linalg.qr(rng.normal(size=(rows, n)))
    v, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return u @ np.diag(sv) @ v.T


# -- indices on hand-built Jacobians ----------------------------------------------------------


def test_indices_of_known_singular_values():
    jac = jacobian_with_singular_values([4.0, 2.0, 1.0], rows=10)
    ind = observability_indices(jac, scaling="none")
    assert_allclose(ind.singular_values, [4, 2, 1], rtol=1e-12)
    assert ind.O1 == pytest.approx(2.0)  # (4·2·1)^(1/3)
    assert ind.O2 == pytest.approx(0.25)
    assert ind.O3 == pytest.approx(1.0)
    assert ind.O4 == pytest.approx(0.25)  # 1² / 4
    assert ind.O5 == pytest.approx(1 / 1.75)  # 1 / (1/4 + 1/2 + 1)
    assert ind.condition_number == pytest.approx(4.0)
    assert ind.rank == 3


def test_fewer_rows_than_columns_gives_zero_singular_values():
    jac = np.random.default_rng(1).normal(size=(2, 4))
    ind = observability_indices(jac, scaling="none")
    assert ind.singular_values.shape == (4,)
    assert ind.singular_values[-1] == 0
    assert ind.O1 == ind.O3 == ind.O4 == ind.O5 == 0.0
    assert ind.condition_number == np.inf
    assert ind.rank == 2


def test_norm_scaling_makes_every_index_invariant_under_column_scaling():
    jac = np.random.default_rng(2).normal(size=(30, 6))
    scale = np.array([1e-3, 0.5, 2.0, 10.0, 300.0, 1.0])
    a = observability_indices(jac, "norm")
    b = observability_indices(jac * scale, "norm")
    for key in ("O1", "O2", "O3", "O4", "O5", "condition_number"):
        assert getattr(b, key) == pytest.approx(getattr(a, key), rel=1e-10)


def test_unscaled_o1_changes_by_the_determinant_and_the_others_change_otherwise():
    jac = np.random.default_rng(3).normal(size=(30, 6))
    scale = np.array([1e-3, 0.5, 2.0, 10.0, 300.0, 1.0])
    a = observability_indices(jac, "none")
    b = observability_indices(jac * scale, "none")
    # D-optimality ranks pose sets the same in any parameter units
    assert b.O1 == pytest.approx(a.O1 * np.prod(scale) ** (1 / 6), rel=1e-10)
    for key in ("O2", "O3", "O4", "O5"):
        assert getattr(b, key) != pytest.approx(getattr(a, key), rel=0.05)


def test_row_scaling():
    jac = np.random.default_rng(4).normal(size=(20, 5))
    a = observability_indices(jac, "none")
    b = observability_indices(3.0 * jac, "none")
    for key in ("O1", "O3", "O4", "O5"):
        assert getattr(b, key) == pytest.approx(3 * getattr(a, key), rel=1e-10)
    assert b.O2 == pytest.approx(a.O2, rel=1e-10)


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 8), st.integers(0, 10_000))
def test_index_inequalities(n, seed):
    jac = np.random.default_rng(seed).normal(size=(3 * n, n))
    ind = observability_indices(jac, "none")
    assert ind.O5 <= ind.O3 * (1 + 1e-12)  # 1/Σ(1/σ) <= σmin
    assert ind.O5 >= ind.O3 / n * (1 - 1e-12)
    assert ind.O3 <= ind.O1 * (1 + 1e-12) <= ind.singular_values[0] * (1 + 1e-12)
    assert ind.O4 == pytest.approx(ind.O2 * ind.O3)


def test_parameter_scaling_and_bad_arguments():
    jac = np.ones((4, 2))
    assert_allclose(column_scales(jac, "parameter", [1.0, 1e-3]), [1.0, 1e-3])
    with pytest.raises(ValueError, match="scaling"):
        column_scales(jac, "columns")
    with pytest.raises(ValueError, match="shape"):
        column_scales(jac, "parameter", [1.0])
    with pytest.raises(ValueError, match=r"\(r, n\)"):
        column_scales(np.ones(3))


def test_null_space_names_a_hand_built_dependency():
    # column 2 = column 0 + column 1: the change (1, 1, -1) is invisible
    rng = np.random.default_rng(5)
    base = rng.normal(size=(10, 2))
    jac = np.column_stack([base, base.sum(axis=1)])
    assert numerical_rank(jac) == 2
    combos = unidentifiable_combinations(jac, ["p", "q", "r"])
    assert combos == ["p + q - r"]
    assert_allclose(jac @ null_space(jac)[0], 0, atol=1e-12)


def test_format_combination():
    assert format_combination([0, 2.0, -1.0], ["a", "b", "c"]) == "b - 0.5·c"
    assert format_combination([-1.0, 0, 1.0], ["a", "b", "c"]) == "a - c"
    assert format_combination([0, -0.5, -1.0], ["a", "b", "c"]) == "0.5·b + c"


# -- the hexapod ------------------------------------------------------------------------------------


def test_poses_that_never_rotate_lose_eighteen_combinations(nominal):
    poses = workspace_corners(nominal)[::4].copy()
    poses[:, 3:] = 0.0
    analysis = analyse_poses(nominal, poses, test_poses=workspace_corners(nominal))
    assert analysis.rank == 24
    expected = {f"u{i}.{ax} + s{i}.{ax}" for i in range(1, 7) for ax in "xyz"}
    assert set(analysis.unidentifiable) == expected
    assert len(analysis.unidentifiable) == 18
    # u and s are lost, l0 is not
    assert analysis.not_identifiable[:36].all() and not analysis.not_identifiable[36:].any()
    assert np.isinf(analysis.std_estimator[:36]).all()
    assert np.isfinite(analysis.std_estimator[36:]).all()
    assert np.isinf(analysis.mean_error_estimator)
    # rotated test poses see the lost combinations: their error is unbounded
    assert np.isinf(analysis.test_position_rms).any()


def test_identify_refuses_the_set_the_analysis_calls_rank_deficient(nominal):
    # measurements exactly at the planned poses (a real machine's small tilts would make
    # the Jacobian numerically full rank but useless)
    from hexcal.estimation import planned_measurements

    poses = workspace_corners(nominal)[::4].copy()
    poses[:, 3:] = 0.0
    with pytest.raises(IdentificationError, match="rank"):
        estimate(nominal, planned_measurements(nominal, poses), "length", with_bound=False)


def test_corners_identify_everything_with_and_without_gains(nominal, corner_poses):
    analysis = analyse_poses(nominal, corner_poses)
    assert analysis.rank == 42 and analysis.unidentifiable == []
    with_gains = analyse_poses(nominal, corner_poses, mask=select_parameters("joints,l0,gains"))
    assert with_gains.rank == 48
    assert with_gains.names[-6:] == tuple(f"g{i}" for i in range(1, 7))


def test_weighted_indices_and_scalings_agree_on_rank(nominal, corner_poses):
    for scaling in ("norm", "parameter", "none"):
        for weighted in (False, True):
            analysis = analyse_poses(nominal, corner_poses, scaling=scaling, weighted=weighted)
            assert analysis.rank == 42
            assert analysis.indices.scaling == scaling


def test_pose_error_map_matches_forward_kinematics_to_first_order(nominal):
    poses = workspace_corners(nominal)[[0, 21, 42, 63]]
    delta = np.random.default_rng(6).uniform(-0.1, 0.1, 42)
    readings = inverse_kinematics(nominal, poses) - nominal.initial_leg_lengths
    emap = pose_error_map(nominal, poses)
    remainders = []
    for step in (1.0, 0.5):
        perturbed = nominal.with_vector(nominal.to_vector() + step * delta)
        reached = forward_kinematics(perturbed, perturbed.initial_leg_lengths + readings, guess=poses)
        assert reached.all_converged
        exact = reached.poses - poses
        remainders.append(np.max(np.abs(exact - emap @ (step * delta))))
        assert remainders[-1] < 1e-2 * np.max(np.abs(exact))
    # the remainder of a correct first-order map is quadratic: halving δ quarters it
    assert 3.0 < remainders[0] / remainders[1] < 5.0
    assert pose_error_map(nominal, poses.reshape(2, 2, 6)).shape == (2, 2, 6, 42)


def test_rotation_vector_map_is_identity_at_zero_angles(nominal):
    assert_allclose(rotation_vector_map(nominal, [0, 0, 800, 0, 0, 0]), np.eye(3), atol=1e-15)


def test_least_squares_covariance_matches_linear_monte_carlo(nominal, corner_poses):
    """The sandwich formula against noise pushed through the linearised estimator."""
    noise = NoiseModel()
    cov = least_squares_covariance(nominal, corner_poses, noise)
    a = planning_jacobian(nominal, corner_poses)
    c = residual_covariances(nominal, corner_poses, noise)
    chol = np.linalg.cholesky(c)  # (m, 6, 6)
    rng = np.random.default_rng(7)
    draws = np.einsum("mij,tmj->tmi", chol, rng.normal(size=(4000, len(corner_poses), 6)))
    estimates = np.linalg.lstsq(a, draws.reshape(4000, -1).T, rcond=None)[0].T
    empirical = np.cov(estimates.T)
    # 4000 draws: standard deviations within a few per cent
    assert_allclose(np.sqrt(np.diag(empirical)), np.sqrt(np.diag(cov)), rtol=0.06)


def test_bound_never_exceeds_the_estimator_covariance(nominal, corner_poses):
    cov = least_squares_covariance(nominal, corner_poses)
    bound = cramer_rao_covariance(nominal, corner_poses)
    gap = np.linalg.eigvalsh(cov - bound)
    assert gap.min() > -1e-9 * gap.max()
    assert mean_abs_error(bound) < mean_abs_error(cov)


def test_paper_residual_covariance_is_close_to_the_length_residual(nominal, corner_poses):
    # the squared residual weights each row by 2 l_ij, nearly constant over a box
    length = mean_abs_error(least_squares_covariance(nominal, corner_poses, method="length"))
    paper = mean_abs_error(least_squares_covariance(nominal, corner_poses, method="paper"))
    assert paper == pytest.approx(length, rel=0.2)
    with pytest.raises(ValueError, match="method"):
        least_squares_covariance(nominal, corner_poses, method="ml")


def test_predicted_pose_errors_match_sampled_parameter_errors(nominal, corner_poses):
    cov = least_squares_covariance(nominal, corner_poses)
    test = workspace_corners(nominal)[:8]
    pos, rot = predicted_pose_errors(nominal, test, cov)
    rng = np.random.default_rng(8)
    draws = rng.multivariate_normal(np.zeros(42), cov, size=20_000)
    moved = np.einsum("tip,dp->tdi", pose_error_map(nominal, test), draws)
    omega = np.einsum("tij,tdj->tdi", rotation_vector_map(nominal, test), moved[..., 3:])
    assert_allclose(pos, np.sqrt(np.mean(np.sum(moved[..., :3] ** 2, -1), axis=1)), rtol=0.03)
    assert_allclose(rot, np.sqrt(np.mean(np.sum(omega**2, -1), axis=1)), rtol=0.03)


def test_mean_abs_error_leaves_gains_out():
    mask = select_parameters("l0,gains")
    cov = np.diag([1.0] * 6 + [1e6] * 6)
    assert mean_abs_error(cov, mask) == pytest.approx(np.sqrt(2 / np.pi))


def test_predicted_error_matches_identify_by_monte_carlo(nominal, true_machine, corner_poses):
    """200 identifications (method 'length') of the same 15 corners on paper-hmt-true.

    The machine's errors (up to 5 mm) take it up to 63 mm and 0.11 rad away from the
    commanded corners; predicted at the poses it really reaches, the sandwich covariance
    gives the Monte Carlo mean error within its standard error (about 2 % with 200 trials).
    """
    from hexcal.simulation import simulate_measurements

    reached = simulate_measurements(nominal, true_machine, corner_poses, NoiseModel(0, 0, 0)).poses
    predicted = mean_abs_error(least_squares_covariance(true_machine, reached))
    truth = true_machine.to_vector()
    errors = []
    for child in np.random.SeedSequence(9).spawn(200):
        data = simulate_measurements(nominal, true_machine, corner_poses, rng=np.random.default_rng(child))
        errors.append(np.mean(np.abs(estimate(nominal, data, "length", with_bound=False).values - truth)))
    assert np.mean(errors) == pytest.approx(predicted, rel=0.05)


def test_analysis_to_dict_is_json_ready_and_has_the_cli_schema(nominal, corner_poses):
    """``to_dict`` holds what ``hexcal observability --json`` writes; inf stays a float."""
    import json

    corners = workspace_corners(nominal)
    analysis = analyse_poses(nominal, corner_poses, test_poses=corners)
    data = analysis.to_dict()
    json.dumps(data)
    assert list(data)[:4] == ["n_poses", "n_parameters", "rank", "scaling"]
    assert data["rank"] == 42 and data["n_parameters"] == 42 and data["unidentifiable"] == []
    assert data["O1"] == analysis.indices.O1
    assert data["singular_values"] == analysis.indices.singular_values.tolist()
    assert data["predicted_mean_abs_error_mm"]["estimator"] == analysis.mean_error_estimator
    assert data["parameters"]["u1.x"]["std_bound"] == analysis.std_bound[0]
    assert data["test_poses"]["n"] == 64
    assert data["test_poses"]["position_rms_max_mm"] == float(np.max(analysis.test_position_rms))
    flat = corners.copy()
    flat[:, 3:] = 0.0
    lost = analyse_poses(nominal, flat).to_dict()
    assert "test_poses" not in lost and lost["rank"] == 24
    assert lost["predicted_mean_abs_error_mm"]["estimator"] == np.inf
    assert data["scaling"] == analysis.indices.to_dict()["scaling"]
