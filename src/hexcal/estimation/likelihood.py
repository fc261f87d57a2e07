"""Maximum likelihood (``"ml"``): the parameters and every true pose, errors in variables.

The unknowns are the parameters ``θ`` (the machine's and every session's instrument's) and
the true pose ``P_j`` of every observation. With Gaussian noise the negative log-likelihood
is half the sum of squares of the whitened observation equations of
:meth:`hexcal.estimation.problem.Problem.observation_equations`: per observation ``j``

    e_leg,j  = (|o(P_j) + R(P_j) s_i - u_i| - f(θ_i, dl_ij)) / σ_leg      (6 values)
    e_inst,j = W (h(θ, P_j) - y_j),    Wᵀ W = Σ_inst⁻¹                  (k values)

(for the full-pose instrument ``h(P) = P``; ``f`` the leg model). Each ``P_j`` touches only
its own equations, so the problem is solved by variable projection (Golub & Pereyra 1973,
doi:10.1137/0710036; with Kaufman's Jacobian, 1975, doi:10.1007/BF01932995): for given
``θ`` all poses are found at once by a vectorised Gauss–Newton iteration (6 × 6 systems),
and Levenberg–Marquardt (``scipy.optimize.least_squares``) works on ``θ`` alone with the
projected Jacobian ``(I - Q_j Q_jᵀ) ∂e_j/∂θ``, ``Q_j`` an orthonormal basis of
``∂e_j/∂P_j``. Time and memory grow linearly with the number of observations.

With instruments in their own frames, some combinations of parameters change no prediction
(the gauge freedoms, :mod:`hexcal.estimation.gauge`): the solver varies only the directions
orthogonal to them, and the solution is reported under the gauge convention.

With no instrument noise (and instruments that determine the pose) it reduces to least
squares on the leg length residual.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.linalg import floored_whitener
from hexcal.core.noise import NoiseModel
from hexcal.errors import IdentificationError
from hexcal.estimation.covariance import finish_result
from hexcal.estimation.gauge import Gauge, apply_convention, complement_basis, gauge_freedoms, unidentifiable
from hexcal.estimation.gls import solve_gls
from hexcal.estimation.least_squares import fit_least_squares, solve_least_squares
from hexcal.estimation.problem import Part, Problem, session_noises
from hexcal.estimation.result import IdentificationResult, rms
from hexcal.estimation.uncertainty import LEG_SIGMA_FLOOR, POSE_VARIANCE_FLOOR

_INNER_MAX_ITER = 20
_INNER_TOL = 1e-12


def _solve(hess: NDArray[np.float64], grad: NDArray[np.float64]) -> NDArray[np.float64]:
    """Gauss–Newton steps of stacked 6 × 6 systems; a numerically singular one (a gross error
    that drove a variance to its floor) gets a relative ridge of 1e-12 instead of an error."""
    try:
        return np.linalg.solve(hess, grad[..., None])[..., 0]
    except np.linalg.LinAlgError:
        scale = np.max(np.abs(np.diagonal(hess, axis1=1, axis2=2)), axis=1)
        ridge = 1e-12 * np.where(scale > 0, scale, 1.0)[:, None, None] * np.eye(hess.shape[-1])
        return np.linalg.solve(hess + ridge, grad[..., None])[..., 0]


class PoseProjection:
    """The inner problem of variable projection for one session: true poses for given
    parameters.

    Caches the last evaluation (``least_squares`` asks for the residual and the Jacobian at
    the same point) and warm-starts each pose solve from the last poses.
    """

    def __init__(self, problem: Problem, part: Part, noise: NoiseModel) -> None:
        self.problem, self.part = problem, part
        self.sigma = max(noise.sigmas[0], LEG_SIGMA_FLOOR)
        self.whitener = floored_whitener(part.instrument.covariance(noise), POSE_VARIANCE_FLOOR)
        self.start = part.instrument.start_poses(problem.start, problem.full0[part.block], part.data)
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
        equations = self.problem.observation_equations
        poses = np.array(self.poses)
        for _ in range(_INNER_MAX_ITER):
            e, b, _, _ = equations(self.part, full, poses, self.sigma, self.whitener, False)
            hess = np.einsum("mki,mkj->mij", b, b)
            grad = np.einsum("mki,mk->mi", b, e)
            step = _solve(hess, grad)
            poses = poses - step
            if np.max(np.abs(step)) < _INNER_TOL * (1.0 + np.max(np.abs(poses))):
                break
        e, b, _, _ = equations(self.part, full, poses, self.sigma, self.whitener, False)
        self.x, self.poses, self.e, self.b = x.copy(), poses, e, b
        return poses, e, b

    def jacobian(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """The projected Jacobian ``(I - Q Qᵀ) ∂e/∂θ`` of this session, ``(m (6 + k), n_free)``."""
        poses, _, b = self.evaluate(x)
        full = self.problem.unpack(x)
        a = self.problem.eiv_parameter_jacobian(self.part, full, poses, self.sigma, self.whitener)
        q, _ = np.linalg.qr(b)
        proj = a - np.matmul(q, np.matmul(q.transpose(0, 2, 1), a))
        return proj.reshape(-1, a.shape[-1])


class Projection:
    """Variable projection over every session of a problem (one :class:`PoseProjection` each)."""

    def __init__(self, problem: Problem, noise: NoiseModel | Sequence[NoiseModel] | None) -> None:
        self.problem = problem
        self.noises = session_noises(problem, noise)
        self.parts = [PoseProjection(problem, p, n) for p, n in zip(problem.parts, self.noises, strict=True)]

    def reset(self) -> None:
        for part in self.parts:
            part.reset()

    def evaluate(self, x: NDArray[np.float64]) -> list[tuple[NDArray, NDArray, NDArray]]:
        """``(poses, e, b)`` of every session at ``x``."""
        return [part.evaluate(x) for part in self.parts]

    def residuals(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.concatenate([part.evaluate(x)[1].ravel() for part in self.parts])

    def jacobian(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """The projected Jacobian of all sessions stacked, solver units."""
        return np.concatenate([part.jacobian(x) for part in self.parts])

    def poses(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """The estimated true poses ``(m, 6)`` of every observation at ``x``."""
        return np.concatenate([part.evaluate(x)[0] for part in self.parts])

    def leg_residuals(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Leg residuals (mm) at the estimated true poses, ``(m, 6)``."""
        return np.concatenate([part.evaluate(x)[1][:, :6] * part.sigma for part in self.parts])

    def blocks(self, x: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """Every session's whitened residuals ``(m_s, 6 + k_s)``."""
        return [part.evaluate(x)[1] for part in self.parts]


def solve_projection(
    problem: Problem,
    inner: Projection,
    gauge: Gauge,
    x_start: NDArray[np.float64],
    xtol: float = 1e-10,
    max_nfev: int | None = 500,
    polish: int = 0,
    truncate: bool = False,
) -> tuple[NDArray[np.float64], Any]:
    """Levenberg–Marquardt on the projected likelihood in the directions orthogonal to the
    gauges: ``(x, solver result)``, ``x`` under the gauge convention."""
    basis = complement_basis(gauge)
    if gauge.size == 0:
        sol = solve_least_squares(
            inner.residuals,
            inner.jacobian,
            x_start,
            polish,
            truncate,
            xtol=xtol,
            ftol=1e-12,
            gtol=1e-12,
            max_nfev=max_nfev,
        )
        return sol.x, sol

    def fun(z: NDArray[np.float64]) -> NDArray[np.float64]:
        return inner.residuals(x_start + basis @ z)

    def jac(z: NDArray[np.float64]) -> NDArray[np.float64]:
        return inner.jacobian(x_start + basis @ z) @ basis

    sol = solve_least_squares(
        fun,
        jac,
        np.zeros(basis.shape[1]),
        polish,
        truncate,
        xtol=xtol,
        ftol=1e-12,
        gtol=1e-12,
        max_nfev=max_nfev,
    )
    full = apply_convention(problem, problem.unpack(x_start + basis @ sol.x), gauge)
    return (full[problem.mask] - problem.full0[problem.mask]) / problem.scale, sol


def fit_ml(
    problem: Problem,
    noise: NoiseModel | Sequence[NoiseModel] | None = None,
    xtol: float = 1e-10,
    max_nfev: int | None = 500,
    polish: int = 0,
    start: NDArray[np.float64] | None = None,
    **_: Any,
) -> IdentificationResult:
    """Maximum-likelihood identification with the poses as nuisance parameters.

    Parameters
    ----------
    problem : Problem
    noise : NoiseModel or sequence of NoiseModel, optional
        One for every session or one each; default the seed paper's.
    xtol : float
    max_nfev : int, optional
        Limit on evaluations (a well-posed fit needs about ten).
    polish : int
        Gauss–Newton steps after the outer Levenberg–Marquardt, to resolve the optimum
        within rounding (:func:`hexcal.estimation.least_squares.solve_least_squares`).
    start : ndarray, optional
        Solver variables to start from (a warm start near a known solution, e.g. the noise
        estimation's last iterate); default the start values (or the GLS estimate).

    Returns
    -------
    IdentificationResult
        ``method`` ``"ml"``; ``residuals`` the whitened leg and instrument residuals of every
        observation; the covariance from the projected Jacobian (gauge-fixed), with the
        independent residuals (``k`` per observation) less the identifiable parameters as
        degrees of freedom, so that the residual variance is close to 1 under a correct noise
        model.
    """
    problem.check_size()
    noises = session_noises(problem, noise)
    quiet = not any(
        np.any(p.instrument.covariance(n) != 0) for p, n in zip(problem.parts, noises, strict=True)
    )
    if problem.determines_pose and quiet:
        return fit_least_squares(problem, "length", polish=polish).replace(method="ml")
    inner = Projection(problem, noises)
    x0 = np.zeros(problem.n_free)
    gauge = gauge_freedoms(problem, problem.full0)
    if problem.determines_pose:
        # identifiability of the pose set as measured (the inner solve would otherwise hide a
        # rank deficiency behind the small pose freedom the noise model allows)
        problem.check_rank(problem.leg_jacobian(problem.full0))
    else:
        weak = unidentifiable(problem, inner.jacobian(x0), gauge)
        if weak:
            beyond = f" beyond the {gauge.size} gauge freedoms" if gauge.size else ""
            raise IdentificationError(
                f"the poses cannot identify all parameters{beyond} ({len(weak)} combination(s); "
                f"weakest: {weak[-1]}): fix some or measure more"
            )
    rms_before = rms(inner.residuals(x0))
    x_start = x0
    if start is not None:
        x_start = np.asarray(start, dtype=float)
        inner.reset()
    elif problem.determines_pose:
        # start from the GLS estimate: the same estimator to first order, five times cheaper,
        # so LM needs only a couple of full likelihood iterations
        x_start, *_ = solve_gls(problem, noises, 1, xtol, check=False)
        inner.reset()
    x, sol = solve_projection(problem, inner, gauge, x_start, xtol, max_nfev, polish)
    e = inner.residuals(x)
    dof = int(problem.observation_counts().sum()) - (problem.n_free - gauge.size)
    # the leg residuals at the measured poses where the instrument gives them, else at the
    # estimated true poses
    legs = None if problem.determines_pose else (inner.leg_residuals(x0), inner.leg_residuals(x))
    # the covariance and the bound linearise the gauges at the solution (as at any other point)
    gauge = gauge_freedoms(problem, problem.unpack(x)) if gauge.size else gauge
    return finish_result(
        problem,
        "ml",
        problem.unpack(x),
        e,
        inner.jacobian(x),
        rms_before,
        sol,
        dof=dof,
        leg_residuals=legs,
        gauge=gauge,
        poses=None if problem.determines_pose else inner.poses(x),
        blocks=inner.blocks(x),
        noises=noises,
    )


def ml_misfit(
    problem: Problem, noise: NoiseModel | Sequence[NoiseModel] | None = None, max_nfev: int | None = None
) -> tuple[float, float, int]:
    """``(rms, sum of squares, dof)`` of the whitened residuals of the ``ml`` fit, without its
    covariance, bound or checks: a refit that only compares residuals (a diagnosis). The last
    iterate counts when ``max_nfev`` runs out."""
    inner = Projection(problem, noise)
    gauge = gauge_freedoms(problem, problem.full0)
    _, sol = solve_projection(
        problem, inner, gauge, np.zeros(problem.n_free), max_nfev=max_nfev, truncate=True
    )
    e = np.asarray(sol.fun)  # at the last iterate (the gauge convention changes no residual)
    dof = int(problem.observation_counts().sum()) - (problem.n_free - gauge.size)
    return rms(e), float(e @ e), dof
