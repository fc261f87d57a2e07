"""Identification of the kinematic parameters from measured poses and leg readings.

Two residuals are available, both per pose ``j`` and leg ``i`` with the leg vector
``v_ij = o_j + R_j s_i - u_i``:

- ``"paper"``: the seed paper's cost (Agheli & Nategh 2009, eq. 3), after Zhuang et
  al. (1998) and Chiu & Perng (2004): ``r_ij = |v_ij|² - (l0_i + g_i dl_ij)²`` (mm²);
- ``"length"``: the leg length residual ``r_ij = |v_ij| - (l0_i + g_i dl_ij)`` (mm).

Both are minimised by Levenberg–Marquardt (``scipy.optimize.least_squares``,
``method="lm"``) with the analytic Jacobian of :func:`identification_jacobian`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from hexcal.core.conventions import as_poses, rotation_matrices
from hexcal.core.geometry import Geometry
from hexcal.core.linalg import gram_pinv, numerical_rank, scaled_svd
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import (
    MIN_POSES,
    N_ALL_PARAMETERS,
    PARAMETER_NAMES,
    PARAMETER_SCALE,
    ParameterSet,
    select_parameters,
)
from hexcal.errors import IdentificationError
from hexcal.models.pose import Measurements

METHODS = ("paper", "length")

_LEG = np.arange(6)
_U_COLS = 3 * _LEG[:, None] + np.arange(3)
_S_COLS = 18 + _U_COLS
_L0_COLS = 36 + _LEG
_G_COLS = 42 + _LEG




def _split(params: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    return (
        params[:18].reshape(6, 3),
        params[18:36].reshape(6, 3),
        params[36:42],
        params[42:48],
    )


def _leg_terms(
    params: NDArray[np.float64],
    rotations: NDArray[np.float64],
    positions: NDArray[np.float64],
    readings: NDArray[np.float64],
) -> tuple[NDArray, NDArray, NDArray]:
    """Leg vectors ``v`` (m, 6, 3), rotated joints ``R s`` (m, 6, 3), and ``l0 + g dl`` (m, 6)."""
    u, s, l0, g = _split(params)
    rotated = np.einsum("mjk,ik->mij", rotations, s)
    legs = rotated + positions[:, None, :] - u
    return legs, rotated, l0 + g * readings


def _residuals(
    params: NDArray[np.float64],
    rotations: NDArray[np.float64],
    positions: NDArray[np.float64],
    readings: NDArray[np.float64],
    method: str,
) -> NDArray[np.float64]:
    legs, _, model = _leg_terms(params, rotations, positions, readings)
    sq = np.einsum("mik,mik->mi", legs, legs)
    if method == "paper":
        return sq - model**2
    return np.sqrt(sq) - model


def _jacobian(
    params: NDArray[np.float64],
    rotations: NDArray[np.float64],
    positions: NDArray[np.float64],
    readings: NDArray[np.float64],
    method: str,
) -> NDArray[np.float64]:
    """Full Jacobian ``d r / d params``, shape ``(m * 6, 48)``."""
    legs, _, model = _leg_terms(params, rotations, positions, readings)
    m = legs.shape[0]
    if method == "paper":
        d_leg = 2.0 * legs  # d|v|²/dv
        d_model = -2.0 * model  # d(-(l0 + g dl)²)/d(l0 + g dl)
    else:
        d_leg = legs / np.sqrt(np.einsum("mik,mik->mi", legs, legs))[..., None]
        d_model = -np.ones_like(model)
    jac = np.zeros((m, 6, N_ALL_PARAMETERS))
    jac[:, _LEG[:, None], _U_COLS] = -d_leg
    # d v / d s_i = R_j, so d r / d s_i = (d r / d v) R_j
    jac[:, _LEG[:, None], _S_COLS] = np.einsum("mik,mkj->mij", d_leg, rotations)
    jac[:, _LEG, _L0_COLS] = d_model
    jac[:, _LEG, _G_COLS] = d_model * readings
    return jac.reshape(m * 6, N_ALL_PARAMETERS)


def _prepare(geometry: Geometry, poses: ArrayLike) -> tuple[NDArray, NDArray]:
    poses = as_poses(poses, "measured poses").reshape(-1, 6)
    return rotation_matrices(poses[:, 3:], geometry.euler), np.ascontiguousarray(poses[:, :3])


def identification_residuals(
    geometry: Geometry, measurements: Measurements, method: str = "length"
) -> NDArray[np.float64]:
    """Residuals of every pose and leg for ``geometry``, shape ``(m, 6)``.

    Units: mm for ``"length"``, mm² for ``"paper"``.
    """
    _check_method(method)
    rot, pos = _prepare(geometry, measurements.poses)
    return _residuals(geometry.to_vector(gains=True), rot, pos, measurements.readings, method)


def identification_jacobian(
    geometry: Geometry,
    measurements: Measurements,
    method: str = "length",
    mask: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Analytic Jacobian of the identification residuals with respect to the parameters.

    Parameters
    ----------
    geometry : Geometry
        Parameters at which to evaluate.
    measurements : Measurements
    method : {"length", "paper"}
    mask : array_like of bool, shape (48,), optional
        Parameters to keep (columns); default the 42 of joints and l0.

    Returns
    -------
    ndarray, shape (6 m, n_selected)
        Row ``6 j + i`` is pose ``j``, leg ``i``; columns in :data:`PARAMETER_NAMES`
        order.
    """
    _check_method(method)
    mask = select_parameters() if mask is None else np.asarray(mask, dtype=bool)
    rot, pos = _prepare(geometry, measurements.poses)
    jac = _jacobian(geometry.to_vector(gains=True), rot, pos, measurements.readings, method)
    return jac[:, mask]


