"""Re-registration of an instrument's quantities on a session, the machine held: what
:func:`hexcal.calibration.validate` fits on each fold before it predicts the others.

Which quantities: those the setup leaves free (a frame given as ``auto`` or not in its
``fixed:``, a tool, targets, a ball bar's pivot, ball and length), or the ones a caller names
(the ISO reports re-register a setup's frame-bound quantities whatever its ``fixed:`` says:
:mod:`hexcal.calibration.iso_validation`).

What the session cannot determine is held at the setup's value, never left to wander where
an iteration stops: a ball bar run on one level circle sees only the pivot minus the ball (the
platform never turns), so its pivot and ball cannot both be fitted, and a pivot in the
circle's plane barely sees its height. A quantity is held when the data leave a combination of
the re-registered ones undetermined (the numerical rank of :mod:`hexcal.core.linalg`) or when
its predicted σ exceeds what the verdict calls not determined (:data:`FAIL_FACTOR` times its
limit in :data:`~hexcal.calibration.verdict.SIGMA_LIMITS`), one at a time, the worst first.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.calibration.verdict import FAIL_FACTOR, parameter_limits
from hexcal.core.geometry import Geometry
from hexcal.core.linalg import gram_pinv_diagonal, numerical_rank, scaled_svd
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import ParameterSet
from hexcal.errors import UsageError
from hexcal.estimation.problem import Problem
from hexcal.estimation.sessions import problem_parameters
from hexcal.estimation.uncertainty import projected_jacobian
from hexcal.instruments.base import MeasurementModel, Session


def quantity_mask(instrument: MeasurementModel, names: Iterable[str] | None = None) -> NDArray[np.bool_]:
    """Which of the instrument's quantities to re-register: those named (names or groups such
    as ``pivot``, ``frame``), or by default those its setup leaves free."""
    own = instrument.parameters()
    if names is None:
        return np.array(own.vary, dtype=bool)
    wanted = set(names)
    unknown = wanted - set(own.names) - set(own.groups)
    if unknown:
        raise UsageError(
            f"unknown instrument quantity {sorted(unknown)[0]!r}; choose from {', '.join(own.names)}"
        )
    grouped = {n for g in wanted & set(own.groups) for n in own.groups[g]}
    return np.array([n in wanted or n in grouped for n in own.names], dtype=bool)


def registration_parameters(geometry: Geometry, session: Session, vary: NDArray[np.bool_]) -> ParameterSet:
    """The parameters of a registration: the machine held, the instrument's quantities varied
    by ``vary`` (whatever its setup fixes)."""
    params = problem_parameters(geometry, [session])
    flags = np.zeros(len(params), dtype=bool)
    flags[params.span("setup.0")] = vary
    return params.with_vary(flags)


def undetermined_quantities(
    geometry: Geometry, session: Session, vary: NDArray[np.bool_], noise: NoiseModel | None = None
) -> NDArray[np.bool_]:
    """Which of the varied quantities (``vary``) the session cannot determine (module
    docstring), under ``noise`` (default :class:`~hexcal.core.noise.NoiseModel`'s, which errs
    towards holding)."""
    from scipy.linalg import qr

    keep = np.array(vary, dtype=bool)
    if not keep.any():
        return np.zeros_like(keep)
    problem = Problem(geometry, [session], parameters=registration_parameters(geometry, session, keep))
    jac = projected_jacobian(problem, NoiseModel() if noise is None else noise)
    limits = FAIL_FACTOR * parameter_limits(problem.names) / problem.scale  # solver units
    alive = np.ones(problem.n_free, dtype=bool)
    while alive.any():
        svd = scaled_svd(jac[:, alive])
        if numerical_rank(svd.singular_values) < alive.sum():
            worst = int(qr(jac[:, alive] / svd.norms, pivoting=True, mode="r")[1][-1])
        else:
            ratio = np.sqrt(gram_pinv_diagonal(svd)) / limits[alive]
            if ratio.max() <= 1.0:
                break
            worst = int(np.argmax(ratio))
        alive[np.flatnonzero(alive)[worst]] = False
    held = np.zeros_like(keep)
    held[np.flatnonzero(keep)[~alive]] = True
    return held


def reregister(
    geometry: Geometry, session: Session, vary: NDArray[np.bool_], noise: NoiseModel | None
) -> Any:
    """The instrument's quantities ``vary`` fitted to ``session`` with the machine held
    (maximum likelihood; the noise learned from the session when ``noise`` is None): an
    :class:`~hexcal.estimation.result.IdentificationResult`."""
    from hexcal.calibration.identify import estimate

    return estimate(
        geometry, session, "ml", parameters=registration_parameters(geometry, session, vary),
        noise="auto" if noise is None else noise, with_bound=False, diagnose=False, verdict=False,
    )  # fmt: skip
