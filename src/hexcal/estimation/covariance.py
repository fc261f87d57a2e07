"""The covariance of a converged fit and the result it makes: one rule for every estimator.

:func:`finish_result` takes a fit's solution, residuals and Jacobian (solver units) and builds
the :class:`~hexcal.estimation.result.IdentificationResult`: the covariance ``s² P (JᵀJ)⁺ Pᵀ``
from the SVD of the column-normalised Jacobian (as ``scipy.optimize.curve_fit`` does; ``P``
the projector onto the gauge convention), the rank beyond the gauges, standard errors,
correlations, and what the sessions' instruments became.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hexcal.core.linalg import gram_pinv, numerical_rank, scaled_svd
from hexcal.core.noise import NoiseModel
from hexcal.errors import IdentificationError
from hexcal.estimation.gauge import CONVENTION, Gauge, complement_basis, gauge_projector
from hexcal.estimation.levenberg import Convergence
from hexcal.estimation.problem import Problem
from hexcal.estimation.result import IdentificationResult, rms


def finish_result(
    problem: Problem,
    method: str,
    full: NDArray[np.float64],
    residuals: NDArray[np.float64],
    jac_scaled: NDArray[np.float64],
    rms_before: float,
    sol: Convergence,
    dof: int | None = None,
    leg_rms: tuple[float, float] | None = None,
    gauge: Gauge | None = None,
    poses: NDArray[np.float64] | None = None,
    blocks: list[NDArray[np.float64]] | None = None,
    noises: tuple[NoiseModel, ...] = (),
    leg_residuals: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
) -> IdentificationResult:
    """Build the result of a converged fit (shared by all estimators).

    ``jac_scaled`` is the Jacobian of ``residuals`` with respect to the varied parameters in
    solver units; ``dof`` defaults to ``residuals.size - n``. The covariance is
    ``s² P (JᵀJ)⁺ Pᵀ`` from the SVD of the column-normalised Jacobian (as
    ``scipy.optimize.curve_fit`` does), with ``s²`` the residual variance per degree of
    freedom and ``P`` the projector onto the gauge convention (the identity without gauges,
    :mod:`hexcal.estimation.gauge`). ``leg_rms`` (before, after) defaults to the leg length
    residuals at the measured poses. ``blocks`` are the residuals of each session when they
    differ in width.
    """
    n_vary = problem.n_free
    g = 0 if gauge is None else gauge.size
    svd = scaled_svd(jac_scaled if g == 0 else jac_scaled @ complement_basis(gauge))
    rank = numerical_rank(svd.singular_values)
    if rank < n_vary - g:
        raise IdentificationError(
            f"rank-deficient Jacobian at the solution (rank {rank} of {n_vary - g}; weakest "
            f"combination: {problem.combination(svd.vt[-1]) if g == 0 else 'beyond the gauges'})"
        )
    dof = residuals.size - (n_vary - g) if dof is None else dof
    # an exactly determined fit (dof 0) has no residual to estimate the noise from
    s2 = float(residuals @ residuals) / dof if dof > 0 else float("nan")
    if g == 0:
        cov = gram_pinv(svd) * s2 * np.outer(problem.scale, problem.scale)
    else:
        proj = gauge_projector(gauge)
        cov = proj @ gram_pinv(scaled_svd(jac_scaled)) @ proj.T * s2 * np.outer(problem.scale, problem.scale)
    stderr = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(stderr, stderr)
    if leg_residuals is None and problem.determines_pose:
        leg_residuals = (problem.leg_residuals(problem.full0), problem.leg_residuals(full))
        poses = problem.measured_poses() if poses is None else poses
    if leg_rms is None and leg_residuals is not None:
        leg_rms = (rms(leg_residuals[0]), rms(leg_residuals[1]))
    leg_rms = (float("nan"), float("nan")) if leg_rms is None else leg_rms
    mask = problem.mask
    widths = {b.shape[1] for b in blocks} if blocks else set()
    shaped = residuals.reshape(len(problem), -1) if len(widths) <= 1 else residuals
    return IdentificationResult(
        method=method,
        names=problem.names,
        values=full[mask],
        status=int(sol.status),
        iterations=int(sol.iterations),
        cost=float(sol.cost),
        rank=rank,
        start=problem.start,
        start_values=problem.full0[mask],
        full=np.array(full),
        geometry=problem.geometry(full),
        stderr=stderr,
        covariance=cov,
        correlation=corr,
        singular_values=svd.singular_values,
        singular_vectors=svd.vt,
        residuals=shaped,
        leg_rms_before=leg_rms[0],
        leg_rms_after=leg_rms[1],
        rms_before=rms_before,
        rms_after=rms(residuals),
        nfev=int(sol.evaluations),
        n_poses=len(problem),
        ids=problem.ids,
        dof=dof,
        model="+".join(dict.fromkeys(p.instrument.name for p in problem.parts)),
        sessions=tuple(p.label for p in problem.parts),
        session_sizes=tuple(len(p) for p in problem.parts),
        instruments=problem.instruments(full),
        gauges=() if gauge is None else gauge.labels,
        convention=CONVENTION if g else "",
        poses=poses,
        noises=tuple(noises),
        leg_residuals_before=None if leg_residuals is None else leg_residuals[0],
        leg_residuals_after=None if leg_residuals is None else leg_residuals[1],
        gauge_directions=None if g == 0 else gauge.generators * problem.scale[:, None],
    )