def _check_method(method: str) -> None:
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose from {', '.join(METHODS)}")


@dataclass(frozen=True, eq=False)
class IdentificationResult:
    """Outcome of :func:`identify` (after lmfit's ``MinimizerResult``).

    Attributes
    ----------
    geometry : Geometry
        The identified geometry (the start geometry with the varied parameters replaced).
    start : Geometry
        The geometry the identification started from (usually the nominal one).
    method : str
    names : tuple of str
        Names of the varied parameters.
    values, start_values, stderr : ndarray, shape (n,)
        Identified values, start values and standard errors of the varied parameters.
    covariance, correlation : ndarray, shape (n, n)
    singular_values : ndarray, shape (n,)
        Singular values of the column-normalised Jacobian at the solution, descending.
    singular_vectors : ndarray, shape (n, n)
        Row ``k`` is the (normalised-parameter) combination of ``singular_values[k]``.
    rank : int
    residuals : ndarray, shape (m, 6)
        Residuals at the solution (units of the method).
    leg_rms_before, leg_rms_after : float
        RMS of the leg length residual ``|v| - (l0 + g dl)`` at the start and at the
        solution, mm (comparable across methods).
    rms_before, rms_after : float
        RMS of the method's own residual.
    cost : float
        ``0.5 * sum(residuals**2)`` at the solution.
    nfev, njev : int
        Function and Jacobian evaluations (``njev`` counts the LM iterations).
    status : int
    message : str
    n_poses : int
    ids : tuple of str
        Ids of the poses used.
    bound : ndarray, shape (n,), optional
        Cramér–Rao σ of each parameter under ``noise`` (see :mod:`hexcal.estimation.likelihood`).
    noise : NoiseModel, optional
        The noise model used by the estimator or the bound.
    """

    geometry: Geometry
    start: Geometry
    method: str
    names: tuple[str, ...]
    values: NDArray[np.float64]
    start_values: NDArray[np.float64]
    stderr: NDArray[np.float64]
    covariance: NDArray[np.float64]
    correlation: NDArray[np.float64]
    singular_values: NDArray[np.float64]
    singular_vectors: NDArray[np.float64]
    rank: int
    residuals: NDArray[np.float64]
    leg_rms_before: float
    leg_rms_after: float
    rms_before: float
    rms_after: float
    cost: float
    nfev: int
    njev: int
    status: int
    message: str
    n_poses: int
    ids: tuple[str, ...] = field(default=())
    bound: NDArray[np.float64] | None = None
    noise: NoiseModel | None = None

    @property
    def reduced_chi2(self) -> float:
        """Residual variance per degree of freedom (about 1 for whitened residuals
        under a correct noise model)."""
        dof = self.dof
        return float(np.sum(self.residuals**2) / dof) if dof > 0 else float("nan")

    @property
    def dof(self) -> int:
        """Degrees of freedom: six leg equations per pose less the varied parameters."""
        return 6 * self.n_poses - len(self.names)

    @property
    def parameters(self) -> dict[str, float]:
        """Identified values by name."""
        return dict(zip(self.names, self.values.tolist(), strict=True))

    @property
    def standard_errors(self) -> dict[str, float]:
        """Standard errors by name."""
        return dict(zip(self.names, self.stderr.tolist(), strict=True))

    def calibration_metadata(self) -> dict[str, Any]:
        """The ``calibration:`` mapping written into a calibrated geometry file."""
        return {
            "method": self.method,
            "poses": self.n_poses,
            "leg_rms_before_mm": self.leg_rms_before,
            "leg_rms_after_mm": self.leg_rms_after,
            "iterations": self.njev,
            "status": self.status,
            "rank": self.rank,
            "stderr": self.standard_errors,
            **(
                {"bound": dict(zip(self.names, self.bound.tolist(), strict=True))}
                if self.bound is not None
                else {}
            ),
            **({"noise": self.noise.describe()} if self.noise is not None else {}),
        }


