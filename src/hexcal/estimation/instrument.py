"""Identification with an instrument setup: register the frame, fit machine and setup by
maximum likelihood with the gauges removed, and report under the gauge convention.

:func:`identify_instrument` is the entry ``hexcal identify --setup`` wires: it takes the
nominal geometry, the data (:class:`hexcal.instruments.targets.TargetMeasurements` or tool poses
as :class:`hexcal.instruments.pose.Measurements`) and a :class:`hexcal.instruments.setup.Setup`.

1. ``instrument_frame: auto``: the frame's start from :func:`hexcal.instruments.registration.register_frame`.
2. The gauges (:mod:`hexcal.estimation.gauge`) are found at the start; Levenberg–Marquardt
   varies only the directions orthogonal to them, on the variable-projection likelihood of
   :class:`hexcal.estimation.likelihood.PoseProjection` (poses eliminated, any model).
3. The solution is moved to the convention's frames; standard errors (``s² P (JᵀJ)⁺ Pᵀ``) and
   the Cramér–Rao bound (``P (JᵀJ)⁺ Pᵀ`` with the known noise) are those of the gauge-fixed
   parameters.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.linalg import numerical_rank, scaled_svd
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import DEFAULT_FIT, ParameterSet
from hexcal.errors import IdentificationError, UsageError
from hexcal.estimation.gauge import (
    CONVENTION,
    Gauge,
    apply_convention,
    complement_basis,
    gauge_freedoms,
    unidentifiable,
)
from hexcal.estimation.least_squares import solve_least_squares
from hexcal.estimation.likelihood import PoseProjection
from hexcal.estimation.model_bounds import gauge_fixed_covariance
from hexcal.estimation.problem import Problem
from hexcal.estimation.result import IdentificationResult, rms
from hexcal.instruments.base import MeasurementModel
from hexcal.instruments.instrument_data import instrument_model
from hexcal.instruments.registration import Registration, register_frame
from hexcal.instruments.setup import Setup


def instrument_parameters(
    geometry: Geometry, setup: Setup, fit: str | Sequence[str] | None = None, fix: Iterable[str] = ()
) -> ParameterSet:
    """Machine plus setup parameters; ``fit`` groups (default ``joints,l0`` and every setup
    group not ``fixed``), less ``fix``. Quantities the setup marks ``fixed`` never vary."""
    params = ParameterSet.machine(geometry.to_vector(gains=True)) + setup.parameters()
    held = setup.parameters().vary
    if fit is None:
        groups = [g for g in ("frame", setup.kind) if g in params.groups]
        fit = DEFAULT_FIT + "," + ",".join(groups)
    fix = list(fix)
    group_fix = [f for f in fix if f in params.groups]
    for group in group_fix:  # a group name in fix holds the whole group
        fix.remove(group)
        fix.extend(params.groups[group])
    params = params.select(fit, fix)
    vary = np.array(params.vary)
    vary[len(vary) - len(held) :] &= held
    if not vary.any():
        raise UsageError("no parameter left to identify")
    return ParameterSet(params.names, params.values, vary, params.scales, params.groups)


@dataclass(frozen=True, eq=False)
class InstrumentResult:
    """Identification with an instrument setup.

    Attributes
    ----------
    result : IdentificationResult
        Machine and setup parameters under the gauge convention; ``bound`` is the
        gauge-fixed Cramér–Rao σ.
    setup : Setup
        The calibrated setup (identified values, ``calibration`` mapping of standard errors).
    registration : Registration or None
        The frame registration (``auto``).
    gauges : tuple of str
        The gauge freedoms removed.
    convention : str
    unidentifiable : list of str
        Combinations not determined beyond the gauges (empty when all are).
    poses : ndarray, shape (m, 6)
        Estimated true poses (the convention's base frame).
    """

    result: IdentificationResult
    setup: Setup
    registration: Registration | None
    gauges: tuple[str, ...]
    convention: str
    unidentifiable: list[str]
    poses: NDArray[np.float64]

    @property
    def geometry(self) -> Geometry:
        return self.result.geometry


def _result(
    problem: Problem, inner: PoseProjection, full: NDArray, gauge: Gauge, sol: Any, rms0: float
) -> tuple:
    x = (full[problem.mask] - problem.full0[problem.mask]) / problem.scale
    poses, e, _ = inner.evaluate(x)
    jac = inner.jacobian(x)
    n_eff = problem.n_free - gauge.size
    dof = int(problem.observation_counts().sum()) - n_eff
    s2 = float(np.sum(e**2)) / dof if dof > 0 else float("nan")
    bound_cov = gauge_fixed_covariance(problem, jac, gauge)
    cov = s2 * bound_cov
    stderr = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(stderr, stderr)
    svd = scaled_svd(jac @ complement_basis(gauge))
    leg = e[:, :6] * inner.sigma
    res = IdentificationResult(
        geometry=problem.geometry(full),
        start=problem.start,
        method="ml",
        names=problem.names,
        values=full[problem.mask],
        start_values=problem.full0[problem.mask],
        stderr=stderr,
        covariance=cov,
        correlation=corr,
        singular_values=svd.singular_values,
        singular_vectors=svd.vt,
        rank=numerical_rank(svd.singular_values),
        residuals=e,
        leg_rms_before=float("nan"),
        leg_rms_after=rms(leg),
        rms_before=rms0,
        rms_after=rms(e),
        cost=0.5 * float(np.sum(e**2)),
        nfev=int(sol.nfev),
        njev=int(sol.njev or 0),
        status=int(sol.status),
        message=str(sol.message),
        n_poses=len(problem),
        ids=problem.ids,
        dof=dof,
        bound=np.sqrt(np.clip(np.diag(bound_cov), 0, None)),
        model=problem.model.name,
    )
    return res, poses


def identify_instrument(
    start: Geometry,
    data: Any,
    setup: Setup,
    noise: NoiseModel | None = None,
    fit: str | Sequence[str] | None = None,
    fix: Iterable[str] = (),
    xtol: float = 1e-10,
    max_nfev: int | None = 200,
    model: MeasurementModel | None = None,
) -> InstrumentResult:
    """Maximum-likelihood identification of the machine and the instrument setup.

    Parameters
    ----------
    start : Geometry
        The nominal machine (start values; the gauge convention's reference).
    data : TargetMeasurements or Measurements
        Target positions or tool poses in the instrument frame, and leg readings.
    setup : Setup
        Nominal setup; ``instrument_frame: auto`` is registered first.
    noise : NoiseModel, optional
        Default the seed paper's (target coordinates: its ``position`` noise).
    fit, fix
        Parameter groups and names (``frame``, ``targets``, ``tool`` as well as the machine's).
    xtol, max_nfev
        Solver tolerance and evaluation limit.
    model : MeasurementModel, optional
        Replaces the setup's default model (e.g. ``ToolModel(setup, orientation="euler")``).

    Returns
    -------
    InstrumentResult
    """
    noise = NoiseModel() if noise is None else noise
    setup = setup.in_euler(start.euler)
    registration = None
    if setup.auto:
        registration = register_frame(start, setup, data)
        setup = setup.with_vector(np.concatenate([registration.frame, setup.vector()[6:]]))
    model = instrument_model(setup) if model is None else model
    params = instrument_parameters(start, setup, fit, fix)
    problem = Problem(start, data, model, parameters=params)
    problem.check_size()
    inner = PoseProjection(problem, noise)
    gauge = gauge_freedoms(problem, problem.full0)
    basis = complement_basis(gauge)
    jac0 = inner.jacobian(np.zeros(problem.n_free))
    weak = unidentifiable(problem, jac0, gauge)
    if weak:
        raise IdentificationError(
            f"the poses cannot identify all parameters beyond the {gauge.size} gauge freedoms "
            f"({len(weak)} more combinations; weakest: {weak[-1]}): fix some or measure more"
        )
    rms0 = rms(inner.residuals(np.zeros(problem.n_free)))

    def fun(z: NDArray[np.float64]) -> NDArray[np.float64]:
        return inner.residuals(basis @ z)

    def jac(z: NDArray[np.float64]) -> NDArray[np.float64]:
        return inner.jacobian(basis @ z) @ basis

    sol = solve_least_squares(
        fun, jac, np.zeros(basis.shape[1]), xtol=xtol, ftol=1e-12, gtol=1e-12, max_nfev=max_nfev
    )
    full = apply_convention(problem, problem.unpack(basis @ sol.x), gauge)
    result, poses = _result(problem, inner, full, gauge, sol, rms0)
    values = problem.setup(full)
    names = setup.names()
    cov_index = {n: k for k, n in enumerate(problem.names)}
    calibration = {
        "method": "ml",
        "poses": len(problem),
        "stderr": {n: float(result.stderr[cov_index[n]]) for n in names if n in cov_index},
        "gauge": CONVENTION if gauge.size else "none",
    }
    if registration is not None:
        calibration["registration_rms_mm"] = registration.rms
    calibrated = setup.with_vector(values, calibration)
    return InstrumentResult(
        result.replace(noise=noise), calibrated, registration, gauge.labels, CONVENTION, [], poses
    )
