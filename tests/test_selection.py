"""Candidate poses, feasibility and optimal pose selection (hexcal.design).

Provenance: the criteria follow their definitions on eigenvalues of the information
matrix; greedy and exchange are checked against brute force (every candidate's
information evaluated directly); the leg length limits of paper-hmt are 604.8652 and
1100 mm (shared/reference/paper-hmt.md), and its Gough-Stewart geometry is singular at
the rotation ``c = 90°`` about the vertical axis.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from hexcal.core import (
    PARAMETER_SCALE,
    NoiseModel,
    box_corners,
    random_interior,
    select_parameters,
    workspace_box,
    workspace_corners,
)
from hexcal.design import (
    CRITERIA,
    GREEDY_RIDGE,
    MIN_SINGULARITY_DISTANCE,
    boundary_grid,
    candidate_poses,
    check_feasibility,
    criterion_value,
    exchange_selection,
    greedy_selection,
    information_blocks,
    information_matrix,
    least_squares_covariance,
    mean_abs_error,
    random_subsets,
    select_poses,
    singularity_distance,
)
from hexcal.errors import SelectionError
from hexcal.estimation import fisher_information


def random_blocks(n_cand=60, rows=3, p=8, seed=0):
    return np.random.default_rng(seed).normal(size=(n_cand, rows, p))


def brute_force_greedy(blocks, n, criterion):
    """Greedy selection by evaluating every candidate's information directly."""
    n_cand, _, p = blocks.shape
    scale = np.einsum("mij,mij->", blocks, blocks) / (n_cand * p)
    chosen: list[int] = []
    info = np.zeros((p, p))
    for _ in range(n):
        lam = np.linalg.eigvalsh(info)
        full = lam[-1] > 0 and lam[0] > 1e-10 * lam[-1]
        ridge = 0.0 if full else GREEDY_RIDGE * scale
        crit = criterion if full or criterion in ("D", "A") else "D"
        trial = info + ridge * np.eye(p) + np.einsum("mji,mjk->mik", blocks, blocks)
        values = np.asarray(criterion_value(trial, crit))
        values[chosen] = -np.inf
        j = int(np.argmax(values))
        chosen.append(j)
        info = info + blocks[j].T @ blocks[j]
    return np.array(chosen)


# -- candidates and feasibility ---------------------------------------------------------------


def test_box_corners_match_the_kinematics_corners(nominal):
    assert_array_equal(box_corners(nominal.workspace), workspace_corners(nominal))


def test_boundary_grid_counts_and_membership(nominal):
    box = nominal.workspace
    grid = boundary_grid(box, 3)
    assert grid.shape == (3**6 - 1, 6)  # every grid point but the centre
    at_bound = np.isclose(grid, box[:, 0]) | np.isclose(grid, box[:, 1])
    assert at_bound.any(axis=1).all()
    edges = boundary_grid(box, 3, min_extreme=5)
    assert edges.shape == (64 + 6 * 32, 6)  # corners and the midpoints of the 192 edges
    corners = boundary_grid(box, 2, min_extreme=6)
    assert {tuple(r) for r in corners} == {tuple(r) for r in box_corners(box)}
    assert boundary_grid(box, 4).shape == (4**6 - 2**6, 6)
    with pytest.raises(ValueError, match="levels"):
        boundary_grid(box, 1)


def test_random_interior_is_seeded_and_inside(nominal):
    a = random_interior(nominal.workspace, 500, 3)
    assert_array_equal(a, random_interior(nominal.workspace, 500, 3))
    assert np.all((a >= nominal.workspace[:, 0]) & (a <= nominal.workspace[:, 1]))


def test_candidate_kinds(nominal):
    assert candidate_poses(nominal, "corners").shape == (64, 6)
    assert candidate_poses(nominal, "grid").shape == (728, 6)
    assert candidate_poses(nominal, "edges", 2).shape == (64, 6)
    assert candidate_poses(nominal, "random", 10, rng=1).shape == (10, 6)
    with pytest.raises(ValueError, match="number"):
        candidate_poses(nominal, "random")
    with pytest.raises(ValueError, match="kind"):
        candidate_poses(nominal, "faces")
    with pytest.raises(ValueError, match="workspace"):
        workspace_box(nominal.replace(workspace=None))


