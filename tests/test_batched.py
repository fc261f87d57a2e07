"""Batched identification against the one-at-a-time solver (:mod:`hexcal.estimation.batched`).

The one-at-a-time reference is ``estimate(..., with_bound=False, polish=5)``: scipy's
Levenberg–Marquardt followed by Gauss–Newton steps, so that it is at its optimum within
rounding (without them it stops up to about 1e-6 mm short in weak directions of the ``paper``
cost; see :func:`hexcal.estimation.least_squares.solve_least_squares`). Both solvers then sit
at the same optimum, and their values must agree to 1e-9 mm.
"""

from __future__ import annotations

import numpy as np
import pytest

from hexcal.calibration import estimate
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import select_parameters
from hexcal.core.workspace import random_poses, workspace_corners
from hexcal.errors import IdentificationError, UsageError
from hexcal.estimation.batched import (
    STATUS_CONVERGED,
    STATUS_MAX_ITER,
    STATUS_NONFINITE,
    STATUS_RANK_DEFICIENT,
    estimate_batch,
    identify_chunk,
)
from hexcal.estimation.batched_solver import cholesky_solve
from hexcal.instruments.pose import Measurements

#: Agreement demanded with the one-at-a-time solver, mm (gains: dimensionless).
AGREEMENT = 1e-9


def random_trials(nominal, true_machine, simulate, trials, m=15, seed=0, noise=None, interior=False):
    """``trials`` data sets of ``m`` poses: random workspace corners (or interior poses), the
    paper's noise by default; readings and measured poses stacked as (T, m, 6)."""
    rng = np.random.default_rng(seed)
    noise = NoiseModel() if noise is None else noise
    corners = workspace_corners(nominal)
    data = []
    for _ in range(trials):
        if interior:
            poses = random_poses(nominal, m, rng)
        else:
            poses = corners[rng.choice(len(corners), m, replace=False)]
        data.append(simulate(nominal, true_machine, poses, noise, rng))
    return np.stack([d.readings for d in data]), np.stack([d.poses for d in data])


def one_at_a_time(nominal, readings, poses, method, mask=None, noise=None):
    """Values of the one-at-a-time solver, iterated to its optimum; NaN rows where it fails.
    The noise is the batched solver's (the seed paper's unless given), not learned."""
    noise = NoiseModel() if noise is None else noise
    out = []
    for r, p in zip(readings, poses, strict=True):
        try:
            res = estimate(nominal, Measurements(p, r), method, mask, noise, with_bound=False, polish=5)
            out.append(res.values)
        except IdentificationError:
            out.append(np.full(int(np.sum(select_parameters() if mask is None else mask)), np.nan))
    return np.array(out)


@pytest.mark.parametrize("method", ["paper", "length", "ml"])
def test_batched_equals_one_at_a_time(nominal, true_machine, simulate, method):
    readings, poses = random_trials(nominal, true_machine, simulate, 6, seed=11)
    batch = estimate_batch(nominal, readings, poses, method)
    ref = one_at_a_time(nominal, readings, poses, method)
    assert batch.converged.all(), batch.message
    assert batch.values.shape == (6, 42)
    assert np.max(np.abs(batch.values - ref)) < AGREEMENT
    # the solution moved far from the start: the comparison is not trivial
    assert np.max(np.abs(batch.values - nominal.to_vector()[:42])) > 0.1
    assert np.all(batch.iterations > 2) and np.all(np.isfinite(batch.cost))


def test_interior_poses_and_gains(nominal, true_machine, simulate):
    """Random interior poses (a weaker design) and all 48 parameters, leg gains included."""
    mask = select_parameters(fit=("joints", "l0", "gains"))
    readings, poses = random_trials(nominal, true_machine, simulate, 4, m=20, seed=5, interior=True)
    for method in ("length", "ml"):
        batch = estimate_batch(nominal, readings, poses, method, mask)
        ref = one_at_a_time(nominal, readings, poses, method, mask)
        assert batch.converged.all(), batch.message
        assert batch.values.shape == (4, 48)
        assert np.max(np.abs(batch.values - ref)) < AGREEMENT


