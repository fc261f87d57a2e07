"""Maximum likelihood (``"ml"``): the parameters and every true pose, errors in variables.

The unknowns are the parameters ``θ`` (the machine's and the measurement model's) and the
true pose ``P_j`` of every observation. With Gaussian noise the negative log-likelihood is
half the sum of squares of the whitened observation equations of
:meth:`hexcal.estimation.problem.Problem.observation_equations`: per observation ``j``

    e_leg,j  = (|o(P_j) + R(P_j) s_i - u_i| - (l0_i + g_i dl_ij)) / σ_leg      (6 values)
    e_inst,j = W (h(θ, P_j) - y_j),    Wᵀ W = Σ_inst⁻¹                       (k values)

(for the full-pose instrument ``h(P) = P``). Each ``P_j`` touches only its own equations,
so the problem is solved by variable projection (Golub & Pereyra 1973,
doi:10.1137/0710036; with Kaufman's Jacobian, 1975, doi:10.1007/BF01932995): for given
``θ`` all poses are found at once by a vectorised Gauss–Newton iteration (6 × 6 systems),
and Levenberg–Marquardt (``scipy.optimize.least_squares``) works on ``θ`` alone with the
projected Jacobian ``(I - Q_j Q_jᵀ) ∂e_j/∂θ``, ``Q_j`` an orthonormal basis of
``∂e_j/∂P_j``. Time and memory grow linearly with the number of observations.

With no instrument noise (and a model that measures the pose) it reduces to least squares
on the leg length residual.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.linalg import floored_whitener
from hexcal.core.noise import NoiseModel
from hexcal.estimation.bounds import LEG_SIGMA_FLOOR, POSE_VARIANCE_FLOOR
from hexcal.estimation.gls import solve_gls
from hexcal.estimation.least_squares import fit_least_squares, solve_least_squares
from hexcal.estimation.problem import Problem
from hexcal.estimation.result import IdentificationResult, finish_result, rms

_INNER_MAX_ITER = 20
_INNER_TOL = 1e-12


class PoseProjection:
    """The inner problem of variable projection: true poses for given parameters.

    Caches the last evaluation (``least_squares`` asks for the residual and the Jacobian at
    the same point) and warm-starts each pose solve from the last poses.
    """

    def __init__(self, problem: Problem, noise: NoiseModel) -> None:
        self.problem = problem
        self.sigma = max(noise.sigmas[0], LEG_SIGMA_FLOOR)
        self.whitener = floored_whitener(problem.model.covariance(noise), POSE_VARIANCE_FLOOR)
        self.start = problem.model.start_poses(problem.start, problem.setup(problem.full0), problem.data)
        self.poses = self.start.copy()
        self.x: NDArray[np.float64] | None = None
        self.e = self.b = np.empty(0)

    def reset(self) -> None:
        """Start the next pose solve from the initial poses again."""
        self.poses, self.x = self.start.copy(), None

    def evaluate(self, x: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray]:
        """``(poses, e, b)`` at solver variables ``x`` (Gauss–Newton over all poses at once)."""
        if self.x is not None and np.array_equal(self.x, x):
            return self.poses, self.e, self.b
        full = self.problem.unpack(x)
        poses = np.array(self.poses)
        for _ in range(_INNER_MAX_ITER):
            e, b, _, _ = self.problem.observation_equations(full, poses, self.sigma, self.whitener, False)
            hess = np.einsum("mki,mkj->mij", b, b)
            grad = np.einsum("mki,mk->mi", b, e)
            step = np.linalg.solve(hess, grad[..., None])[..., 0]
            poses = poses - step
            if np.max(np.abs(step)) < _INNER_TOL * (1.0 + np.max(np.abs(poses))):
                break
        e, b, _, _ = self.problem.observation_equations(full, poses, self.sigma, self.whitener, False)
        self.x, self.poses, self.e, self.b = x.copy(), poses, e, b
        return poses, e, b

    def residuals(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.evaluate(x)[1].ravel()

    def jacobian(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """The projected Jacobian ``(I - Q Qᵀ) ∂e/∂θ`` stacked over observations, solver units."""
        poses, _, b = self.evaluate(x)
        a = self.problem.eiv_parameter_jacobian(self.problem.unpack(x), poses, self.sigma, self.whitener)
        q, _ = np.linalg.qr(b)
        proj = a - np.matmul(q, np.matmul(q.transpose(0, 2, 1), a))
        return proj.reshape(-1, a.shape[-1])


def fit_ml(
    problem: Problem,
    noise: NoiseModel | None = None,
    xtol: float = 1e-10,
    max_nfev: int | None = 500,
    polish: int = 0,
    **_: Any,
) -> IdentificationResult:
    """Maximum-likelihood identification with the poses as nuisance parameters.

    Parameters
    ----------
    problem : Problem
    noise : NoiseModel, optional
        Default the seed paper's.
    xtol : float
    max_nfev : int, optional
        Limit on evaluations (a well-posed fit needs about ten).
    polish : int
        Gauss–Newton steps after the outer Levenberg–Marquardt, to resolve the optimum
        within rounding (:func:`hexcal.estimation.least_squares.solve_least_squares`).

    Returns
    -------
    IdentificationResult
        ``method`` ``"ml"``; ``residuals`` of shape ``(m, 6 + k)`` (whitened leg and
        instrument residuals); the covariance from the projected Jacobian, with the
        independent residuals (``k`` per observation) less the parameters as degrees of
        freedom, so that the residual variance is close to 1 under a correct noise model.
    """
    noise = NoiseModel() if noise is None else noise
    problem.check_size()
    model = problem.model
    if model.measures_pose and not np.any(model.covariance(noise) != 0):
        return fit_least_squares(problem, "length", polish=polish).replace(method="ml")
    inner = PoseProjection(problem, noise)
    x0 = np.zeros(problem.n_free)
    if model.measures_pose:
        # identifiability of the pose set as measured (the inner solve would otherwise hide a
        # rank deficiency behind the small pose freedom the noise model allows)
        problem.check_rank(problem.leg_jacobian(problem.full0))
    rms_before = rms(inner.residuals(x0))
    x_start = x0
    if model.measures_pose:
        # start from the GLS estimate: the same estimator to first order, five times cheaper,
        # so LM needs only a couple of full likelihood iterations
        x_start, *_ = solve_gls(problem, noise, 1, xtol, check=False)
        inner.reset()
    else:
        problem.check_rank(inner.jacobian(x0))
    sol = solve_least_squares(
        inner.residuals, inner.jacobian, x_start, polish, xtol=xtol, ftol=1e-12, gtol=1e-12, max_nfev=max_nfev
    )
    _, e, _ = inner.evaluate(sol.x)
    dof = int(problem.observation_counts().sum()) - problem.n_free
    return finish_result(
        problem, "ml", problem.unpack(sol.x), e.ravel(), inner.jacobian(sol.x), rms_before, sol, dof=dof
    )
