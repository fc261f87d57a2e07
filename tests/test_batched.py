"""Batched identification (:mod:`hexcal.estimation.batched`, the one solver of
:mod:`hexcal.estimation.levenberg`) against an independent solver, one data set at a time.

The reference is ``scipy.optimize.least_squares`` (Levenberg–Marquardt, MINPACK) on the same
problem's residual and Jacobian functions (:meth:`Problem.least_squares_functions`, and
:class:`~hexcal.estimation.likelihood.Projection` for maximum likelihood), followed by
Gauss–Newton steps, so that it is at its optimum within rounding (without them it stops up to
about 1e-6 mm short in weak directions of the ``paper`` cost, whose residuals are differences of
squares of 800 mm). Both solvers then sit at the same optimum, and their values must agree to
1e-9 mm. ``estimate`` itself (a batch of one) must give the batched values to rounding.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

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
from hexcal.estimation.gls import residual_weights
from hexcal.estimation.levenberg import cholesky_solve
from hexcal.estimation.likelihood import Projection
from hexcal.estimation.problem import Problem
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


def scipy_solve(fun, jac, x, polish=5):
    """scipy's Levenberg–Marquardt from ``x``, then Gauss–Newton steps (to the optimum within
    rounding)."""
    sol = least_squares(fun, x, jac=jac, method="lm", x_scale=1.0, xtol=1e-12, ftol=1e-12, gtol=1e-12)
    assert sol.status > 0, sol.message
    x = sol.x
    for _ in range(polish):
        step = np.linalg.lstsq(jac(x), -fun(x), rcond=None)[0]
        x = x + step
        if np.linalg.norm(step) <= 1e-15 * (1.0 + np.linalg.norm(x)):
            break
    return x


def scipy_fit(problem, method, noise=None):
    """The optimum of ``method`` by :func:`scipy_solve` (the reference): the full parameter
    vector. ``gls``: two fits, the weights at the start and at the first estimate."""
    x = np.zeros(problem.n_free)
    if method == "gls":
        noises = (noise or NoiseModel(),) * len(problem.parts)
        for _ in range(2):
            w = residual_weights(problem, problem.unpack(x), noises)
            x = scipy_solve(*problem.least_squares_functions("length", weights=w), x)
        return problem.unpack(x)
    if method == "ml" and np.any(problem.model.covariance(noise or NoiseModel()) != 0):
        inner = Projection(problem, noise)
        return problem.unpack(scipy_solve(inner.residuals, inner.jacobian, x))
    fun, jac = problem.least_squares_functions("paper" if method == "paper" else "length")
    return problem.unpack(scipy_solve(fun, jac, x))


def one_at_a_time(nominal, readings, poses, method, mask=None, noise=None):
    """Values of the reference solver, one data set at a time; NaN rows where it fails."""
    out = []
    for r, p in zip(readings, poses, strict=True):
        problem = Problem(nominal, Measurements(p, r), mask=mask)
        try:
            problem.check_rank(problem.leg_jacobian(problem.full0))
            out.append(scipy_fit(problem, method, noise)[problem.mask])
        except IdentificationError:
            out.append(np.full(int(np.sum(select_parameters() if mask is None else mask)), np.nan))
    return np.array(out)


def estimated(nominal, readings, poses, method, mask=None, noise=None):
    """Values of ``estimate`` (a batch of one), one data set at a time, under the batched
    solver's noise (the seed paper's unless given; ``estimate`` learns it by default)."""
    noise = NoiseModel() if noise is None else noise
    return np.array(
        [
            estimate(nominal, Measurements(p, r), method, mask, noise, with_bound=False).values
            for r, p in zip(readings, poses, strict=True)
        ]
    )


@pytest.mark.parametrize("method", ["paper", "length", "gls", "ml"])
def test_batched_equals_one_at_a_time(nominal, true_machine, simulate, method):
    readings, poses = random_trials(nominal, true_machine, simulate, 6, seed=11)
    batch = estimate_batch(nominal, readings, poses, method)
    ref = one_at_a_time(nominal, readings, poses, method)
    assert batch.converged.all(), batch.message
    assert batch.values.shape == (6, 42)
    assert np.max(np.abs(batch.values - ref)) < AGREEMENT
    # one identification is a batch of one: the same solver, the same values to rounding (as
    # between chunks of other sizes, test_per_trial_starts_reach_the_same_optimum)
    assert np.max(np.abs(estimated(nominal, readings, poses, method) - batch.values)) < 1e-10
    # the solution moved far from the start: the comparison is not trivial
    assert np.max(np.abs(batch.values - nominal.to_vector()[:42])) > 0.1
    assert np.all(batch.iterations > 2) and np.all(np.isfinite(batch.cost))


def test_interior_poses_and_gains(nominal, true_machine, simulate):
    """Random interior poses (a weaker design) and all 48 parameters, leg gains included."""
    mask = select_parameters(fit=("joints", "l0", "gains"))
    readings, poses = random_trials(nominal, true_machine, simulate, 4, m=20, seed=5, interior=True)
    for method in ("length", "gls", "ml"):
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
        estimate_batch(nominal, readings, poses, "bogus")
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
