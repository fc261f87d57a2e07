"""Issue 22: the learned noise against the truth, and the verdict's screen on a small campaign.

The Monte Carlo figures of every cell are in ``benchmarks/noise_learning.py`` (and
``docs/identification.md``); the slow test here guards the issue's claim (leg σ learned 1.22
times the true one at 100 poses on an irregular 6-6 machine), which the benchmark does not
reproduce: 200 trials per cell give 0.988-1.003 for the legs there.
"""

from __future__ import annotations

import numpy as np
import pytest
from tests.tracker_cases import general_machines

from hexcal.core.noise import NoiseModel
from hexcal.core.presets import preset
from hexcal.core.workspace import random_poses, workspace_corners
from hexcal.estimation.noise_estimation import estimate_noise
from hexcal.estimation.problem import Problem
from hexcal.estimation.robust import screen_poses
from hexcal.estimation.uncertainty import planned_measurements
from hexcal.instruments.data import Measurements
from hexcal.simulation.protocol import MachineBatch, simulate_campaigns

NOMINAL, TRUE = preset("paper-hmt"), preset("paper-hmt-true")


def test_the_studentized_screen_does_not_score_a_good_pose_of_a_small_campaign_near_8():
    # 15 random corners, the seed paper's noise as normal σ, 10 seeds. The raw screen (leg
    # residuals over their MAD) scores a good pose up to 9.3, past the verdict's threshold of 8:
    # 42 of the 90 residual dimensions go to the parameters, the residuals differ in variance by
    # the angles' lever arm, and an L1-like fit leaves some at zero. Studentized and fitted
    # least-squares-like within 3 robust σ: measured 1.9-4.0, against 2.8-9.3 raw
    noise = NoiseModel(0.01 / np.sqrt(3), 0.025 / np.sqrt(3), 0.001 / np.sqrt(3), distribution="normal")
    corners = workspace_corners(NOMINAL)
    raw, stud = [], []
    for seed in range(10):
        rng = np.random.default_rng(seed)
        poses = corners[rng.permutation(len(corners))[:15]]
        data = planned_measurements(TRUE, poses)
        data = Measurements(
            data.poses + noise.pose_errors(rng, (15,)), data.readings + noise.leg_errors(rng, (15,))
        )
        problem = Problem(NOMINAL, data)
        raw.append(screen_poses(NOMINAL, problem=problem).max())
        stud.append(screen_poses(NOMINAL, problem=problem, noise=noise, studentized=True).max())
    assert max(raw) > 8.0  # the old screen's false alarm, on these seeds
    assert max(stud) < 6.0


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["balanced", "pose"])
def test_learned_sigmas_are_unbiased_at_100_poses_on_an_irregular_machine(kind):
    # 60 campaigns of 100 random poses; the ratio learned / true σ has a spread of 0.05-0.09
    # per trial (benchmark, 200 trials), so the mean of 60 has a standard error <= 0.012:
    # 0.05 is over 4 standard errors, and the 1.22 is far outside it
    noise = {
        "balanced": NoiseModel(0.01, 0.01, 1e-4, distribution="normal"),
        "pose": NoiseModel(0.01 / np.sqrt(3), 0.025 / np.sqrt(3), 0.001 / np.sqrt(3), distribution="normal"),
    }[kind]
    nominal, real = general_machines(7)
    trials, n = 60, 100
    rng = np.random.default_rng(22)
    poses = random_poses(nominal, trials * n, rng).reshape(trials, n, 6)
    campaign = simulate_campaigns(
        nominal,
        MachineBatch.from_geometry(real),
        poses,
        noise.leg_errors(rng, (trials, n)),
        noise.pose_errors(rng, (trials, n)),
    )
    ratios = []
    for t in range(trials):
        est, _ = estimate_noise(Problem(nominal, Measurements(campaign.measured[t], campaign.readings[t])))
        assert est.converged and est.estimated.all()
        ratios.append(est.sigmas / np.array(noise.sigmas))
    ratios = np.array(ratios)
    se = ratios.std(axis=0, ddof=1) / np.sqrt(trials)
    assert np.all(se < 0.0125)
    np.testing.assert_allclose(ratios.mean(axis=0), 1.0, atol=0.05)
