"""The instrument interface: what an instrument measures at a platform pose, and a session.

Every observation ``j`` (one measured pose of the machine) has six leg readings and some
instrument values ``y_j``. Its unknowns are the parameters ``θ`` (the machine's, and the
instrument's own: its frame, a tool, targets) and the true platform pose ``P_j`` (a nuisance
parameter). A :class:`MeasurementModel` predicts the instrument values ``h(θ, P_j)``, gives
their Jacobians with respect to its own parameters and to the pose, which values are present
(a laser tracker loses a target now and then), their noise covariance, a start for what the
data must register (an unknown frame), and simulated data. The leg equations are the same
for every instrument (:mod:`hexcal.core.legs`), so a new instrument is one subclass of
:class:`MeasurementModel` plus one registration (:mod:`hexcal.instruments.registry`); every
estimator, bound, noise estimate, outlier check, verdict, validation and simulation then
works for it.

A :class:`Session` is the data of one campaign and the instrument that saw them: a
calibration combines one or more sessions of one machine, each with its own instrument
quantities.

Imports :mod:`hexcal.core` only.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.geometry import Geometry
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import ParameterSet
from hexcal.errors import UsageError
from hexcal.instruments.covariates import NO_COVARIATES, Covariates
from hexcal.instruments.known_noise import Device, device_for

#: The noise groups an instrument's covariance may depend on (fields of :class:`NoiseModel`).
NOISE_FIELDS = ("position", "orientation")


class MeasurementModel(ABC):
    """An instrument: predicted values of an observation, their Jacobians and their noise.

    Attributes
    ----------
    name : str
        Registry name.
    size : int
        Instrument values per observation (missing values are masked, see :meth:`observed`).
    """

    name: str = ""
    size: int = 0

    # -- the instrument's own parameters -------------------------------------------------
    def parameters(self) -> ParameterSet:
        """The instrument's parameters: start values, which are varied, scales, groups
        (none by default)."""
        return ParameterSet((), np.empty(0))

    def with_values(self, values: NDArray[np.float64], calibration: dict[str, Any] | None = None) -> Any:
        """The same instrument with its parameters at ``values`` (a calibrated instrument)."""
        return self

    def describe(self) -> str:
        """One line: what the instrument sees."""
        return self.name

    def setup_dict(self) -> dict[str, Any] | None:
        """The instrument's setup as the mapping of a setup file (None: it has none to write)."""
        return None

    # -- data ----------------------------------------------------------------------------
    @abstractmethod
    def observed(self, data: Any) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Instrument values ``(m, size)`` of the data and which are present (same shape)."""

    def readings(self, data: Any) -> NDArray[np.float64]:
        """Leg readings ``(m, 6)`` of the data."""
        return data.readings

    def ids(self, data: Any) -> tuple[str, ...]:
        """Observation labels."""
        return tuple(data.ids)

    def covariates(self, data: Any) -> Covariates:
        """The observations' covariates (time, leg temperatures, payload): ``data.covariates``,
        none present for data that carry none."""
        found = getattr(data, "covariates", None)
        return NO_COVARIATES if found is None else found

    def subset(self, data: Any, index: NDArray[np.intp]) -> Any:
        """The observations at ``index``."""
        return data.subset(index)

    def value_groups(self) -> tuple[tuple[str, NDArray[np.intp]], ...]:
        """Groups of an observation's values that can be wrong on their own (a target seen
        badly), as ``(label, value indices)``; none by default (only whole observations)."""
        return ()

    def without_values(self, data: Any, j: int, values: NDArray[np.intp]) -> Any:
        """The data with values ``values`` of observation ``j`` left out (an outlier); by
        default, and when no value of the observation would remain, without the observation."""
        return self.subset(data, np.delete(np.arange(len(self.ids(data))), j))

    # -- the measurement model -----------------------------------------------------------
    @abstractmethod
    def predict(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        """Predicted instrument values ``(m, size)`` at true poses ``(m, 6)``."""

    def residual(
        self,
        setup: NDArray[np.float64],
        poses: NDArray[np.float64],
        euler: str,
        observed: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """Instrument residual ``(m, size)`` at true poses: ``predict - observed`` by default; a
        model overrides it where a plain difference is not a distance (orientations)."""
        return self.predict(setup, poses, euler) - observed

    @abstractmethod
    def pose_jacobian(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        """``d residual / d pose``, shape ``(m, size, 6)``."""

    def whitened_pose_jacobian(
        self,
        setup: NDArray[np.float64],
        poses: NDArray[np.float64],
        euler: str,
        whitener: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """``W d residual / d pose`` for a whitening matrix ``W`` (size, size): ``(m, size, 6)``."""
        return np.matmul(whitener, self.pose_jacobian(setup, poses, euler))

    def residual_and_pose_jacobian(
        self,
        setup: NDArray[np.float64],
        poses: NDArray[np.float64],
        euler: str,
        observed: NDArray[np.float64],
        whitener: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """:meth:`residual` and :meth:`whitened_pose_jacobian` at once (what the pose solve of the
        likelihood asks at every step); a model overrides it to share the work of the two."""
        return self.residual(setup, poses, euler, observed), self.whitened_pose_jacobian(
            setup, poses, euler, whitener
        )

    def setup_jacobian(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        """``d residual / d instrument parameters``, shape ``(m, size, q)`` (none by default)."""
        return np.zeros((len(poses), self.size, len(setup)))

    @abstractmethod
    def covariance(self, noise: NoiseModel) -> NDArray[np.float64]:
        """Noise covariance of one observation's instrument values, ``(size, size)``."""

    def noise_groups(self) -> tuple[str, ...]:
        """The :class:`NoiseModel` fields the covariance depends on (``position``, ...)."""
        groups = []
        for name in NOISE_FIELDS:
            probe = NoiseModel(0.0, **{f: float(f == name) for f in NOISE_FIELDS}, distribution="normal")
            if np.any(np.asarray(self.covariance(probe)) != 0):
                groups.append(name)
        return tuple(groups)

    @property
    def device(self) -> Device:
        """The kind of instrument and the noise such instruments have
        (:mod:`hexcal.instruments.known_noise`); by default the kind of its name."""
        return device_for(self.name)

    def declared_noise(self) -> dict[str, float]:
        """The instrument's own noise as its setup declares it, one σ by noise group (none by
        default)."""
        return {}

    def uses_pose_covariance(self) -> bool:
        """Whether a full pose covariance (:attr:`NoiseModel.pose_covariance`) changes this
        instrument's noise: it does for an instrument that measures a pose, not for targets."""
        # two covariances with the same σ per group (NoiseModel.sigmas) but another shape: only an
        # instrument that uses the matrix itself tells them apart
        shaped = NoiseModel(0.0, 1.0, 1.0, "normal", pose_covariance=np.diag([1.0, 4.0, 9.0] * 2))
        even = NoiseModel(0.0, 1.0, 1.0, "normal", pose_covariance=np.eye(6) * 14.0 / 3.0)
        return not np.array_equal(np.asarray(self.covariance(shaped)), np.asarray(self.covariance(even)))

    def group_labels(self) -> dict[str, str]:
        """What each noise group is called in reports (``targets`` for target positions)."""
        return {}

    @abstractmethod
    def start_poses(self, geometry: Geometry, setup: NDArray[np.float64], data: Any) -> NDArray[np.float64]:
        """Initial estimates of the true poses ``(m, 6)``."""

    # -- what the data must settle ------------------------------------------------------
    def register(self, geometry: Geometry, data: Any) -> tuple[Any, Any]:
        """``(instrument, registration)``: the instrument with start values for the
        quantities the data must settle (an unknown frame), and a record of how they were
        found (None when nothing needed it)."""
        return self, None

    def as_start(self) -> MeasurementModel:
        """The instrument as an identification starts from it in a simulated campaign: the
        quantities a user does not know beforehand marked unknown (an instrument frame
        ``auto``); itself by default."""
        return self

    def after_step(self) -> MeasurementModel:
        """The instrument of the observations after a step (it was bumped, or what it sees
        slipped), as a session of their own: what it measured from is unknown again. By default
        itself: its free quantities are each session's own anyway."""
        return self

    @property
    def unregistered(self) -> bool:
        """Whether some of the instrument's quantities are unknown until the data register
        them (an instrument frame given as ``auto``)."""
        return False

    def transform_setup(
        self,
        setup: NDArray[np.float64],
        base: tuple[NDArray, NDArray],
        platform: tuple[NDArray, NDArray],
        euler: str,
    ) -> NDArray[np.float64] | None:
        """The parameters after new base (``p' = R_b p + t_b``) and platform coordinates
        (the same physical instrument), or None when the instrument is tied to the base frame
        (its values have no meaning in other coordinates: then the frames are no gauge)."""
        return None

    @property
    def determines_pose(self) -> bool:
        """Whether one observation alone gives the platform pose in the base frame (the
        estimators that treat the measured pose as exact, ``paper``, ``length`` and ``gls``,
        need this)."""
        return False

    def platform_poses(self, setup: NDArray[np.float64], data: Any, euler: str) -> NDArray[np.float64]:
        """The platform poses ``(m, 6)`` the observations give (instruments that
        :attr:`determine the pose <determines_pose>`)."""
        raise UsageError(f"the {self.name} measurement does not give the platform pose by itself")

    def platform_from(
        self, setup: NDArray[np.float64], measured: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        """The platform poses ``(..., m, 6)`` of measured values ``(..., m, size)`` (batch-first;
        instruments that determine the pose)."""
        raise UsageError(f"the {self.name} measurement does not give the platform pose by itself")

    @property
    def constant_pose_jacobian(self) -> bool:
        """Whether ``d residual / d pose`` is the identity (the full pose): batched solvers then
        take the instrument rows of the pose Jacobian to be the whitener itself."""
        return False

    def platform_covariance(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], noise: NoiseModel, euler: str
    ) -> NDArray[np.float64]:
        """Covariance ``(m, 6, 6)`` of the platform poses that the instrument's values give with
        its quantities known (the least-squares pose of each observation, as validation finds
        it): the noise through the pseudo-inverse of the pose Jacobian, ``H⁺ Σ H⁺ᵀ`` (``H⁻¹ Σ
        H⁻ᵀ`` for six values); NaN where the values cannot give the pose (rank below 6)."""
        jac = self.pose_jacobian(setup, poses, euler)  # batch-first: (..., m, size, 6)
        if jac.shape[-2] == 6:
            inv = np.linalg.inv(jac)
        else:
            inv = np.linalg.pinv(jac)
            sv = np.linalg.svd(jac, compute_uv=False)
            inv[~(sv[..., -1] > 1e-9 * sv[..., 0]) if sv.shape[-1] == 6 else ...] = np.nan
        return inv @ self.covariance(noise) @ np.swapaxes(inv, -1, -2)

    # -- simulation and diagnoses ---------------------------------------------------------
    def simulate(
        self,
        setup: NDArray[np.float64],
        poses: NDArray[np.float64],
        readings: NDArray[np.float64],
        euler: str,
        noise: NoiseModel | None,
        rng: np.random.Generator,
        ids: tuple[str, ...] = (),
    ) -> Any:
        """The data the instrument records at true ``poses`` with leg ``readings``: the
        prediction plus noise drawn from ``rng`` (noise-free when ``noise`` is None)."""
        raise UsageError(f"the {self.name} instrument cannot simulate data")

    def variants(self, data: Any) -> tuple[tuple[str, str, Any], ...]:
        """Re-readings of the data that a likely mistake would explain, as ``(code, text,
        data)``: lengths in metres or inches, angles in the other unit (none by default)."""
        return ()

    @property
    def has_angles(self) -> bool:
        """Whether the data carry angles (then a wrong Euler sequence can be diagnosed)."""
        return False

    def errors(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], data: Any, euler: str
    ) -> dict[str, NDArray[np.float64]]:
        """Prediction errors in the instrument's own terms at poses ``(m, 6)``: named arrays
        ``(m, ...)`` (``position`` mm, ``orientation`` rad, ...), NaN where a value is missing."""
        values, present = self.observed(data)
        diff = np.where(present, self.residual(setup, poses, euler, values), np.nan)
        return {"value": np.sqrt(np.nanmean(diff**2, axis=1))}


@dataclass(frozen=True, eq=False)
class Session:
    """One measurement session: the data and the instrument that recorded them.

    Parameters
    ----------
    data
        Observations in the form the instrument reads (leg readings and instrument values).
    instrument : MeasurementModel
        The instrument, with the start values of its own quantities and which are fixed.
    label : str
        How reports name the session (a file name); default ``session 1``, ... by position.
    """

    data: Any
    instrument: MeasurementModel
    label: str = ""

    def __len__(self) -> int:
        return len(self.instrument.ids(self.data))

    @property
    def ids(self) -> tuple[str, ...]:
        return self.instrument.ids(self.data)

    def subset(self, index: NDArray[np.intp]) -> Session:
        """The session with the observations at ``index``."""
        return Session(self.instrument.subset(self.data, index), self.instrument, self.label)

    def replace(self, **changes: Any) -> Session:
        from dataclasses import replace

        return replace(self, **changes)
