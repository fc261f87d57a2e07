"""Estimators by name: one signature, one result type; a new estimator is one registration.

Every estimator is a function ``fit(problem, noise, **options) -> IdentificationResult``
(:class:`hexcal.estimation.problem.Problem`,
:class:`hexcal.estimation.result.IdentificationResult`). The registry holds, for each
name, the label that reports print, the unit of its residuals, whether it uses the noise
model, whether it needs a measurement that determines the pose, and where the function
lives (imported on first use, so that listing the estimators costs nothing: the command
line builds its ``--method`` choices from here).

This module imports only :mod:`hexcal.errors` at load time.

>>> list(ESTIMATORS)
['ml', 'gls', 'length', 'paper']
>>> ESTIMATORS["paper"].label
"least squares on squared leg lengths (the seed paper's eq. 3)"
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

from hexcal.errors import IdentificationError, UsageError


@dataclass(frozen=True)
class Estimator:
    """A registered estimator.

    Attributes
    ----------
    name : str
    label : str
        What reports call it.
    residual_unit : str
        Unit of its residuals (``"whitened, 1"`` for noise-weighted ones).
    function : str
        ``"module:function"`` of its ``fit(problem, noise, **options)``.
    uses_noise : bool
        Whether the estimate depends on the noise model.
    needs_pose : bool
        Whether it needs a measurement model whose observation determines the pose.
    """

    name: str
    label: str
    residual_unit: str
    function: str
    uses_noise: bool = False
    needs_pose: bool = False

    def fit(self, problem: Any, noise: Any = None, **options: Any) -> Any:
        """Run the estimator on a :class:`~hexcal.estimation.problem.Problem`."""
        if self.needs_pose and not problem.determines_pose:
            part = next(p for p in problem.parts if not p.instrument.determines_pose)
            raise IdentificationError(
                f"the {self.name} estimator needs the platform pose measured at every observation; "
                f"{part.label}: the {part.instrument.describe()} does not give it (a free frame or "
                "tool, targets, a ballbar): use ml"
            )
        module, _, function = self.function.partition(":")
        return getattr(importlib.import_module(module), function)(problem, noise, **options)


#: The registered estimators; the first is the default.
ESTIMATORS: dict[str, Estimator] = {}

#: Name of the default estimator (``hexcal identify`` without ``--method``).
DEFAULT_ESTIMATOR = "ml"


def register(estimator: Estimator) -> Estimator:
    """Add an estimator to :data:`ESTIMATORS` (replacing one of the same name)."""
    ESTIMATORS[estimator.name] = estimator
    return estimator


def get_estimator(name: str) -> Estimator:
    """The estimator registered as ``name``, or :class:`UsageError` listing the choices."""
    try:
        return ESTIMATORS[name]
    except KeyError:
        raise UsageError(f"unknown method {name!r}; choose from {', '.join(ESTIMATORS)}") from None


for _estimator in (
    Estimator(
        "ml",
        "maximum likelihood (errors in variables)",
        "whitened, 1",
        "hexcal.estimation.likelihood:fit_ml",
        uses_noise=True,
    ),
    Estimator(
        "gls",
        "generalised least squares (propagated pose covariance)",
        "whitened, 1",
        "hexcal.estimation.gls:fit_gls",
        uses_noise=True,
        needs_pose=True,
    ),
    Estimator(
        "length",
        "least squares on leg lengths",
        "mm",
        "hexcal.estimation.least_squares:fit_length",
        needs_pose=True,
    ),
    Estimator(
        "paper",
        "least squares on squared leg lengths (the seed paper's eq. 3)",
        "mm²",
        "hexcal.estimation.least_squares:fit_paper",
        needs_pose=True,
    ),
):
    register(_estimator)
