"""Detection of gross measurement errors (outlying poses) in an identification.

A pose is one group of six residuals (one per leg). The statistic of pose ``j`` is the
drop of the residual sum of squares when the pose is deleted, computed for all poses
at once from the hat matrix of the identification Jacobian (exact for a linear model,
and the fit is nearly linear at its solution):

    ΔSSE_j = r_jᵀ (I - H_jj)⁻¹ r_j,      F_j = (ΔSSE_j / 6) / ((SSE - ΔSSE_j) / (n - p - 6))

with ``H_jj`` the 6×6 diagonal block of ``H = J (JᵀJ)⁻¹ Jᵀ``. This is the group form of
the externally studentised residual (Cook & Weisberg, *Residuals and Influence in
Regression*, 1982, ch. 2.2). A pose is flagged when ``F_j`` exceeds the ``1 - alpha / m``
quantile of its null distribution (a Bonferroni bound over the ``m`` poses):

- **with a noise model** (the default of ``hexcal identify``), residuals and Jacobian are
  whitened by the covariance ``C_j`` of each pose's six residuals
  (:func:`hexcal.estimation.bounds.residual_covariances`; the pose measurement error is
  shared by the six legs) and the fit is generalised least squares. The six whitened
  residuals are then independent with equal variance and ``F_j`` follows F(6, n - p - 6)
  under Gaussian noise, whatever the scale of the noise;
- **without a noise model**, on a plain least-squares fit, the six residuals of a pose
  may be correlated in an unknown way. The threshold is then the quantile of F(1, n - p - 6),
  the distribution of ``F_j`` when the six residuals are perfectly correlated: the
  heaviest tail possible, so the false alarm rate stays below ``alpha`` however the noise
  is shared, at the price of detecting only larger errors.

The robust identification removes the most significant pose, refits, and repeats
until no pose is flagged; removing a pose gives exactly the fit on the remaining
data, so the result is as if the outlier had never been measured.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.linalg import whitening
from hexcal.core.noise import NoiseModel
from hexcal.errors import IdentificationError
from hexcal.estimation.bounds import LEG_SIGMA_FLOOR, residual_covariances
from hexcal.estimation.problem import Problem
from hexcal.estimation.registry import get_estimator
from hexcal.estimation.result import IdentificationResult
from hexcal.instruments.pose import Measurements

#: Family-wise false alarm rate of the outlier test over all poses of a data set.
DEFAULT_ALPHA = 0.01

#: A pose whose leverage block has an eigenvalue above this cannot be checked: the
#: fit follows it whatever it says (it alone determines some parameter combination).
MAX_LEVERAGE = 1 - 1e-6

#: Screening: a pose whose largest leg residual under the robust fit exceeds this many
#: robust standard deviations is set aside before the least-squares fit.
SCREEN_THRESHOLD = 8.0


@dataclass(frozen=True)
class PoseDiagnostics:
    """Per-pose outlier statistics of a fit.

    Attributes
    ----------
    statistic : ndarray, shape (m,)
        ``F_j`` (NaN where the pose cannot be checked).
    threshold : float
        Critical value of ``F_j``.
    leverage : ndarray, shape (m,)
        Largest eigenvalue of ``H_jj``.
    """

    statistic: NDArray[np.float64]
    threshold: float
    leverage: NDArray[np.float64]

    @property
    def flagged(self) -> NDArray[np.intp]:
        """Indices of the poses beyond the threshold, most significant first."""
        stat = np.where(np.isfinite(self.statistic), self.statistic, -np.inf)
        idx = np.flatnonzero(stat > self.threshold)
        return idx[np.argsort(-stat[idx])]

    @property
    def uncheckable(self) -> NDArray[np.intp]:
        return np.flatnonzero(~np.isfinite(self.statistic))

    def to_dict(self, ids: tuple[str, ...] | None = None) -> dict[str, object]:
        """Statistics, threshold and flagged poses (by id when ``ids`` are given)."""
        label = (lambda k: ids[k]) if ids is not None else int
        return {
            "statistic": self.statistic.tolist(),
            "threshold": self.threshold,
            "leverage": self.leverage.tolist(),
            "flagged": [label(k) for k in self.flagged],
        }


def block_diagnostics(
    residuals: NDArray[np.float64],
    jacobian: NDArray[np.float64],
    alpha: float = DEFAULT_ALPHA,
    exact: bool = True,
) -> PoseDiagnostics:
    """Deletion statistics of groups of residuals in a linear(ised) least-squares model.

    Parameters
    ----------
    residuals : ndarray, shape (m, k)
        ``k`` residuals of each of ``m`` groups (poses) at the solution.
    jacobian : ndarray, shape (m k, p)
        Their Jacobian with respect to the ``p`` varied parameters.
    alpha : float
        Family-wise false alarm rate (Bonferroni over the groups).
    exact : bool
        The residuals are whitened (independent, equal variance): threshold from
        F(k, dof); otherwise the conservative F(1, dof) (module docstring).
    """
    from scipy.special import fdtri  # not scipy.stats: that costs half a second of import time

    m, k = residuals.shape
    p = jacobian.shape[1]
    q, _ = np.linalg.qr(jacobian / np.linalg.norm(jacobian, axis=0))
    qb = q.reshape(m, k, p)
    hat = np.einsum("mik,mjk->mij", qb, qb)  # (m, k, k) diagonal blocks of H
    leverage = np.linalg.eigvalsh(hat)[:, -1]
    sse = float(np.sum(residuals**2))
    dof = k * m - p - k
    ok = leverage < MAX_LEVERAGE
    stat = np.full(m, np.nan)
    r = residuals
    if dof > 0 and ok.any():
        eye = np.eye(k)
        delta = np.einsum("mi,mi->m", r[ok], np.linalg.solve(eye - hat[ok], r[ok][..., None])[..., 0])
        stat[ok] = (delta / k) / (np.maximum(sse - delta, 1e-300) / dof)
    if dof <= 0:
        threshold = np.inf
    else:
        threshold = float(fdtri(k if exact else 1, dof, 1 - alpha / m))
    return PoseDiagnostics(stat, threshold, leverage)


def floored(noise: NoiseModel) -> NoiseModel:
    """The noise model with a leg σ of at least LEG_SIGMA_FLOOR (keeps C_j invertible)."""
    return NoiseModel(
        leg=max(noise.sigmas[0], LEG_SIGMA_FLOOR),
        distribution="normal",
        pose_covariance=noise.pose_cov(),
    )


def pose_diagnostics(
    result: IdentificationResult,
    measurements: Measurements,
    mask: ArrayLike,
    alpha: float = DEFAULT_ALPHA,
    noise: NoiseModel | None = None,
) -> PoseDiagnostics:
    """Outlier statistics of every pose of a full-pose fit (see the module docstring).

    With ``noise``, ``result`` should be the generalised least-squares fit for the statistic
    to be exact; without, a least-squares fit of its ``method``.
    """
    problem = Problem(result.geometry, measurements, mask=mask)
    m = len(problem)
    if noise is None:
        variant = result.method if result.method in ("length", "paper") else "length"
        jac = problem.leg_jacobian(problem.full0, variant, scaled=False)
        r = problem.leg_residuals(problem.full0, variant)
    else:
        w = whitening(residual_covariances(result.geometry, measurements.poses, floored(noise)))
        a = problem.leg_jacobian(problem.full0, "length", scaled=False).reshape(m, 6, -1)
        jac = np.einsum("mij,mjk->mik", w, a).reshape(6 * m, -1)
        r = np.einsum("mij,mj->mi", w, problem.leg_residuals(problem.full0))
    return block_diagnostics(r, jac, alpha, exact=noise is not None)


def screen_poses(
    start: Geometry, measurements: Measurements, mask: NDArray[np.bool_], rounds: int = 3
) -> NDArray[np.float64]:
    """Per-pose scores from a fit that gross errors cannot pull (for screening only).

    Minimises the soft-L1 loss of the leg length residuals (``least_squares`` with
    ``loss="soft_l1"``), whose influence is bounded, re-estimating the scale
    ``f_scale = 1.4826 MAD`` of the residuals each round (starting at 1 mm). Returns
    ``max_i |r_ji| / scale`` for every pose ``j``. Several gross errors that would drag
    a least-squares fit (and hide each other from its diagnostics) stand out here.
    """
    from scipy.optimize import least_squares

    problem = Problem(start, measurements, mask=mask)
    fun, jac = problem.least_squares_functions("length")
    x = np.zeros(problem.n_free)
    f_scale = 1.0
    for _ in range(rounds):
        sol = least_squares(fun, x, jac=jac, method="trf", loss="soft_l1", f_scale=f_scale, x_scale=1.0)
        x = sol.x
        f_scale = max(1.4826 * float(np.median(np.abs(sol.fun))), 1e-9)
    r = fun(x).reshape(len(measurements), 6)
    return np.max(np.abs(r), axis=1) / f_scale


@dataclass(frozen=True)
class RobustResult:
    """A fit without its outlying poses.

    Attributes
    ----------
    result : IdentificationResult
        The fit on the poses kept (its ``outliers`` name the poses removed).
    outliers : tuple of str
        Ids of the poses removed, in the order they were found.
    diagnostics : PoseDiagnostics
        Statistics of the kept poses under the final fit.
    kept : ndarray of int
        Indices (into the input measurements) of the poses kept.
    """

    result: IdentificationResult
    outliers: tuple[str, ...]
    diagnostics: PoseDiagnostics
    kept: NDArray[np.intp]


def identify_robust(
    start: Geometry,
    measurements: Measurements,
    method: str | None = None,
    mask: ArrayLike | None = None,
    alpha: float = DEFAULT_ALPHA,
    max_fraction: float = 0.25,
    noise: NoiseModel | None = None,
) -> RobustResult:
    """Identify with any registered estimator, without the outlying poses.

    1. Screening: poses with a gross residual under a robust soft-L1 fit
       (:func:`screen_poses`) are set aside.
    2. Backward: the estimator ``method`` fits the rest; the most significant pose of
       :func:`pose_diagnostics` is removed and the fit repeated until none is flagged.
    3. Forward: each pose set aside is tried again, and re-admitted when it is not
       flagged in the fit that includes it.

    Parameters
    ----------
    start : Geometry
    measurements : Measurements
    method : str, optional
        Any estimator of :data:`hexcal.estimation.registry.ESTIMATORS`; default ``gls``
        with a noise model and ``length`` without.
    mask : array_like of bool, shape (48,), optional
    alpha : float
        Family-wise false alarm rate of the outlier test.
    max_fraction : float
        At most this fraction of the poses may be removed; more is an error (the data
        are not a calibration with a few gross errors).
    noise : NoiseModel, optional
        With a noise model the test is the exact F(6, dof) one on the whitened residuals;
        without, the conservative threshold on the fit's own residuals (module docstring).
    """
    method = ("gls" if noise is not None else "length") if method is None else method
    estimator = get_estimator(method)
    problem = Problem(start, measurements, mask=mask)
    problem.check_size()
    mask = problem.mask
    m = len(measurements)
    limit = int(np.floor(max_fraction * m))
    keep = np.ones(m, dtype=bool)
    scores = screen_poses(start, measurements, mask)
    for j in np.argsort(-scores)[:limit]:
        if scores[j] > SCREEN_THRESHOLD:
            keep[j] = False
    order = [int(j) for j in np.argsort(-scores) if not keep[j]]

    def fit(sel: NDArray[np.bool_]) -> tuple[IdentificationResult, PoseDiagnostics]:
        sub = problem.subset(sel)
        res = estimator.fit(sub, noise if estimator.uses_noise else None)
        return res, pose_diagnostics(res, sub.data, mask, alpha, noise)

    result, diag = fit(keep)
    while diag.flagged.size:
        if m - keep.sum() >= limit:
            raise IdentificationError(
                f"more than {limit} of {m} poses are outliers: the data do not fit the model "
                "(wrong geometry, wrong Euler sequence, or a systematic error)"
            )
        worst = np.flatnonzero(keep)[diag.flagged[0]]
        keep[worst] = False
        order.append(int(worst))
        result, diag = fit(keep)
    for j in list(order):
        trial = keep.copy()
        trial[j] = True
        try:
            res, dg = fit(trial)
        except IdentificationError:
            continue
        pos_in_fit = int(np.flatnonzero(trial).tolist().index(j))
        if dg.flagged.size == 0 and np.isfinite(dg.statistic[pos_in_fit]):
            keep, result, diag = trial, res, dg
            order.remove(j)
    outliers = tuple(measurements.ids[j] for j in order)
    return RobustResult(result.replace(outliers=outliers), outliers, diag, np.flatnonzero(keep))
