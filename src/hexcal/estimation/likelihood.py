"""Statistically efficient identification: maximum likelihood and generalised least squares.

Both use a measurement noise model (:class:`hexcal.core.measurement.NoiseModel`): a leg
sensor error of standard deviation ``σ_leg`` on every leg length, and a pose
measurement error of covariance ``Σ_pose`` (6 × 6, mm and rad) on every measured pose.

**Maximum likelihood** (``"ml"``, errors in variables). The unknowns are the
parameters ``θ`` and the true pose ``P_j`` of every measurement. With Gaussian noise
the negative log-likelihood is half the sum of squares of, per pose ``j``,

    e_leg,j  = (|o(P_j) + R(P_j) s_i - u_i| - (l0_i + g_i dl_ij)) / σ_leg      (6 values)
    e_pose,j = W (P_j - P̂_j),    Wᵀ W = Σ_pose⁻¹                              (6 values)

Each ``P_j`` touches only its own twelve residuals, so the problem is solved by
variable projection (Golub & Pereyra 1973, doi:10.1137/0710036; with Kaufman's
Jacobian, 1975, doi:10.1007/BF01932995): for given ``θ`` all poses are found at once
by a vectorised Gauss–Newton iteration (6 × 6 systems), and Levenberg–Marquardt
(``scipy.optimize.least_squares``) works on ``θ`` alone with the projected Jacobian
``(I - Q_j Q_jᵀ) ∂e_j/∂θ``, ``Q_j`` an orthonormal basis of ``∂e_j/∂P_j``. Time and
memory grow linearly with the number of poses.

**Generalised least squares** (``"gls"``). The leg residuals at the measured poses,
whitened by their propagated covariance ``C_j = J_j Σ_pose J_jᵀ + σ_leg² I``
(:func:`hexcal.estimation.bounds.residual_covariances`), recomputed once at the first
estimate. To first order it is the same estimator as maximum likelihood.

With no pose noise both reduce to least squares on the leg length residual.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import pose_jacobian_from_arrays
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import PARAMETER_SCALE, select_parameters
from hexcal.errors import IdentificationError
from hexcal.estimation.bounds import cramer_rao_covariance, residual_covariances, whitening
from hexcal.estimation.identification import (
    IdentificationResult,
    _jacobian,
    _prepare,
    _residuals,
    _rms,
    check_data_size,
    check_rank,
    finish_result,
    identify,
    parameter_unpacker,
)
from hexcal.models.pose import Measurements

#: Estimators by name; ``"ml"`` is the default of ``hexcal identify``.
ESTIMATORS = ("ml", "gls", "length", "paper")

#: Smallest leg sensor σ used in the likelihood (mm): a zero σ makes the legs exact
#: constraints, which this floor approximates without dividing by zero.
LEG_SIGMA_FLOOR = 1e-7

#: Smallest pose error variance used in the likelihood (mm², rad²), for the same reason.
POSE_VARIANCE_FLOOR = 1e-18

_INNER_MAX_ITER = 20
_INNER_TOL = 1e-12


def _pose_whitener(noise: NoiseModel) -> NDArray[np.float64]:
    """``W`` with ``W Σ_pose Wᵀ = I`` (variances floored at :data:`POSE_VARIANCE_FLOOR`)."""
    vals, vecs = np.linalg.eigh(noise.pose_cov())
    return (vecs / np.sqrt(np.maximum(vals, POSE_VARIANCE_FLOOR))).T


def _has_pose_noise(noise: NoiseModel) -> bool:
    return bool(np.any(noise.pose_cov() != 0))


def identify_ml(
    start: Geometry,
    measurements: Measurements,
    noise: NoiseModel | None = None,
    mask: ArrayLike | None = None,
    xtol: float = 1e-10,
    max_nfev: int | None = 500,
) -> IdentificationResult:
    """Maximum-likelihood identification with the poses as nuisance parameters.

    Parameters
    ----------
    start : Geometry
        Start values (the nominal geometry).
    measurements : Measurements
    noise : NoiseModel, optional
        Default the seed paper's.
    mask : array_like of bool, shape (48,), optional
        Parameters to vary; default joints and l0.
    xtol : float
    max_nfev : int, optional
        Limit on evaluations (a well-posed fit needs about ten).

    Returns
    -------
    IdentificationResult
        ``method`` is ``"ml"``; ``residuals`` has shape ``(m, 12)`` (six whitened leg and
        six whitened pose residuals per pose).

    Notes
    -----
    See the module docstring. The covariance is computed as for :func:`identify`, from
    the projected Jacobian, with ``6 m - n`` degrees of freedom; with a correct noise
    model the residual variance is close to 1.
    """
    noise = NoiseModel() if noise is None else noise
    mask = select_parameters() if mask is None else np.asarray(mask, dtype=bool)
    check_data_size(measurements, mask)
    if not _has_pose_noise(noise):
        return dataclasses.replace(identify(start, measurements, "length", mask), method="ml")
    sigma = max(noise.sigmas[0], LEG_SIGMA_FLOOR)
    wp = _pose_whitener(noise)
    wtw = wp.T @ wp
    measured = measurements.poses
    readings = measurements.readings
    m = len(measurements)
    euler = start.euler
    full0 = start.to_vector(gains=True)
    scale = PARAMETER_SCALE[mask]

    unpack = parameter_unpacker(full0, mask)

    state: dict[str, object] = {"x": None, "poses": measured.copy()}

    def solve_poses(full: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray]:
        """True poses for given parameters: Gauss–Newton, all poses at once."""
        u, s = full[:18].reshape(6, 3), full[18:36].reshape(6, 3)
        model = full[36:42] + full[42:48] * readings
        poses = np.array(state["poses"])  # warm start from the last evaluation
        for _ in range(_INNER_MAX_ITER):
            lengths, jp = pose_jacobian_from_arrays(u, s, poses, euler)
            e_leg = (lengths - model) / sigma
            hess = np.einsum("mki,mkj->mij", jp, jp) / sigma**2 + wtw
            grad = np.einsum("mki,mk->mi", jp, e_leg) / sigma + (poses - measured) @ wtw
            step = np.linalg.solve(hess, grad[..., None])[..., 0]
            poses = poses - step
            if np.max(np.abs(step)) < _INNER_TOL * (1.0 + np.max(np.abs(poses))):
                break
        lengths, jp = pose_jacobian_from_arrays(u, s, poses, euler)
        e = np.concatenate([(lengths - model) / sigma, (poses - measured) @ wp.T], axis=1)
        return poses, e, jp

    def evaluate(x: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray]:
        if state["x"] is None or not np.array_equal(state["x"], x):
            poses, e, jp = solve_poses(unpack(x))
            state.update(x=x.copy(), poses=poses, e=e, jp=jp)
        return state["poses"], state["e"], state["jp"]  # type: ignore[return-value]

    def fun(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return evaluate(x)[1].ravel()

    def jac(x: NDArray[np.float64]) -> NDArray[np.float64]:
        poses, _, jp = evaluate(x)
        rot, pos = _prepare(start, poses)
        a = _jacobian(unpack(x), rot, pos, readings, "length")[:, mask].reshape(m, 6, -1)
        a = a * (scale / sigma)
        j_pose = np.concatenate([jp / sigma, np.broadcast_to(wp, (m, 6, 6))], axis=1)  # (m, 12, 6)
        q, _ = np.linalg.qr(j_pose)
        full_a = np.concatenate([a, np.zeros_like(a)], axis=1)  # (m, 12, n)
        proj = full_a - np.matmul(q, np.matmul(q[:, :6].transpose(0, 2, 1), a))
        return proj.reshape(12 * m, -1)

    x0 = np.zeros(int(mask.sum()))
    # identifiability of the pose set as measured (the inner solve would otherwise hide a
    # rank deficiency behind the small pose freedom the noise model allows)
    rot0, pos0 = _prepare(start, measured)
    check_rank(_jacobian(full0, rot0, pos0, readings, "length")[:, mask] * scale, mask)
    rms_before = _rms(fun(x0))
    # start the outer iteration from the GLS estimate: the same estimator to first order,
    # five times cheaper, so LM needs only a couple of full likelihood iterations
    x_start, *_ = _solve_gls(start, measurements, noise, mask, 1, xtol, check=False)
    state["poses"] = measured.copy()
    sol = least_squares(
        fun, x_start, jac=jac, method="lm", x_scale=1.0, xtol=xtol, ftol=1e-12, gtol=1e-12, max_nfev=max_nfev
    )
    if sol.status <= 0 or not np.all(np.isfinite(sol.x)):
        raise IdentificationError(f"the solver did not converge: {sol.message}")
    _, e, _ = evaluate(sol.x)
    return finish_result(
        start,
        measurements,
        "ml",
        mask,
        unpack(sol.x),
        e.ravel(),
        jac(sol.x),
        rms_before,
        sol,
        dof=6 * m - int(mask.sum()),
    )


def identify_gls(
    start: Geometry,
    measurements: Measurements,
    noise: NoiseModel | None = None,
    mask: ArrayLike | None = None,
    rounds: int = 2,
    xtol: float = 1e-10,
) -> IdentificationResult:
    """Generalised least squares on the leg residuals with the propagated pose covariance.

    The weights ``C_j⁻¹`` are computed at the start geometry, then again at the
    estimate (``rounds`` fits in all). Returns an :class:`IdentificationResult` with
    ``method`` ``"gls"`` and whitened residuals of shape ``(m, 6)``.
    """
    noise = NoiseModel() if noise is None else noise
    mask = select_parameters() if mask is None else np.asarray(mask, dtype=bool)
    check_data_size(measurements, mask)
    if not _has_pose_noise(noise) and noise.sigmas[0] == 0:
        return dataclasses.replace(identify(start, measurements, "length", mask), method="gls")
    x, sol, rms_before, unpack = _solve_gls(start, measurements, noise, mask, rounds, xtol, check=True)
    return finish_result(start, measurements, "gls", mask, unpack(x), sol.fun, sol.jac, rms_before, sol)


def _solve_gls(
    start: Geometry,
    measurements: Measurements,
    noise: NoiseModel,
    mask: NDArray[np.bool_],
    rounds: int,
    xtol: float,
    check: bool,
) -> tuple[NDArray[np.float64], Any, float, Callable[[NDArray[np.float64]], NDArray[np.float64]]]:
    """The GLS iterations: ``(x, last solver result, RMS before, unpack)``."""
    rot, pos = _prepare(start, measurements.poses)
    readings = measurements.readings
    m = len(measurements)
    full0 = start.to_vector(gains=True)
    scale = PARAMETER_SCALE[mask]

    unpack = parameter_unpacker(full0, mask)

    floor = NoiseModel(
        leg=max(noise.sigmas[0], LEG_SIGMA_FLOOR), distribution="normal", pose_covariance=noise.pose_cov()
    )
    x = np.zeros(int(mask.sum()))
    sol = None
    rms_before = 0.0
    for k in range(max(1, rounds)):
        w = whitening(residual_covariances(start.with_vector(unpack(x)), measurements.poses, floor))

        def fun(x: NDArray[np.float64], w: NDArray[np.float64] = w) -> NDArray[np.float64]:
            r = _residuals(unpack(x), rot, pos, readings, "length")
            return np.einsum("mij,mj->mi", w, r).ravel()

        def jac(x: NDArray[np.float64], w: NDArray[np.float64] = w) -> NDArray[np.float64]:
            a = _jacobian(unpack(x), rot, pos, readings, "length")[:, mask].reshape(m, 6, -1) * scale
            return np.matmul(w, a).reshape(6 * m, -1)

        if k == 0:
            if check:
                check_rank(jac(x), mask)
            rms_before = _rms(fun(x))
        sol = least_squares(fun, x, jac=jac, method="lm", x_scale=1.0, xtol=xtol, ftol=1e-12, gtol=1e-12)
        if sol.status <= 0 or not np.all(np.isfinite(sol.x)):
            raise IdentificationError(f"the solver did not converge: {sol.message}")
        x = sol.x
    return x, sol, rms_before, unpack


def estimate(
    start: Geometry,
    measurements: Measurements,
    method: str = "ml",
    mask: ArrayLike | None = None,
    noise: NoiseModel | None = None,
    with_bound: bool = True,
) -> IdentificationResult:
    """Identify with any of :data:`ESTIMATORS` and attach the Cramér–Rao bound.

    ``noise`` (default the seed paper's) is used by ``ml`` and ``gls`` and for the bound
    of every method; the bound's σ of each parameter is in ``result.bound``.
    """
    noise = NoiseModel() if noise is None else noise
    mask = select_parameters() if mask is None else np.asarray(mask, dtype=bool)
    if method == "ml":
        result = identify_ml(start, measurements, noise, mask)
    elif method == "gls":
        result = identify_gls(start, measurements, noise, mask)
    elif method in ("length", "paper"):
        result = identify(start, measurements, method, mask)
    else:
        raise ValueError(f"unknown method {method!r}; choose from {', '.join(ESTIMATORS)}")
    bound = bound_stderr(result.geometry, measurements, noise, mask) if with_bound else None
    return dataclasses.replace(result, bound=bound, noise=noise)


def bound_stderr(
    geometry: Geometry, measurements: Measurements, noise: NoiseModel | None, mask: ArrayLike
) -> NDArray[np.float64]:
    """Cramér–Rao σ of each varied parameter of ``geometry`` for the measured poses.

    Zero where the noise model has no noise at all (the bound is then zero).
    """
    noise = NoiseModel() if noise is None else noise
    if not _has_pose_noise(noise) and noise.sigmas[0] == 0:
        return np.zeros(int(np.sum(mask)))
    cov = cramer_rao_covariance(
        geometry, measurements.poses, noise, np.asarray(mask, dtype=bool), measurements.readings
    )
    return np.sqrt(np.diag(cov))