def test_feasibility_rejects_poses_beyond_the_leg_limits_and_near_singularity(nominal):
    poses = np.array(
        [
            [0, 0, 800, 0, 0, 0],  # home: feasible
            [0, 0, 550, 0, 0, 0],  # legs 590.5 mm < 604.8652 mm
            [0, 0, 1100, 0, 0, 0],  # legs 1120.8 mm > 1100 mm
            [0, 0, 800, 0, 0, np.pi / 2],  # the rotation singularity
            [0, 0, 800, 0, 0, np.deg2rad(60)],  # far enough from it
        ]
    )
    report = check_feasibility(nominal, poses)
    assert_array_equal(report.feasible, [True, False, False, False, True])
    assert_array_equal(report.too_short, [False, True, False, False, False])
    assert_array_equal(report.too_long, [False, False, True, False, False])
    assert_array_equal(report.near_singular, [False, False, False, True, False])
    assert report.distance[3] < 1e-8
    assert "lower limit" in report.reasons(1) and "upper limit" in report.reasons(2)
    assert "singular" in report.reasons(3) and report.reasons(0) == ""
    assert report.n_infeasible == 3 and "3 of 5 infeasible" in report.summary()


def test_the_paper_workspace_is_feasible_and_far_from_singularity(nominal):
    poses = np.vstack([workspace_corners(nominal), random_interior(nominal.workspace, 2000, 4)])
    assert check_feasibility(nominal, poses).feasible.all()
    distance = singularity_distance(nominal, poses)
    assert distance.min() > 3 * MIN_SINGULARITY_DISTANCE  # documented: 0.17 to 0.28
    assert 0.17 < distance.min() and distance.max() < 0.29


def test_without_leg_limits_only_the_singularity_counts(nominal):
    free = nominal.replace(leg_length_limits=None)
    assert check_feasibility(free, [[0, 0, 1100, 0, 0, 0]]).feasible.all()
    with pytest.raises(ValueError, match="NaN"):
        check_feasibility(nominal, [[0, 0, np.nan, 0, 0, 0]])


# -- criteria and information -----------------------------------------------------------------


def test_criterion_values_of_a_diagonal_information():
    info = np.diag([4.0, 1.0, 0.25])
    assert criterion_value(info, "D") == pytest.approx(np.mean(np.log([4, 1, 0.25])))
    assert criterion_value(info, "A") == pytest.approx(-(0.25 + 1 + 4))
    assert criterion_value(info, "E") == pytest.approx(0.25)
    assert criterion_value(info, "O4") == pytest.approx(0.25 / 2)
    singular = np.diag([1.0, 0.0])
    assert criterion_value(singular, "D") == -np.inf and criterion_value(singular, "A") == -np.inf
    assert criterion_value(singular, "E") == 0
    with pytest.raises(SelectionError, match="criterion"):
        criterion_value(info, "G")
    assert np.shape(criterion_value(np.stack([info, info]), "D")) == (2,)


def test_information_blocks_add_up_to_the_fisher_information(nominal, corner_poses):
    noise = NoiseModel()
    for fit in ("joints,l0", "joints,l0,gains"):
        mask = select_parameters(fit)
        blocks = information_blocks(nominal, corner_poses, noise, mask)
        assert blocks.shape == (15, 6, int(mask.sum()))
        scale = PARAMETER_SCALE[mask]
        expected = fisher_information(nominal, corner_poses, noise, mask) * np.outer(scale, scale)
        assert_allclose(information_matrix(blocks), expected, rtol=1e-10)


# -- greedy and exchange ----------------------------------------------------------------------


@pytest.mark.parametrize("criterion", ["D", "A"])
def test_greedy_equals_brute_force(criterion):
    blocks = random_blocks(seed=1)
    assert_array_equal(greedy_selection(blocks, 9, criterion), brute_force_greedy(blocks, 9, criterion))


@pytest.mark.parametrize("criterion", ["E", "O4"])
def test_greedy_eigenvalue_criteria_close_to_brute_force(criterion):
    # E and O4 evaluate a screened shortlist exactly: with 60 candidates the shortlist of
    # 32 almost always holds the best, and the chosen value can only be lower if not
    blocks = random_blocks(seed=2)
    ours = greedy_selection(blocks, 9, criterion)
    brute = brute_force_greedy(blocks, 9, criterion)
    a = criterion_value(information_matrix(blocks, ours), criterion)
    b = criterion_value(information_matrix(blocks, brute), criterion)
    assert a >= 0.9 * b


@pytest.mark.parametrize("criterion", CRITERIA)
def test_exchange_never_ends_worse_than_its_greedy_start(criterion):
    for seed in range(3):
        blocks = random_blocks(seed=10 + seed)
        result = select_poses(blocks, 6, criterion, rng=seed)
        assert result.value >= result.greedy_value
        assert len(set(result.indices.tolist())) == 6
        assert result.value == pytest.approx(
            criterion_value(information_matrix(blocks, result.indices), criterion)
        )


