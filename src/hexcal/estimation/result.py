"""The one result type of every estimator, :class:`IdentificationResult`, for one identification
and for a batch of them.

One identification has scalar ``status``, ``iterations`` and ``cost`` and ``values`` of shape
``(n,)`` with its statistics (standard errors, covariance, singular values, residuals); a batch of
``T`` identifications (a Monte Carlo study's, :func:`hexcal.estimation.batched.estimate_stack`) has
them over a leading trial axis, and its statistics are None. ``result[k]`` is trial ``k``.

What the calibration workflow attaches to a fit (the noise's source, the bound, the outlier check,
the verdict, registrations: :func:`hexcal.calibration.estimate`) is not the estimator's: it is kept
apart in :attr:`IdentificationResult.workflow` and read through properties of the same names,
together with the report and file methods, until the workflow has a result of its own.

Imports :mod:`hexcal.core`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.noise import NoiseModel
from hexcal.errors import UsageError

#: Status of a converged fit (:data:`hexcal.estimation.levenberg.STATUS_CONVERGED`).
CONVERGED = 1

#: What the calibration workflow attaches (``workflow``), and the default of each.
WORKFLOW_FIELDS: dict[str, Any] = {
    "bound": None,
    "outliers": (),
    "flagged": (),
    "verdict": None,
    "noise_source": "given",
    "noise_estimate": None,
    "noise_check": None,
    "registrations": (),
}


@dataclass(frozen=True, eq=False)
class IdentificationResult:
    """Outcome of an identification, or of a batch of them (after lmfit's ``MinimizerResult``).

    Attributes
    ----------
    method : str
        Registry name of the estimator.
    names : tuple of str
        Names of the varied parameters.
    values, start_values : ndarray, shape (..., n)
        Identified and start values of the varied parameters (NaN rows: failed trials).
    status : int or ndarray of int
        :data:`hexcal.estimation.levenberg.STATUS_CONVERGED` (1), or a failure (<= 0,
        :data:`hexcal.estimation.levenberg.STATUS_MESSAGES`).
    iterations : int or ndarray of int
        Levenberg–Marquardt iterations (the slowest leg's for ``paper``/``length``).
    cost : float or ndarray
        ``0.5 * sum(residuals**2)`` at the solution (the method's residuals; NaN if failed).
    rank : int or ndarray of int
        Numerical rank of the Jacobian (beyond the gauges).
    start : Geometry
        The geometry the identification started from (usually the nominal one).
    full : ndarray, shape (..., N), optional
        Every parameter's value (the varied ones identified, the others as started).
    geometry : Geometry, optional
        The identified geometry (one identification).
    stderr : ndarray, shape (n,), optional
        Standard errors of the varied parameters.
    covariance, correlation : ndarray, shape (n, n), optional
    singular_values : ndarray, shape (n,), optional
        Singular values of the column-normalised Jacobian at the solution, descending.
    singular_vectors : ndarray, shape (n, n), optional
        Row ``k`` is the (normalised-parameter) combination of ``singular_values[k]``.
    residuals : ndarray, shape (m, k), optional
        Residuals at the solution (units of the method; whitened for ``ml`` and ``gls``).
    leg_rms_before, leg_rms_after : float
        RMS of the leg length residual ``|v| - (l0 + g dl)`` at the start and at the
        solution, mm (comparable across methods).
    rms_before, rms_after : float
        RMS of the method's own residual.
    nfev : int
        Function evaluations.
    n_poses : int
    ids : tuple of str
        Ids of the poses used.
    dof : int
        Degrees of freedom: independent residuals less the varied parameters.
    model : str
        Name of the measurement model.
    sessions : tuple of str
        The sessions' labels (one for a single data set).
    session_sizes : tuple of int
        Observations of each session.
    instruments : tuple of MeasurementModel
        Each session's instrument with its identified values (a calibrated setup).
    gauges : tuple of str
        The gauge freedoms removed (``base translation x`` ...), empty when none.
    convention : str
        The gauge convention the values are reported under ("" without gauges).
    poses : ndarray, shape (m, 6), optional
        The estimated true poses (maximum likelihood).
    noises : tuple of NoiseModel
        The noise model of each session.
    gauge_directions : ndarray, shape (n, g), optional
        The gauge freedoms as directions of the varied parameters (parameter units).
    leg_residuals_before, leg_residuals_after : ndarray, shape (m, 6), optional
        Leg residuals (mm) of every observation at the start and at the solution: at the
        measured poses where the instruments give them, else at the estimated true poses.
    workflow : dict
        What the calibration workflow attached (:data:`WORKFLOW_FIELDS`: ``bound``, the
        Cramér–Rao σ of each parameter; ``outliers`` left out and ``flagged`` observations;
        the ``verdict``; the noise's ``noise_source``, ``noise_estimate`` or ``noise_check``;
        each session's ``registrations``), read through properties of the same names.
    """

    method: str
    names: tuple[str, ...]
    values: NDArray[np.float64]
    status: Any
    iterations: Any
    cost: Any
    rank: Any
    start: Geometry | None = None
    start_values: NDArray[np.float64] | None = None
    full: NDArray[np.float64] | None = None
    geometry: Geometry | None = None
    stderr: NDArray[np.float64] | None = None
    covariance: NDArray[np.float64] | None = None
    correlation: NDArray[np.float64] | None = None
    singular_values: NDArray[np.float64] | None = None
    singular_vectors: NDArray[np.float64] | None = None
    residuals: NDArray[np.float64] | None = None
    leg_rms_before: float = float("nan")
    leg_rms_after: float = float("nan")
    rms_before: float = float("nan")
    rms_after: float = float("nan")
    nfev: Any = 0
    n_poses: int = 0
    ids: tuple[str, ...] = field(default=())
    dof: int = 0
    model: str = "pose"
    sessions: tuple[str, ...] = ()
    session_sizes: tuple[int, ...] = ()
    instruments: tuple[Any, ...] = ()
    gauges: tuple[str, ...] = ()
    convention: str = ""
    poses: NDArray[np.float64] | None = None
    noises: tuple[NoiseModel, ...] = ()
    leg_residuals_before: NDArray[np.float64] | None = None
    leg_residuals_after: NDArray[np.float64] | None = None
    gauge_directions: NDArray[np.float64] | None = None
    workflow: dict[str, Any] = field(default_factory=dict)

    # -- one identification or a batch ---------------------------------------------------
    @property
    def batched(self) -> bool:
        """Whether this is a batch of identifications (a leading trial axis)."""
        return np.ndim(self.values) > 1

    @property
    def trials(self) -> int:
        """Identifications held (1 for one identification)."""
        return int(np.shape(self.values)[0]) if self.batched else 1

    def __getitem__(self, trial: int) -> IdentificationResult:
        """Trial ``trial`` of a batch, as one identification."""
        if not self.batched:
            raise UsageError("one identification has no trials to index")
        return IdentificationResult(
            self.method,
            self.names,
            self.values[trial],
            int(self.status[trial]),
            int(self.iterations[trial]),
            float(self.cost[trial]),
            int(self.rank[trial]),
            self.start,
            None if self.start_values is None else self.start_values[trial],
            None if self.full is None else self.full[trial],
            model=self.model,
            sessions=self.sessions,
            noises=self.noises,
        )

    @property
    def converged(self) -> Any:
        """Whether each identification converged (its values are the identified ones)."""
        return np.asarray(self.status) == CONVERGED if self.batched else self.status == CONVERGED

    @property
    def message(self) -> Any:
        """What the solver says of each identification (one string, or one per trial)."""
        from hexcal.estimation.levenberg import STATUS_MESSAGES

        if self.batched:
            return tuple(STATUS_MESSAGES[int(s)] for s in self.status)
        return STATUS_MESSAGES.get(int(self.status), str(self.status))

    @property
    def njev(self) -> Any:
        """Jacobian evaluations: the iterations."""
        return self.iterations

    @property
    def noise(self) -> NoiseModel | None:
        """The first session's noise model (None when none was used)."""
        return self.noises[0] if self.noises else None

    @property
    def reduced_chi2(self) -> float:
        """Residual variance per degree of freedom (about 1 for whitened residuals under a
        correct noise model)."""
        if self.residuals is None:
            return float("nan")
        return float(np.sum(self.residuals**2) / self.dof) if self.dof > 0 else float("nan")

    @property
    def parameters(self) -> dict[str, float]:
        """Identified values by name."""
        return dict(zip(self.names, np.asarray(self.values).tolist(), strict=True))

    @property
    def standard_errors(self) -> dict[str, float]:
        """Standard errors by name."""
        stderr = np.full(len(self.names), np.nan) if self.stderr is None else self.stderr
        return dict(zip(self.names, stderr.tolist(), strict=True))

    def replace(self, **changes: Any) -> IdentificationResult:
        """Copy with some fields (or workflow attachments, :data:`WORKFLOW_FIELDS`) changed."""
        noise = changes.pop("noise", None)
        if noise is not None and "noises" not in changes:
            changes["noises"] = (noise,) * max(len(self.sessions), 1)
        attached = {k: changes.pop(k) for k in list(changes) if k in WORKFLOW_FIELDS}
        if attached:
            changes["workflow"] = {**self.workflow, **attached}
        return dataclasses.replace(self, **changes)

    # -- what the calibration workflow attached (until it has a result of its own) -----------
    def _attached(self, name: str) -> Any:
        return self.workflow.get(name, WORKFLOW_FIELDS[name])

    @property
    def bound(self) -> NDArray[np.float64] | None:
        """Cramér–Rao σ of each parameter under ``noise`` (attached by the workflow)."""
        return self._attached("bound")

    @property
    def outliers(self) -> tuple[str, ...]:
        """Ids of the poses left out as outliers (robust fitting)."""
        return self._attached("outliers")

    @property
    def flagged(self) -> tuple[str, ...]:
        """Ids of poses whose residuals are implausible under the noise model."""
        return self._attached("flagged")

    @property
    def verdict(self) -> Any:
        """``pass`` | ``warn`` | ``fail`` with its reasons (:mod:`hexcal.calibration.verdict`)."""
        return self._attached("verdict")

    @property
    def noise_source(self) -> str:
        """``"estimated"`` (learned from the data) or ``"given"``."""
        return self._attached("noise_source")

    @property
    def noise_estimate(self) -> Any:
        """The variance components (σ, standard errors, redundancies) when estimated."""
        return self._attached("noise_estimate")

    @property
    def noise_check(self) -> Any:
        """The given noise tested against the data, per group."""
        return self._attached("noise_check")

    @property
    def registrations(self) -> tuple[Any, ...]:
        """How each session's unknown frame was registered (None where it was not)."""
        return self._attached("registrations")

    # -- reports and files (the workflow's, until it has a result of its own) ---------------
    def calibrated_instruments(self) -> tuple[Any, ...]:
        """Each session's instrument at its identified values, with the ``calibration`` mapping
        of a calibrated setup: method, observations, standard errors by name, the gauge
        convention and the registration residual."""
        out = []
        for k, (inst, info) in enumerate(zip(self.instruments, self.session_dicts(), strict=True)):
            calibration: dict[str, Any] = {
                "method": self.method,
                "poses": info["observations"],
                "stderr": {n: v["stderr"] for n, v in info["setup"].items() if v["stderr"] is not None},
                "gauge": self.convention or "none",
            }
            reg = self.registrations[k] if k < len(self.registrations) else None
            if reg is not None:
                calibration["registration_rms_mm"] = reg.rms
            out.append(inst.with_values(inst.parameters().values, calibration))
        return tuple(out)

    @property
    def verdict_status(self) -> str:
        """``pass``, ``warn`` or ``fail`` (``pass`` when no verdict was made)."""
        return "pass" if self.verdict is None else self.verdict.status

    @property
    def failed(self) -> bool:
        """The verdict is ``fail``: write no calibrated geometry (unless forced)."""
        return self.verdict is not None and self.verdict.failed

    def calibration_metadata(self) -> dict[str, Any]:
        """The ``calibration:`` mapping written into a calibrated geometry file."""
        out: dict[str, Any] = {
            "method": self.method,
            "poses": self.n_poses,
            "leg_rms_before_mm": self.leg_rms_before,
            "leg_rms_after_mm": self.leg_rms_after,
            "iterations": self.njev,
            "status": self.status,
            "rank": self.rank,
            "stderr": self.standard_errors,
        }
        if self.bound is not None:
            out["bound"] = dict(zip(self.names, self.bound.tolist(), strict=True))
        if self.noise is not None:
            out["noise"] = self.noise.describe()
            out["noise_source"] = self.noise_source
        if self.verdict is not None:
            out["verdict"] = self.verdict_status
        uncertainty = self.machine_uncertainty()
        if uncertainty is not None:
            out["uncertainty"] = uncertainty
        return out

    def machine_uncertainty(self) -> dict[str, Any] | None:
        """What a later ``validate`` needs to state what it should measure: the identified
        machine parameters' ``names``, their ``covariance`` (rows as lists), the ``gauge``
        directions among them (rows, one column per gauge freedom; empty without gauges) and
        the first session's noise standard deviations ``noise`` (mm, mm, rad). None when the
        covariance is not finite (a rank-deficient fit)."""
        machine = set(self.start.machine_names())
        rows = np.array([n in machine for n in self.names], dtype=bool)
        if not rows.any():
            return None
        cov = self.covariance[np.ix_(rows, rows)]
        if not np.all(np.isfinite(cov)):
            return None
        gauge = (
            np.zeros((int(rows.sum()), 0)) if self.gauge_directions is None else self.gauge_directions[rows]
        )
        out: dict[str, Any] = {
            "names": [n for n, r in zip(self.names, rows, strict=True) if r],
            "covariance": cov.tolist(),
            "gauge": gauge.tolist(),
        }
        if self.noise is not None:
            leg, pos, ang = self.noise.sigmas
            out["noise"] = {"leg": leg, "position": pos, "orientation": ang}
        return out

    def noise_dict(self) -> dict[str, Any] | None:
        """The noise model used as standard deviations (mm, mm, rad) and its source: the first
        session's at the top, every group of every session under ``groups``."""
        if self.noise is None:
            return None
        leg, pos, ang = self.noise.sigmas
        out: dict[str, Any] = {
            "leg": leg,
            "position": pos,
            "orientation": ang,
            "source": self.noise_source,
            "distribution": self.noise.distribution,
            "sigmas": {"leg": leg, "position": pos, "orientation": ang},
        }
        est = self.noise_estimate
        if est is not None:
            first = [k for k, (s, _) in enumerate(est.keys) if s == 0]
            out["stderr"] = {est.keys[k][1]: float(est.stderr[k]) for k in first}
            out["groups"] = [
                {
                    "session": self.sessions[s] if s < len(self.sessions) else s,
                    "group": name,
                    "label": est.groups[k],
                    "sigma": float(est.sigmas[k]),
                    "stderr": float(est.stderr[k]),
                    "unit": est.units()[k],
                    "estimated": bool(est.estimated[k]),
                }
                for k, (s, name) in enumerate(est.keys)
            ]
        else:
            out["given"] = self.noise.to_dict()
        return out

    def session_dicts(self) -> list[dict[str, Any]]:
        """Each session: its label, instrument, observations, calibrated instrument quantities
        (value and standard error by name), what its setup fixes, the registration of an unknown
        frame and its noise (standard deviations)."""
        out = []
        stderr = self.standard_errors
        many = len(self.instruments) > 1
        for k, inst in enumerate(self.instruments):
            params = inst.parameters()
            prefix = f"session{k + 1}." if many else ""
            setup = {
                n: {"value": float(v), "stderr": stderr.get(prefix + n)}
                for n, v in zip(params.names, params.values, strict=True)
            }
            reg = self.registrations[k] if k < len(self.registrations) else None
            noise = self.noises[k] if k < len(self.noises) else self.noise
            out.append(
                {
                    "label": self.sessions[k] if k < len(self.sessions) else f"session {k + 1}",
                    "instrument": inst.name,
                    "description": inst.describe(),
                    "observations": self.session_sizes[k] if k < len(self.session_sizes) else self.n_poses,
                    "setup": setup,
                    "varied": [n for n in params.names if prefix + n in stderr],
                    "registration": None if reg is None else reg.to_dict(),
                    "noise": None
                    if noise is None
                    else dict(zip(("leg", "position", "orientation"), noise.sigmas, strict=True)),
                }
            )
        return out

    def to_dict(self) -> dict[str, Any]:
        """Everything a report needs, JSON-ready (the ``--json`` file of ``hexcal identify``).

        Lengths in mm, angles in rad; ``correlation`` row-major over ``names``.

        - ``verdict``: ``"pass"`` | ``"warn"`` | ``"fail"``; ``reasons``: list of
          ``{"code", "severity" (info|warn|fail), "message"[, "data"]}``; ``accuracy``: the
          predicted pose error after calibration over the workspace
          (``position_rms_mm``, ``position_max_mm``, ``orientation_rms_rad``,
          ``orientation_max_rad``);
        - ``noise``: the noise model used, as **standard deviations**: ``{"leg": mm,
          "position": mm, "orientation": rad, "source": "estimated" | "given", ...}``, plus
          ``stderr`` (same units) when estimated and ``given`` (the model as given, its
          uniform half-widths or σ) when given; ``noise_check``: per group the σ ratio
          (data / given), redundancy and p-value;
        - ``bound``: name -> Cramér–Rao σ (mm, gains dimensionless); ``stderr`` likewise;
        - ``reduced_chi_square``: sum of squared whitened residuals over ``dof``
          (mm² over ``dof`` for ``length``; mm⁴ for ``paper``).
        """
        verdict = None if self.verdict is None else self.verdict.to_dict()
        return {
            "verdict": self.verdict_status if verdict is not None else None,
            "reasons": [] if verdict is None else verdict["reasons"],
            "accuracy": None if verdict is None else verdict["accuracy"],
            "noise_check": None if self.noise_check is None else self.noise_check.to_dict(),
            "noise_estimate": None if self.noise_estimate is None else self.noise_estimate.to_dict(),
            "method": self.method,
            "model": self.model,
            "poses": self.n_poses,
            "parameters": self.parameters,
            "start": dict(zip(self.names, self.start_values.tolist(), strict=True)),
            "stderr": self.standard_errors,
            "bound": None if self.bound is None else dict(zip(self.names, self.bound.tolist(), strict=True)),
            "noise": self.noise_dict(),
            "rank": self.rank,
            "n_parameters": len(self.names),
            "dof": self.dof,
            "reduced_chi_square": self.reduced_chi2,
            "singular_values": self.singular_values.tolist(),
            "singular_vectors": self.singular_vectors.tolist(),
            "names": list(self.names),
            "correlation": self.correlation.tolist(),
            "leg_rms_before": self.leg_rms_before,
            "leg_rms_after": self.leg_rms_after,
            "rms_before": self.rms_before,
            "rms_after": self.rms_after,
            "cost": self.cost,
            "iterations": self.njev,
            "function_evaluations": self.nfev,
            "status": self.status,
            "message": self.message,
            "outliers": list(self.outliers),
            "flagged": list(self.flagged),
            "ids": list(self.ids),
            "pose_rms_before": _pose_rms(self.leg_residuals_before),
            "pose_rms_after": _pose_rms(self.leg_residuals_after),
            "sessions": self.session_dicts(),
            "gauges": list(self.gauges),
            "convention": self.convention,
        }


def _pose_rms(residuals: NDArray[np.float64] | None) -> list[float] | None:
    """RMS of each observation's six leg residuals (mm), or None."""
    return None if residuals is None else np.sqrt(np.mean(residuals**2, axis=1)).tolist()


def rms(x: NDArray[np.float64]) -> float:
    """Root mean square of all entries."""
    return float(np.sqrt(np.mean(np.square(x))))
