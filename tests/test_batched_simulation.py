"""The simulations identify each chunk's trials together (estimate_batch): the same numbers as
one trial at a time (the same solvers, a batch of one), to rounding, with failed trials NaN and
counted."""

from __future__ import annotations

import numpy as np
import pytest

from hexcal.core import NoiseModel, preset, workspace_corners
from hexcal.simulation import (
    TrialSeeds,
    identify_trials,
    run_paper_experiment,
    simulate_campaigns,
    true_machines,
)
from hexcal.simulation.selection import run_selection_study

NOMINAL = preset("paper-hmt")


def _campaign(trials: int, n: int, seed: int):
    seeds, noise = TrialSeeds.from_seed(seed), NoiseModel()
    rngs = [seeds.generator(t) for t in range(trials)]
    _, machines = true_machines(NOMINAL, None, rngs, 5.0)
    corners = workspace_corners(NOMINAL)
    commanded = np.stack([corners[r.permutation(64)[:n]] for r in rngs])
    leg = np.stack([noise.leg_errors(r, (n,)) for r in rngs])
    pose = np.stack([noise.pose_errors(r, (n,)) for r in rngs])
    return simulate_campaigns(NOMINAL, machines, commanded, leg, pose, strict=False), noise


@pytest.mark.parametrize("method", ["paper", "length", "gls", "ml"])
def test_batched_trials_equal_one_at_a_time(method):
    campaign, noise = _campaign(8, 15, seed=11)
    # a failing trial (every pose the same: rank-deficient) must not spoil the others
    campaign.measured[3], campaign.readings[3] = campaign.measured[3, :1], campaign.readings[3, :1]
    batched = identify_trials(NOMINAL, campaign, slice(None), method, noise)
    single = identify_trials(NOMINAL, campaign, slice(None), method, noise, batched=False)
    assert np.isnan(batched[3]).all() and np.isnan(single[3]).all()
    ok = np.arange(8) != 3
    assert np.isfinite(batched[ok]).all()
    # one at a time is a batch of one: the same optimum to rounding (as between chunks)
    np.testing.assert_allclose(batched[ok], single[ok], rtol=0, atol=1e-9)


def test_unreachable_and_underdetermined_trials_fail_as_nan():
    campaign, noise = _campaign(4, 15, seed=2)
    campaign.reached[1, 0] = np.nan  # an unreachable pose
    out = identify_trials(NOMINAL, campaign, slice(None), "paper", noise)
    assert np.isnan(out[1]).all() and np.isfinite(out[[0, 2, 3]]).all()
    few = identify_trials(NOMINAL, campaign, slice(0, 5), "paper", noise)  # 30 equations, 42 unknowns
    assert np.isnan(few).all()


def test_paper_experiment_counts_failures_and_does_not_depend_on_chunks():
    true = preset("paper-hmt-true")
    a = run_paper_experiment(NOMINAL, true, trials=6, rng=1, chunk_size=6)
    b = run_paper_experiment(NOMINAL, true, trials=6, rng=1, chunk_size=2)
    assert a.to_dict()["failures"] == {"interior": 0, "boundary": 0}
    # trials batched in different groups: the same optimum to rounding
    np.testing.assert_allclose(a.boundary_vectors, b.boundary_vectors, rtol=0, atol=1e-9)


def test_selection_study_orders_strategies_and_shows_selection_helps():
    cells = run_selection_study(NOMINAL, preset("paper-hmt-true"), trials=8, rng=0, pose_counts=(15,))
    rows = {c.strategy: c.row() for c in cells}
    assert list(rows) == ["interior", "corners", "selected"]
    # bounds of fixed geometry: selected poses beat the corners, which beat interior poses
    assert rows["selected"]["bound"] < rows["corners"]["bound"] < rows["interior"]["bound"]
    assert all(r["failures"] == 0 for r in rows.values())