@pytest.mark.parametrize("criterion", ["D", "A"])
def test_exchange_ends_in_a_local_optimum(criterion):
    blocks = random_blocks(n_cand=40, seed=3)
    chosen, swaps, _ = exchange_selection(blocks, greedy_selection(blocks, 5, criterion), criterion)
    value = criterion_value(information_matrix(blocks, chosen), criterion)
    for slot in range(chosen.size):
        for j in np.setdiff1d(np.arange(40), chosen):
            trial = chosen.copy()
            trial[slot] = j
            assert criterion_value(information_matrix(blocks, trial), criterion) <= value + 1e-9 * abs(value)
    assert swaps >= 0


def test_exchange_mends_a_rank_deficient_start():
    degenerate = random_blocks(n_cand=50, rows=2, p=8, seed=4)
    degenerate[:4, :, 4:] = 0.0  # the first four candidates see only half the parameters
    start = np.arange(4)
    assert criterion_value(information_matrix(degenerate, start), "D") == -np.inf
    chosen, swaps, _ = exchange_selection(degenerate, start, "D")
    assert swaps > 0
    assert criterion_value(information_matrix(degenerate, chosen), "D") > -np.inf


@pytest.mark.parametrize("criterion", CRITERIA)
def test_exactly_determined_sets(criterion):
    # 4 poses of 2 rows for 8 parameters: removing any pose leaves F singular, the case of
    # 7 hexapod poses for 42 parameters
    blocks = random_blocks(n_cand=40, rows=2, p=8, seed=5)
    result = select_poses(blocks, 4, criterion, rng=0)
    assert result.value >= result.greedy_value
    assert criterion_value(information_matrix(blocks, result.indices), "D") > -np.inf


def test_seven_hexapod_poses(nominal):
    candidates = candidate_poses(nominal, "grid")
    result = select_poses(information_blocks(nominal, candidates), 7, "D", rng=0)
    assert result.value >= result.greedy_value > -np.inf


def test_selection_is_deterministic_under_a_seed(nominal):
    candidates = candidate_poses(nominal, "corners")
    blocks = information_blocks(nominal, candidates)
    a = select_poses(blocks, 15, "D", rng=7)
    b = select_poses(blocks, 15, "D", rng=7)
    assert_array_equal(a.indices, b.indices)
    assert a.value == b.value
    assert_array_equal(random_subsets(64, 15, 3, 5), random_subsets(64, 15, 3, 5))
    subsets = random_subsets(64, 15, 50, 6)
    assert all(len(set(s.tolist())) == 15 for s in subsets)


def test_selection_errors():
    blocks = random_blocks(n_cand=5)
    with pytest.raises(SelectionError, match="5 feasible"):
        select_poses(blocks, 6)
    with pytest.raises(SelectionError, match="criterion"):
        select_poses(blocks, 3, "X")
    with pytest.raises(SelectionError, match="at least 1"):
        select_poses(blocks, 0)


def test_optimal_poses_beat_the_paper_strategy_by_prediction(nominal):
    """15 D-optimal poses from the boundary grid against 15 random corners (20 draws)."""
    candidates = candidate_poses(nominal, "grid")
    result = select_poses(information_blocks(nominal, candidates), 15, "D", rng=0)
    optimal = mean_abs_error(least_squares_covariance(nominal, candidates[result.indices]))
    corners = workspace_corners(nominal)
    paper = np.mean(
        [mean_abs_error(least_squares_covariance(nominal, corners[s])) for s in random_subsets(64, 15, 20, 1)]
    )
    assert optimal < 0.8 * paper  # the target: at least 20 % lower
    assert result.value > result.greedy_value


def test_every_criterion_beats_random_corner_sets_on_its_own_measure(nominal):
    candidates = candidate_poses(nominal, "corners")
    blocks = information_blocks(nominal, candidates)
    randoms = random_subsets(64, 15, 30, 2)
    for criterion in CRITERIA:
        result = select_poses(blocks, 15, criterion, rng=0)
        values = [criterion_value(information_matrix(blocks, s), criterion) for s in randoms]
        assert result.value > max(values)


def test_results_to_dict(nominal):
    """Selection and feasibility results as plain Python (JSON-ready)."""
    import json

    corners = workspace_corners(nominal)
    result = select_poses(information_blocks(nominal, corners), 10, "A", rng=0)
    data = result.to_dict()
    json.dumps(data)
    assert data["indices"] == result.indices.tolist() and data["value"] == result.value
    assert data["greedy_indices"] == result.greedy_indices.tolist() and data["passes"] == result.passes
    poses = np.vstack([corners[:2], [[0.0, 0.0, 0.0, 0.0, 0.0, np.pi / 2]]])
    report = check_feasibility(nominal, poses).to_dict()
    json.dumps(report)
    assert (report["n_poses"], report["n_feasible"], report["n_infeasible"]) == (3, 2, 1)
    assert report["near_singular"] == 1 and report["feasible"] == [True, True, False]
    assert report["reasons"][:2] == ["", ""] and "near singular" in report["reasons"][2]
