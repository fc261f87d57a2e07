"""An identification problem, and the one place that maps solver variables to residuals.

A :class:`Problem` binds the start geometry, a measurement model, its data and the
parameter set (which parameters vary, and their scales). Every estimator, the robust
fitting and the bounds build their residual and Jacobian functions here:

- :meth:`Problem.least_squares_functions`: the leg residuals at the measured poses
  (``length`` or the seed paper's ``paper`` variant), optionally whitened per observation,
  for models whose observation determines the pose;
- :meth:`Problem.observation_equations`: the errors-in-variables equations of every
  observation at given true poses: whitened leg and instrument residuals, their Jacobian
  with respect to the varied parameters and to the pose.

The solver varies ``x = (θ - θ_start) / scale`` over the varied parameters
(:meth:`hexcal.core.parameters.ParameterSet.unpacker`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import pose_jacobian_from_arrays
from hexcal.core.linalg import null_space, numerical_rank, scaled_svd
from hexcal.core.parameters import (
    MIN_POSES,
    N_ALL_PARAMETERS,
    PARAMETER_GROUPS,
    PARAMETER_NAMES,
    PARAMETER_SCALE,
    ParameterSet,
    select_parameters,
)
from hexcal.errors import IdentificationError, UsageError
from hexcal.instruments.base import MeasurementModel
from hexcal.instruments.legs import check_variant, leg_parameter_jacobian, leg_residuals, pose_frames
from hexcal.instruments.pose import FullPoseModel, Measurements

Functions = tuple[
    Callable[[NDArray[np.float64]], NDArray[np.float64]], Callable[[NDArray[np.float64]], NDArray]
]


class Problem:
    """Start geometry, measurement model, data and parameters of one identification.

    Parameters
    ----------
    start : Geometry
        Start values of the machine parameters (the nominal geometry).
    data
        Observations in the form the model reads (for the default full-pose model,
        :class:`hexcal.instruments.pose.Measurements`).
    model : MeasurementModel, optional
        Default :class:`hexcal.instruments.pose.FullPoseModel`.
    mask : array_like of bool, optional
        Varied parameters: 48 flags of the machine, or one per parameter of the set.
        Default the machine's joints and ``l0`` and all the model's parameters.
    parameters : ParameterSet, optional
        The whole parameter set (machine first, then the model's), replacing ``mask``.
    """

    def __init__(
        self,
        start: Geometry,
        data: Any,
        model: MeasurementModel | None = None,
        mask: ArrayLike | None = None,
        parameters: ParameterSet | None = None,
    ) -> None:
        self.start, self.data = start, data
        self.model = FullPoseModel() if model is None else model
        if parameters is None:
            parameters = _parameter_set(start, self.model, mask)
        self.parameters = parameters
        self.mask = np.array(parameters.vary)
        self.machine_mask = self.mask[:N_ALL_PARAMETERS]
        self.scale = np.array(parameters.scales[self.mask])
        self.full0 = np.array(parameters.values)
        self.unpack = parameters.unpacker()
        self.readings = self.model.readings(data)
        self.ids = self.model.ids(data)
        self.euler = start.euler
        self._frames: tuple[NDArray, NDArray] | None = None
        self.observed, self.present = self.model.observed(data)
        self.complete = bool(self.present.all())

    # -- bookkeeping -------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.ids)

    @property
    def n_free(self) -> int:
        return int(self.mask.sum())

    @property
    def names(self) -> tuple[str, ...]:
        """Names of the varied parameters."""
        return self.parameters.free_names

    def geometry(self, full: NDArray[np.float64]) -> Geometry:
        """The start geometry with the machine parameters of ``full``."""
        return self.start.with_vector(full[:N_ALL_PARAMETERS])

    def setup(self, full: NDArray[np.float64]) -> NDArray[np.float64]:
        """The model's parameter values in ``full``."""
        return full[N_ALL_PARAMETERS:]

    def subset(self, index: ArrayLike) -> Problem:
        """The same problem on the observations at ``index`` (integer or boolean)."""
        idx = np.arange(len(self))[np.asarray(index)]
        return Problem(self.start, self.model.subset(self.data, idx), self.model, parameters=self.parameters)

    def check_size(self) -> None:
        """Refuse data sets too small to determine the varied parameters."""
        m, n = len(self), self.n_free
        if self.model.measures_pose:
            min_poses = MIN_POSES + (1 if self.machine_mask[42:].any() else 0)
            if m < min_poses:
                raise IdentificationError(
                    f"{m} poses cannot determine the parameters: at least {min_poses} are needed "
                    f"(each leg has {min_poses} parameters and gets one equation per pose)"
                )
        equations = 6 * m if self.model.measures_pose else int(self.present.sum())
        if equations < n:
            raise IdentificationError(f"{equations} equations for {n} parameters: measure more poses")

    def check_rank(self, jac_scaled: NDArray[np.float64], where: str = "") -> None:
        """Refuse a rank-deficient (scaled) Jacobian, naming the weakest combination."""
        svd = scaled_svd(jac_scaled)
        rank = numerical_rank(svd.singular_values)
        if rank < self.n_free:
            basis, _ = null_space(jac_scaled)
            combos = "; ".join(self.combination(v) for v in basis[:5])
            more = f" and {len(basis) - 5} more" if len(basis) > 5 else ""
            raise IdentificationError(
                f"the poses cannot identify all parameters{where} (rank-deficient Jacobian: rank "
                f"{rank} of {self.n_free}; weakest combination: {self.combination(svd.vt[-1])}; "
                f"undetermined combinations: {combos}{more})"
            )

    def combination(self, vector: NDArray[np.float64], top: int = 4) -> str:
        """Readable form of a parameter combination (its largest components)."""
        order = np.argsort(-np.abs(vector))[:top]
        return " ".join(f"{vector[k]:+.2f}·{self.names[k]}" for k in order)

    # -- measured poses (models that measure the pose) ---------------------------------
    def measured_frames(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Rotations and positions of the measured poses (cached)."""
        if not self.model.measures_pose:
            raise IdentificationError(
                f"the {self.model.name} measurement does not determine the platform pose by itself: "
                "use the ml estimator"
            )
        if self._frames is None:
            self._poses = self.model.start_poses(self.start, self.setup(self.full0), self.data)
            self._frames = pose_frames(self._poses, self.euler)
        return self._frames

    def measured_poses(self) -> NDArray[np.float64]:
        """The measured poses ``(m, 6)`` (models that measure the pose)."""
        self.measured_frames()
        return self._poses

    def leg_residuals(self, full: NDArray[np.float64], variant: str = "length") -> NDArray[np.float64]:
        """Leg residuals at the measured poses, ``(m, 6)``."""
        rot, pos = self.measured_frames()
        return leg_residuals(full[:N_ALL_PARAMETERS], rot, pos, self.readings, variant)

    def leg_jacobian(
        self, full: NDArray[np.float64], variant: str = "length", scaled: bool = True
    ) -> NDArray[np.float64]:
        """Jacobian of :meth:`leg_residuals`, ``(6 m, n_free)``, in solver units (or parameter
        units when not ``scaled``)."""
        rot, pos = self.measured_frames()
        jac = leg_parameter_jacobian(full[:N_ALL_PARAMETERS], rot, pos, self.readings, variant)
        jac = jac.reshape(-1, N_ALL_PARAMETERS)
        if len(self.mask) > N_ALL_PARAMETERS:  # model parameters do not enter the legs
            jac = np.concatenate([jac, np.zeros((jac.shape[0], len(self.mask) - N_ALL_PARAMETERS))], axis=1)
        return jac[:, self.mask] * self.scale if scaled else jac[:, self.mask]

    def least_squares_functions(self, variant: str = "length", weights: NDArray | None = None) -> Functions:
        """``fun(x)`` and ``jac(x)`` of the leg residuals at the measured poses.

        ``weights`` (m, 6, 6) whiten each pose's six residuals (generalised least squares).
        """
        check_variant(variant)
        m, unpack = len(self), self.unpack

        if weights is None:

            def fun(x: NDArray[np.float64]) -> NDArray[np.float64]:
                return self.leg_residuals(unpack(x), variant).ravel()

            def jac(x: NDArray[np.float64]) -> NDArray[np.float64]:
                return self.leg_jacobian(unpack(x), variant)

            return fun, jac

        def wfun(x: NDArray[np.float64]) -> NDArray[np.float64]:
            return np.einsum("mij,mj->mi", weights, self.leg_residuals(unpack(x), variant)).ravel()

        def wjac(x: NDArray[np.float64]) -> NDArray[np.float64]:
            a = self.leg_jacobian(unpack(x), variant).reshape(m, 6, -1)
            return np.matmul(weights, a).reshape(6 * m, -1)

        return wfun, wjac

    # -- errors in variables -----------------------------------------------------------
    def observation_equations(
        self,
        full: NDArray[np.float64],
        poses: NDArray[np.float64],
        leg_sigma: float,
        instrument_whitener: NDArray[np.float64],
        parameters: bool = True,
    ) -> tuple[NDArray, NDArray, NDArray | None, NDArray]:
        """Whitened errors-in-variables equations of every observation at true ``poses``.

        Returns
        -------
        e : ndarray, shape (m, 6 + k)
            Leg residuals over ``leg_sigma``, then the whitened instrument residuals
            ``W (h(θ, P) - y)`` (zero where a value is missing).
        b : ndarray, shape (m, 6 + k, 6)
            Their Jacobian with respect to the pose.
        a : ndarray, shape (m, 6 + k, n_free) or None
            Their Jacobian with respect to the varied parameters in solver units (when
            ``parameters``).
        lengths : ndarray, shape (m, 6)
            Leg lengths of the poses on the machine of ``full``.
        """
        machine, setup = full[:N_ALL_PARAMETERS], self.setup(full)
        u, s = machine[:18].reshape(6, 3), machine[18:36].reshape(6, 3)
        lengths, jp = pose_jacobian_from_arrays(u, s, poses, self.euler)
        model_lengths = machine[36:42] + machine[42:48] * self.readings
        present, w = self.present, instrument_whitener
        delta = self.model.residual(setup, poses, self.euler, self.observed)
        if not self.complete:
            delta = np.where(present, delta, 0.0)
        e_inst = delta @ w.T
        dh = self.model.whitened_pose_jacobian(setup, poses, self.euler, w)
        if not self.complete:
            e_inst = np.where(present, e_inst, 0.0)
            dh = np.where(present[..., None], dh, 0.0)
        e = np.concatenate([(lengths - model_lengths) / leg_sigma, e_inst], axis=1)
        b = np.concatenate([jp / leg_sigma, dh], axis=1)
        a = None
        if parameters:
            a = self.eiv_parameter_jacobian(full, poses, leg_sigma, w)
        return e, b, a, lengths

    def eiv_parameter_jacobian(
        self,
        full: NDArray[np.float64],
        poses: NDArray[np.float64],
        leg_sigma: float,
        w: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """Jacobian of the observation equations with respect to the varied parameters,
        ``(m, 6 + k, n_free)`` in solver units (see :meth:`observation_equations`)."""
        m, k = len(self), self.model.size
        machine, setup = full[:N_ALL_PARAMETERS], self.setup(full)
        rot, pos = pose_frames(poses, self.euler)
        legs = leg_parameter_jacobian(machine, rot, pos, self.readings, "length")
        a_leg = legs[:, :, self.machine_mask] * (self.scale[: int(self.machine_mask.sum())] / leg_sigma)
        setup_mask = self.mask[N_ALL_PARAMETERS:]
        if not setup_mask.any():
            return np.concatenate([a_leg, np.zeros((m, k, a_leg.shape[-1]))], axis=1)
        dsetup = np.matmul(w, self.model.setup_jacobian(setup, poses, self.euler))
        if not self.complete:
            dsetup = np.where(self.present[..., None], dsetup, 0.0)
        a_inst = dsetup[:, :, setup_mask] * self.scale[int(self.machine_mask.sum()) :]
        a_leg = np.concatenate([a_leg, np.zeros((m, 6, a_inst.shape[-1]))], axis=2)
        a_inst = np.concatenate([np.zeros((m, k, a_leg.shape[-1] - a_inst.shape[-1])), a_inst], axis=2)
        return np.concatenate([a_leg, a_inst], axis=1)

    def observation_counts(self) -> NDArray[np.intp]:
        """Equations per observation after the six pose unknowns: ``6 + present values - 6``."""
        return self.present.sum(axis=1)


def _parameter_set(start: Geometry, model: MeasurementModel, mask: ArrayLike | None) -> ParameterSet:
    """The machine's 48 parameters and the model's, varied by ``mask`` (built once: a fit of
    15 poses takes milliseconds, and this runs for every one of a study's fits)."""
    extra = model.parameters()
    flags = np.asarray(select_parameters() if mask is None else mask, dtype=bool)
    n = N_ALL_PARAMETERS + len(extra)
    if flags.shape == (N_ALL_PARAMETERS,):
        flags = np.concatenate([flags, np.ones(len(extra), dtype=bool)])
    if flags.shape != (n,):
        raise UsageError(f"mask must have shape (48,) or ({n},), got {flags.shape}")
    groups = dict(PARAMETER_GROUPS)
    for key, names in extra.groups.items():
        groups[key] = groups.get(key, ()) + names
    return ParameterSet(
        PARAMETER_NAMES + extra.names,
        np.concatenate([start.to_vector(gains=True), extra.values]),
        flags,
        np.concatenate([PARAMETER_SCALE, extra.scales]),
        groups,
    )


def measurements_problem(
    geometry: Geometry, measurements: Measurements, mask: ArrayLike | None = None
) -> Problem:
    """A full-pose :class:`Problem` (the form most of hexcal's planning code uses)."""
    return Problem(geometry, measurements, FullPoseModel(), mask)


def identification_residuals(
    geometry: Geometry, measurements: Measurements, method: str = "length"
) -> NDArray[np.float64]:
    """Leg residuals of every measured pose for ``geometry``, shape ``(m, 6)``.

    Units: mm for ``"length"``, mm² for ``"paper"``.
    """
    check_variant(method)
    problem = measurements_problem(geometry, measurements)
    return problem.leg_residuals(problem.full0, method)


def identification_jacobian(
    geometry: Geometry,
    measurements: Measurements,
    method: str = "length",
    mask: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Analytic Jacobian of the leg residuals at the measured poses, parameter units.

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
        Row ``6 j + i`` is pose ``j``, leg ``i``; columns in parameter order.
    """
    check_variant(method)
    problem = measurements_problem(geometry, measurements, mask)
    return problem.leg_jacobian(problem.full0, method, scaled=False)
