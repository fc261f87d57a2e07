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
from scipy.optimize import least_squares
from scipy.special import fdtri

from hexcal.core.geometry import Geometry
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import PARAMETER_SCALE, select_parameters
from hexcal.errors import IdentificationError
from hexcal.estimation.bounds import residual_covariances, whitening
from hexcal.estimation.identification import (
    IdentificationResult,
    _jacobian,
    _prepare,
    _residuals,
    check_data_size,
    identification_jacobian,
    identify,
    parameter_unpacker,
)
from hexcal.estimation.likelihood import LEG_SIGMA_FLOOR, identify_gls
from hexcal.models.pose import Measurements

#: Family-wise false alarm rate of the outlier test over all poses of a data set.
DEFAULT_ALPHA = 0.01

#: A pose whose leverage block has an eigenvalue above this cannot be checked: the
#: fit follows it whatever it says (it alone determines some parameter combination).
MAX_LEVERAGE = 1 - 1e-6


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


def pose_diagnostics(
    result: IdentificationResult,
    measurements: Measurements,
    mask: ArrayLike,
    alpha: float = DEFAULT_ALPHA,
    noise: NoiseModel | None = None,
) -> PoseDiagnostics:
    """Outlier statistics of every pose of a fit (see the module docstring).

    With ``noise``, ``result`` should be the generalised least-squares fit
    (:func:`hexcal.estimation.likelihood.identify_gls`) for the statistic to be exact; without, a
    least-squares fit of its ``method``.
    """
    mask = np.asarray(mask, dtype=bool)
    m, p = len(measurements), int(mask.sum())
    if noise is None:
        method = result.method if result.method in ("length", "paper") else "length"
        jac = identification_jacobian(result.geometry, measurements, method, mask)
        rot, pos = _prepare(result.geometry, measurements.poses)
        r = _residuals(result.geometry.to_vector(gains=True), rot, pos, measurements.readings, method)
    else:
        w = whitening(residual_covariances(result.geometry, measurements.poses, _floored(noise)))
        a = identification_jacobian(result.geometry, measurements, "length", mask).reshape(m, 6, p)
        jac = np.einsum("mij,mjk->mik", w, a).reshape(6 * m, p)
        rot, pos = _prepare(result.geometry, measurements.poses)
        raw = _residuals(result.geometry.to_vector(gains=True), rot, pos, measurements.readings, "length")
        r = np.einsum("mij,mj->mi", w, raw)
    q, _ = np.linalg.qr(jac / np.linalg.norm(jac, axis=0))
    qb = q.reshape(m, 6, p)
    hat = np.einsum("mik,mjk->mij", qb, qb)  # (m, 6, 6) diagonal blocks of H
    leverage = np.linalg.eigvalsh(hat)[:, -1]
    sse = float(np.sum(r**2))
    dof = 6 * m - p - 6
    ok = leverage < MAX_LEVERAGE
    stat = np.full(m, np.nan)
    if dof > 0 and ok.any():
        eye = np.eye(6)
        delta = np.einsum("mi,mi->m", r[ok], np.linalg.solve(eye - hat[ok], r[ok][..., None])[..., 0])
        stat[ok] = (delta / 6) / (np.maximum(sse - delta, 1e-300) / dof)
    # scipy.special, not scipy.stats: the latter costs half a second of import time
    if dof <= 0:
        threshold = np.inf
    elif noise is None:
        threshold = float(fdtri(1, dof, 1 - alpha / m))
    else:
        threshold = float(fdtri(6, dof, 1 - alpha / m))
    return PoseDiagnostics(stat, threshold, leverage)


def _floored(noise: NoiseModel) -> NoiseModel:
    """The noise model with a leg σ of at least LEG_SIGMA_FLOOR (keeps C_j invertible)."""
    return NoiseModel(
        leg=max(noise.sigmas[0], LEG_SIGMA_FLOOR),
        distribution="normal",
        pose_covariance=noise.pose_cov(),
    )


#: Screening: a pose whose largest leg residual under the robust fit exceeds this many
#: robust standard deviations is set aside before the least-squares fit.
SCREEN_THRESHOLD = 8.0


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
    rot, pos = _prepare(start, measurements.poses)
    readings = measurements.readings
    full0 = start.to_vector(gains=True)
    scale_p = PARAMETER_SCALE[mask]

    unpack = parameter_unpacker(full0, mask)

    def fun(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return _residuals(unpack(x), rot, pos, readings, "length").ravel()

    def jac(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return _jacobian(unpack(x), rot, pos, readings, "length")[:, mask] * scale_p

    x = np.zeros(int(mask.sum()))
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
        The fit on the poses kept.
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
    method: str = "length",
    mask: ArrayLike | None = None,
    alpha: float = DEFAULT_ALPHA,
    max_fraction: float = 0.25,
    noise: NoiseModel | None = None,
) -> RobustResult:
    """Identify without the outlying poses.

    1. Screening: poses with a gross residual under a robust soft-L1 fit
       (:func:`screen_poses`) are set aside.
    2. Backward: least squares on the rest; the most significant pose of
       :func:`pose_diagnostics` is removed and the fit repeated until none is flagged.
    3. Forward: each pose set aside is tried again, and re-admitted when it is not
       flagged in the fit that includes it.

    Parameters
    ----------
    start : Geometry
    measurements : Measurements
    method : {"length", "paper"}
    mask : array_like of bool, shape (48,), optional
    alpha : float
        Family-wise false alarm rate of the outlier test.
    max_fraction : float
        At most this fraction of the poses may be removed; more is an error (the data
        are not a calibration with a few gross errors).
    noise : NoiseModel, optional
        With a noise model the fits are generalised least squares and the test is the
        exact F(6, dof) one; without, least squares of ``method`` with the conservative
        threshold (module docstring).
    """
    mask = select_parameters() if mask is None else np.asarray(mask, dtype=bool)
    check_data_size(measurements, mask)
    m = len(measurements)
    limit = int(np.floor(max_fraction * m))
    keep = np.ones(m, dtype=bool)
    scores = screen_poses(start, measurements, mask)
    for j in np.argsort(-scores)[:limit]:
        if scores[j] > SCREEN_THRESHOLD:
            keep[j] = False
    order = [int(j) for j in np.argsort(-scores) if not keep[j]]

    def fit(sel: NDArray[np.bool_]) -> tuple[IdentificationResult, PoseDiagnostics]:
        sub = measurements.subset(sel)
        if noise is None:
            res = identify(start, sub, method=method, mask=mask)
        else:
            res = identify_gls(start, sub, noise, mask)
        return res, pose_diagnostics(res, sub, mask, alpha, noise)

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
    return RobustResult(result, tuple(measurements.ids[j] for j in order), diag, np.flatnonzero(keep))
