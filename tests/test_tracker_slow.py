"""Monte Carlo: the maximum-likelihood estimate on simulated tracker data against its
Cramér–Rao bound (200 trials; ``make test-slow``; ``benchmarks/tracker.py`` prints more)."""

from __future__ import annotations

import numpy as np
import pytest

from hexcal.core.noise import NoiseModel
from hexcal.estimation import cramer_rao, information_blocks, problem_parameters
from hexcal.estimation.gauge import apply_convention, gauge_freedoms
from hexcal.estimation.problem import Problem
from hexcal.instruments import Session
from hexcal.instruments.targets import TargetModel
from tracker_cases import general_machines, identify, poses, reached_poses, simulate, tracker_setups

NOISE = NoiseModel(leg=0.005, position=0.015, orientation=2e-5, distribution="normal")
TRIALS = 200


@pytest.mark.slow
def test_ml_attains_the_cramer_rao_bound():
    nominal, true = general_machines()
    true_setup, start = tracker_setups(3)
    commanded = poses(nominal, 40, 21)
    reached = reached_poses(nominal, true, commanded)
    full_true = np.concatenate([true.to_vector(gains=True), true_setup.vector()])
    sq, bound = [], []
    for trial in range(TRIALS):
        data = simulate(nominal, true, true_setup, commanded, NOISE, 0.08, 500 + trial)
        out = identify(nominal, data, start, NOISE, with_bound=False, diagnose=False)
        calibrated = out.instruments[0]
        problem = Problem(
            nominal,
            Session(data, calibrated),
            parameters=problem_parameters(nominal, [Session(data, TargetModel(start))]),
        )
        fixed_true = apply_convention(problem, full_true, gauge_freedoms(problem, full_true))
        got = np.concatenate([out.geometry.to_vector(gains=True), calibrated.setup.vector()])
        sq.append(((got - fixed_true)[problem.mask][:42]) ** 2)
        rows = np.array([int(i) - 1 for i in data.ids])
        bound.append(np.diag(cramer_rao(problem, NOISE, full_true, reached[rows]))[:42])
    ratio = np.sqrt(np.sum(np.mean(sq, axis=0)) / np.sum(np.mean(bound, axis=0)))
    assert 0.9 < ratio < 1.1


def test_information_blocks_sum_to_the_fisher_information():
    nominal, true = general_machines()
    true_setup, _ = tracker_setups(1)
    data = simulate(nominal, true, true_setup, poses(nominal, 20, 1), None, 0.0, 2)
    problem = Problem(nominal, data, TargetModel(true_setup))
    reached = reached_poses(nominal, true, poses(nominal, 20, 1))
    blocks = information_blocks(problem, NOISE, problem.full0, reached)
    assert blocks.shape == (20, problem.n_free, problem.n_free)
    assert np.allclose(blocks, blocks.transpose(0, 2, 1))
    # each observation carries at most 3 independent values (3 target coordinates)
    assert np.linalg.matrix_rank(blocks[0], tol=1e-9 * np.abs(blocks[0]).max()) <= 3
