"""The one result type of every estimator, :class:`IdentificationResult`, and how it is built.

Imports :mod:`hexcal.core`, :mod:`hexcal.instruments` and :mod:`hexcal.estimation.problem`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.noise import NoiseModel


@dataclass(frozen=True, eq=False)
class IdentificationResult:
    """Outcome of an identification (after lmfit's ``MinimizerResult``).

    Attributes
    ----------
    geometry : Geometry
        The identified geometry (the start geometry with the varied parameters replaced).
    start : Geometry
        The geometry the identification started from (usually the nominal one).
    method : str
        Registry name of the estimator.
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
    residuals : ndarray, shape (m, k)
        Residuals at the solution (units of the method; whitened for ``ml`` and ``gls``).
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
    dof : int
        Degrees of freedom: independent residuals less the varied parameters.
    bound : ndarray, shape (n,), optional
        Cramér–Rao σ of each parameter under ``noise``.
    noise : NoiseModel, optional
        The noise model used by the estimator or the bound.
    outliers : tuple of str
        Ids of the poses left out as outliers (robust fitting).
    flagged : tuple of str
        Ids of poses whose residuals are implausible under the noise model.
    model : str
        Name of the measurement model.
    verdict : Verdict, optional
        ``pass`` | ``warn`` | ``fail`` with its reasons (:mod:`hexcal.calibration.verdict`).
    noise_source : str
        ``"estimated"`` (learned from the data, :mod:`hexcal.estimation.noise_estimation`)
        or ``"given"``.
    noise_estimate : NoiseEstimate, optional
        The variance components (σ, standard errors, redundancies) when estimated.
    noise_check : NoiseCheck, optional
        The given noise tested against the data, per group.
    sessions : tuple of str
        The sessions' labels (one for a single data set).
    session_sizes : tuple of int
        Observations of each session.
    instruments : tuple of MeasurementModel
        Each session's instrument with its identified values (a calibrated setup).
    registrations : tuple
        How each session's unknown frame was registered (None where it was not).
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
    dof: int = 0
    bound: NDArray[np.float64] | None = None
    noise: NoiseModel | None = None
    outliers: tuple[str, ...] = ()
    flagged: tuple[str, ...] = ()
    model: str = "pose"
    verdict: Any = None
    noise_source: str = "given"
    noise_estimate: Any = None
    noise_check: Any = None
    sessions: tuple[str, ...] = ()
    session_sizes: tuple[int, ...] = ()
    instruments: tuple[Any, ...] = ()
    registrations: tuple[Any, ...] = ()
    gauges: tuple[str, ...] = ()
    convention: str = ""
    poses: NDArray[np.float64] | None = None
    noises: tuple[NoiseModel, ...] = ()
    leg_residuals_before: NDArray[np.float64] | None = None
    leg_residuals_after: NDArray[np.float64] | None = None
    gauge_directions: NDArray[np.float64] | None = None

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

    @property
    def reduced_chi2(self) -> float:
        """Residual variance per degree of freedom (about 1 for whitened residuals under a
        correct noise model)."""
        return float(np.sum(self.residuals**2) / self.dof) if self.dof > 0 else float("nan")

    @property
    def parameters(self) -> dict[str, float]:
        """Identified values by name."""
        return dict(zip(self.names, self.values.tolist(), strict=True))

    @property
    def standard_errors(self) -> dict[str, float]:
        """Standard errors by name."""
        return dict(zip(self.names, self.stderr.tolist(), strict=True))

    def replace(self, **changes: Any) -> IdentificationResult:
        """Copy with some fields changed."""
        return dataclasses.replace(self, **changes)

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
