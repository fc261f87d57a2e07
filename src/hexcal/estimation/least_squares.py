"""Least squares on the leg residuals at the measured poses: the ``length`` and ``paper`` estimators.

- ``"paper"``: the seed paper's cost (Agheli & Nategh 2009, eq. 3, after Zhuang et al. 1998
  and Chiu & Perng 2004): ``r_ij = |v_ij|² - (l0_i + g_i dl_ij)²`` (mm²);
- ``"length"``: the leg length residual ``r_ij = |v_ij| - (l0_i + g_i dl_ij)`` (mm).

Both are minimised by Levenberg–Marquardt (``scipy.optimize.least_squares``, ``method="lm"``)
with the analytic Jacobian of :meth:`hexcal.estimation.problem.Problem.least_squares_functions`.
They need a measurement model whose observation determines the pose.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hexcal.core.noise import NoiseModel
from hexcal.errors import IdentificationError
from hexcal.estimation.covariance import finish_result
from hexcal.estimation.problem import Problem
from hexcal.estimation.result import IdentificationResult, rms


def solve_least_squares(
    fun: Any, jac: Any, x0: np.ndarray, polish: int = 0, truncate: bool = False, **kwargs: Any
) -> Any:
    """``scipy.optimize.least_squares`` by Levenberg–Marquardt with hexcal's tolerances.

    ``x_scale=1``: the variables are already in parameter-scale units (scipy >= 1.16 defaults
    LM to 'jac' scaling, which starts with steps far too small here). Raises
    :class:`IdentificationError` when the solver fails; with ``truncate``, a solver that runs
    out of evaluations (``max_nfev``) returns its last iterate instead (a refit that only
    compares residuals, such as a diagnosis).

    ``polish``: at most that many Gauss–Newton steps after Levenberg–Marquardt. LM stops when
    its trust region collapses because the cost (a sum of large squares) can no longer tell
    steps apart; that can leave the optimum unresolved by up to about 1e-6 mm in weakly
    determined directions (``paper`` residuals are differences of squares of 800 mm). The
    gradient still resolves it, so Gauss–Newton steps reach the optimum within rounding.
    """
    from scipy.optimize import least_squares  # deferred: scipy.optimize takes 0.7 s to import

    options = {"method": "lm", "x_scale": 1.0, "xtol": 1e-12, "ftol": 1e-12, "gtol": 1e-12} | kwargs
    sol = least_squares(fun, x0, jac=jac, **options)
    if (sol.status < 0 or (sol.status == 0 and not truncate)) or not np.all(np.isfinite(sol.x)):
        raise IdentificationError(f"the solver did not converge: {sol.message}")
    x = sol.x
    for _ in range(polish):
        step = np.linalg.lstsq(jac(x), -fun(x), rcond=None)[0]
        if not np.all(np.isfinite(step)) or np.linalg.norm(step) > 1e-6 * (1.0 + np.linalg.norm(x)):
            break  # not a refinement: keep the LM solution
        x = x + step
        if np.linalg.norm(step) <= 1e-15 * (1.0 + np.linalg.norm(x)):
            break
    if polish:
        sol.x, sol.fun, sol.jac = x, fun(x), jac(x)
    return sol


def fit_least_squares(
    problem: Problem,
    variant: str = "length",
    xtol: float = 1e-12,
    max_nfev: int | None = None,
    polish: int = 0,
    truncate: bool = False,
) -> IdentificationResult:
    """Least squares of the leg residual ``variant`` at the measured poses.

    ``polish`` Gauss–Newton steps after Levenberg–Marquardt resolve the optimum within
    rounding, ``truncate`` keeps the last iterate of a solver out of evaluations
    (:func:`solve_least_squares`).

    The covariance is ``s² V S⁻² Vᵀ`` from the SVD of the column-normalised Jacobian at the
    solution, with ``s²`` the residual variance ``sum(r²) / (6 m - n)``.
    """
    problem.check_size()
    fun, jac = problem.least_squares_functions(variant)
    x0 = np.zeros(problem.n_free)
    problem.check_rank(jac(x0))
    r0 = fun(x0)
    sol = solve_least_squares(fun, jac, x0, polish, truncate, xtol=xtol, max_nfev=max_nfev)
    return finish_result(problem, variant, problem.unpack(sol.x), sol.fun, sol.jac, rms(r0), sol)


def fit_length(problem: Problem, noise: NoiseModel | None = None, **options: Any) -> IdentificationResult:
    """The ``length`` estimator (registry signature; ``noise`` is not used)."""
    return fit_least_squares(problem, "length", **options)


def fit_paper(problem: Problem, noise: NoiseModel | None = None, **options: Any) -> IdentificationResult:
    """The ``paper`` estimator (registry signature; ``noise`` is not used)."""
    return fit_least_squares(problem, "paper", **options)