def identify(
    start: Geometry,
    measurements: Measurements,
    method: str = "paper",
    mask: ArrayLike | None = None,
    xtol: float = 1e-12,
    max_nfev: int | None = None,
) -> IdentificationResult:
    """Identify kinematic parameters by Levenberg–Marquardt.

    Parameters
    ----------
    start : Geometry
        Start values (the nominal geometry); parameters not varied keep its values.
    measurements : Measurements
        Measured poses (in ``start.euler``) and leg readings.
    method : {"paper", "length"}
        The residual (see the module docstring).
    mask : array_like of bool, shape (48,), optional
        Parameters to vary; default joints and l0 (:func:`hexcal.core.geometry.select_parameters`).
    xtol : float
        Relative step tolerance of the solver.
    max_nfev : int, optional
        Limit on function evaluations (default scipy's).

    Returns
    -------
    IdentificationResult

    Raises
    ------
    IdentificationError
        Fewer poses than needed, a rank-deficient Jacobian, or no convergence.

    Notes
    -----
    The parameters are varied in units of :data:`PARAMETER_SCALE`. The covariance is
    ``s² V S⁻² Vᵀ`` from the SVD of the column-normalised Jacobian at the solution
    (as ``scipy.optimize.curve_fit`` does), with ``s²`` the residual variance
    ``sum(r²) / (6 m - n)``; standard errors are the square roots of its diagonal.
    """
    _check_method(method)
    mask = select_parameters() if mask is None else np.asarray(mask, dtype=bool)
    if mask.shape != (N_ALL_PARAMETERS,):
        raise ValueError(f"mask must have shape (48,), got {mask.shape}")
    n_vary = int(mask.sum())
    check_data_size(measurements, mask)
    rot, pos = _prepare(start, measurements.poses)
    readings = measurements.readings
    full0 = start.to_vector(gains=True)
    scale = PARAMETER_SCALE[mask]

    unpack = parameter_unpacker(full0, mask)

    def fun(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return _residuals(unpack(x), rot, pos, readings, method).ravel()

    def jac(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return _jacobian(unpack(x), rot, pos, readings, method)[:, mask] * scale

    check_rank(jac(np.zeros(n_vary)), mask)
    r0 = fun(np.zeros(n_vary))
    # x_scale=1: the variables are already in PARAMETER_SCALE units (scipy >= 1.16
    # defaults LM to 'jac' scaling, which starts with steps far too small here)
    sol = least_squares(
        fun,
        np.zeros(n_vary),
        jac=jac,
        method="lm",
        x_scale=1.0,
        xtol=xtol,
        ftol=1e-12,
        gtol=1e-12,
        max_nfev=max_nfev,
    )
    if sol.status <= 0 or not np.all(np.isfinite(sol.x)):
        raise IdentificationError(f"the solver did not converge: {sol.message}")
    return finish_result(start, measurements, method, mask, unpack(sol.x), sol.fun, sol.jac, _rms(r0), sol)


def check_data_size(measurements: Measurements, mask: NDArray[np.bool_]) -> None:
    """Refuse data sets too small to determine the varied parameters."""
    n_vary = int(mask.sum())
    m = len(measurements)
    min_poses = MIN_POSES + (1 if mask[42:].any() else 0)
    if m < min_poses:
        raise IdentificationError(
            f"{m} poses cannot determine the parameters: at least {min_poses} are needed "
            f"(each leg has {min_poses} parameters and gets one equation per pose)"
        )
    if 6 * m < n_vary:
        raise IdentificationError(f"{6 * m} equations for {n_vary} parameters: measure more poses")


def check_rank(jac: NDArray[np.float64], mask: NDArray[np.bool_], where: str = "") -> None:
    """Refuse a rank-deficient (scaled) Jacobian, naming the weakest combination."""
    svd = scaled_svd(jac)
    n, rank = int(mask.sum()), numerical_rank(svd.singular_values)
    if rank < n:
        raise IdentificationError(
            f"the poses cannot identify all parameters{where} (rank-deficient Jacobian: rank "
            f"{rank} of {n}; weakest combination: {_combination(svd.vt[-1], mask)})"
        )


def finish_result(
    start: Geometry,
    measurements: Measurements,
    method: str,
    mask: NDArray[np.bool_],
    full: NDArray[np.float64],
    residuals: NDArray[np.float64],
    jac_scaled: NDArray[np.float64],
    rms_before: float,
    sol: Any,
    dof: int | None = None,
) -> IdentificationResult:
    """Build the result of a converged fit (shared by all estimators).

    ``jac_scaled`` is the Jacobian of ``residuals`` with respect to the varied
    parameters in :data:`PARAMETER_SCALE` units; ``dof`` defaults to
    ``residuals.size - n``.
    """
    scale = PARAMETER_SCALE[mask]
    n_vary = int(mask.sum())
    m = len(measurements)
    svd = scaled_svd(jac_scaled)
    sv, vt = svd.singular_values, svd.vt
    rank = numerical_rank(sv)
    if rank < n_vary:
        raise IdentificationError(
            f"rank-deficient Jacobian at the solution (rank {rank} of {n_vary}; weakest "
            f"combination: {_combination(vt[-1], mask)})"
        )
    dof = residuals.size - n_vary if dof is None else dof
    # an exactly determined fit (dof 0) has no residual to estimate the noise from
    s2 = float(residuals @ residuals) / dof if dof > 0 else float("nan")
    cov = gram_pinv(svd) * s2 * np.outer(scale, scale)
    stderr = np.sqrt(np.diag(cov))
    corr = cov / np.outer(stderr, stderr)
    rot, pos = _prepare(start, measurements.poses)
    full0 = start.to_vector(gains=True)
    r0_len = _residuals(full0, rot, pos, measurements.readings, "length")
    r_len = _residuals(full, rot, pos, measurements.readings, "length")
    names = tuple(n for n, keep in zip(PARAMETER_NAMES, mask, strict=True) if keep)
    return IdentificationResult(
        geometry=start.with_vector(full),
        start=start,
        method=method,
        names=names,
        values=full[mask],
        start_values=full0[mask],
        stderr=stderr,
        covariance=cov,
        correlation=corr,
        singular_values=sv,
        singular_vectors=vt,
        rank=rank,
        residuals=residuals.reshape(m, -1),
        leg_rms_before=_rms(r0_len),
        leg_rms_after=_rms(r_len),
        rms_before=rms_before,
        rms_after=_rms(residuals),
        cost=float(sol.cost),
        nfev=int(sol.nfev),
        njev=int(sol.njev or 0),
        status=int(sol.status),
        message=str(sol.message),
        n_poses=m,
        ids=measurements.ids,
    )


def parameter_unpacker(
    full0: NDArray[np.float64], mask: NDArray[np.bool_]
) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """The map from solver variables to the full 48-vector (:meth:`ParameterSet.unpacker`)."""
    return ParameterSet(PARAMETER_NAMES, full0, mask, PARAMETER_SCALE).unpacker()


def _rms(x: NDArray[np.float64]) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def _combination(vector: NDArray[np.float64], mask: NDArray[np.bool_], top: int = 4) -> str:
    """Readable form of a parameter combination (the largest components)."""
    names = [n for n, keep in zip(PARAMETER_NAMES, mask, strict=True) if keep]
    order = np.argsort(-np.abs(vector))[:top]
    return " ".join(f"{vector[k]:+.2f}·{names[k]}" for k in order)
