"""The Levenberg–Marquardt solver's convergence test (:func:`hexcal.estimation.levenberg.minimise`)
on a problem whose gradient is off by a little noise at every point, as a variable projection's
is where its inner pose solves stop at their tolerance.

There the cost cannot tell the remaining steps apart: each Gauss–Newton step raises it a little,
steps within the rounding of the cost are taken with a negative gain, so the damping doubles at
every one and never falls below the Gauss–Newton level. The solver ran out of iterations there
(motion-capture campaigns with the frame registered, about one in five, in
``benchmarks/sequence.py``); such steps in a row that promise no decrease beyond the rounding of
the cost end the solve, whatever the damping.
"""

from __future__ import annotations

import numpy as np

from hexcal.estimation.levenberg import (
    STALL,
    STATUS_CONVERGED,
    minimise,
)


class BiasedQuadratic:
    """``0.5 |A x - y|²`` for one problem, its gradient reported with an error drawn afresh at
    every point: ``bias`` times standard normal numbers."""

    def __init__(self, a: np.ndarray, y: np.ndarray, bias: float, rng: np.random.Generator) -> None:
        self.a, self.y, self.bias, self.rng = a, y, bias, rng
        self.x = np.zeros((1, a.shape[1]))
        self._normal(np.array([0]))

    def _cost(self, x: np.ndarray) -> np.ndarray:
        r = x @ self.a.T - self.y
        return 0.5 * np.sum(r**2, axis=1)

    def _normal(self, idx: np.ndarray) -> None:
        r = self.x @ self.a.T - self.y
        self.g = r @ self.a + self.bias * self.rng.normal(size=(1, self.a.shape[1]))
        self.h = np.broadcast_to(self.a.T @ self.a, (1, *self.a.T.shape[:1] * 2)).copy()
        self.cost = self._cost(self.x)

    def deviation(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.x[idx], self.x[idx]

    def trial(self, idx: np.ndarray, dx: np.ndarray) -> object:
        class Trial:
            pass

        t = Trial()
        t.x = self.x[idx] + dx
        t.cost = self._cost(t.x)
        return t

    def take(self, idx: np.ndarray, trial: object, accept: np.ndarray, again: np.ndarray) -> None:
        self.x[idx[accept]] = trial.x[accept]
        if np.any(accept):
            self._normal(idx)


def test_a_gradient_off_by_more_than_the_cost_can_tell_still_converges():
    rng = np.random.default_rng(5)
    a = rng.normal(size=(12, 3)) * [1.0, 3.0, 10.0]
    optimum = np.array([0.3, -0.2, 0.1])
    residual = rng.normal(size=12)
    residual -= a @ np.linalg.lstsq(a, residual, rcond=None)[0]  # orthogonal to A's columns
    residual *= np.sqrt(2 * 1000.0) / np.linalg.norm(residual)  # the cost at the optimum: 1000
    y = a @ optimum - residual
    h = a.T @ a
    # gradient errors whose Gauss–Newton step raises the cost about 10 times its rounding
    # (1e-10 × 1000): 0.5 bᵀH⁻¹b = 1e-6 on average
    bias = float(np.sqrt(2 * 1e-6 / np.trace(np.linalg.inv(h))))
    model = BiasedQuadratic(a, y, bias, rng)
    status, iterations = minimise(model, np.array([True]), np.zeros(1), max_iter=500)
    assert status[0] == STATUS_CONVERGED
    assert iterations[0] < 100  # converged by the stall test, not near the limit
    # where it stopped: within a few of the bias's Gauss–Newton steps of the optimum
    offset = bias * np.sqrt(np.trace(np.linalg.inv(h) @ np.linalg.inv(h)))
    assert np.linalg.norm(model.x[0] - optimum) < 20 * offset
    assert model.cost[0] < 1000.0 * (1 + 1e-8)
    assert STALL < iterations[0]