@pytest.mark.parametrize("method", ["paper", "ml"])
def test_failures_do_not_spoil_other_trials(nominal, true_machine, simulate, method):
    readings, poses = random_trials(nominal, true_machine, simulate, 5, seed=3)
    clean = estimate_batch(nominal, readings, poses, method)
    readings[1, 4, 2] = np.nan  # a broken leg reading
    poses[3] = poses[3, :1]  # one pose measured fifteen times: rank-deficient from the start
    with pytest.raises(IdentificationError, match="rank-deficient"):
        estimate(nominal, Measurements(poses[3], readings[3]), method, with_bound=False)
    batch = estimate_batch(nominal, readings, poses, method)
    assert batch.status.tolist() == [
        STATUS_CONVERGED,
        STATUS_NONFINITE,
        STATUS_CONVERGED,
        STATUS_RANK_DEFICIENT,
        STATUS_CONVERGED,
    ]
    assert np.isnan(batch.values[[1, 3]]).all() and np.isnan(batch.cost[[1, 3]]).all()
    assert batch.rank[3] < 42 and batch.rank[0] == 42
    good = [0, 2, 4]  # the same within rounding (stopping rules are shared by the trials solved together)
    assert np.max(np.abs(batch.values[good] - clean.values[good])) < 1e-10
    assert "rank-deficient" in batch.message[3] and batch.message[0] == "converged"


def test_not_converged_is_reported(nominal, true_machine, simulate):
    readings, poses = random_trials(nominal, true_machine, simulate, 3, seed=4)
    batch = estimate_batch(nominal, readings, poses, "paper", max_iter=2)
    assert (batch.status == STATUS_MAX_ITER).all() and np.isnan(batch.values).all()
    assert not batch.converged.any() and (batch.iterations == 2).all()


def test_per_trial_starts_reach_the_same_optimum(nominal, true_machine, simulate):
    readings, poses = random_trials(nominal, true_machine, simulate, 4, seed=8)
    rng = np.random.default_rng(1)
    starts = nominal.to_vector(gains=True) + np.concatenate(
        [rng.uniform(-1, 1, (4, 42)), np.zeros((4, 6))], 1
    )
    shared = estimate_batch(nominal, readings, poses, "paper")
    own = estimate_batch(nominal, readings, poses, "paper", starts=starts)
    assert own.converged.all()
    assert np.max(np.abs(own.values - shared.values)) < AGREEMENT
    # solved in chunks of three and of one trial: the same values within rounding
    for chunk in (3, 1):
        again = estimate_batch(nominal, readings, poses, "paper", chunk=chunk)
        assert np.max(np.abs(again.values - shared.values)) < 1e-10
        assert np.array_equal(again.status, shared.status)


def test_without_pose_noise_ml_is_length(nominal, true_machine, simulate):
    noise = NoiseModel(leg=0.01, position=0.0, orientation=0.0)
    readings, poses = random_trials(nominal, true_machine, simulate, 3, seed=9, noise=noise)
    ml = estimate_batch(nominal, readings, poses, "ml", noise=noise)
    length = estimate_batch(nominal, readings, poses, "length")
    assert np.array_equal(ml.values, length.values)
    ref = one_at_a_time(nominal, readings, poses, "ml", noise=noise)
    assert np.max(np.abs(ml.values - ref)) < AGREEMENT


def test_exact_data_recovers_the_true_machine(nominal, true_machine, simulate):
    corners = workspace_corners(nominal)[::3]
    data = simulate(nominal, true_machine, corners)
    batch = estimate_batch(nominal, data.readings[None], data.poses[None], "paper")
    assert batch.converged.all()
    assert np.max(np.abs(batch.values[0] - true_machine.to_vector()[:42])) < 1e-7


def test_identify_chunk_and_bad_input(nominal, true_machine, simulate):
    readings, poses = random_trials(nominal, true_machine, simulate, 2, seed=2)
    out = identify_chunk(nominal, readings, poses, ("paper", "length"))
    assert set(out) == {"paper", "length"} and out["paper"].shape == (2, 42)
    with pytest.raises(UsageError, match="unknown batched method"):
        estimate_batch(nominal, readings, poses, "gls")
    with pytest.raises(UsageError, match="shape"):
        estimate_batch(nominal, readings[0], poses[0])
    with pytest.raises(IdentificationError, match="at least 7"):
        estimate_batch(nominal, readings[:, :5], poses[:, :5])


def test_batched_cholesky_solve():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(5, 7, 7))
    a = a @ a.transpose(0, 2, 1) + 0.1 * np.eye(7)
    b = rng.normal(size=(5, 7))
    a[2] = -np.eye(7)  # not positive definite: NaN, and the others still solved
    x = cholesky_solve(a, b)
    assert np.isnan(x[2]).all()
    ok = [0, 1, 3, 4]
    assert np.allclose(x[ok], np.linalg.solve(a[ok], b[ok][..., None])[..., 0], rtol=1e-10, atol=1e-12)
