"""Position instruments: laser-tracker targets (SMRs) on the platform, in the tracker's frame.

An observation is one pose of the machine: the six leg readings and, for each target of the
setup, its measured position in the instrument frame (or nothing, when the line of sight was
lost). The model predicts ``y_i = R_F (o + R_P q_i) + t_F`` for target ``q_i`` (platform frame)
at the true pose ``(o, R_P)`` with the instrument frame ``(R_F, t_F)``: three residuals per
target seen. Noise: each coordinate of a target has the standard deviation of
:class:`~hexcal.core.noise.NoiseModel`'s ``position`` (independent, isotropic; reported as the
``targets`` group).

>>> model = TargetModel(Setup(np.zeros(6), {"t1": [0, 0, 60]}))
>>> model.predict(model.setup.vector(), np.zeros((2, 6)), "XYZ")
array([[ 0.,  0., 60.],
       [ 0.,  0., 60.]])
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.conventions import euler_axes
from hexcal.core.geometry import Geometry
from hexcal.core.machine import pose_frames
from hexcal.core.noise import NoiseModel
from hexcal.errors import UsageError
from hexcal.instruments.data import TargetMeasurements
from hexcal.instruments.framed import FramedModel, cross_axes
from hexcal.instruments.pose import LENGTH_UNITS
from hexcal.instruments.registration import Registration, register_targets
from hexcal.instruments.setup import Setup, frame_transform


class TargetModel(FramedModel):
    """Target positions in the instrument frame: ``3 n`` values per pose, any subset present.

    Setup parameters: the instrument frame (6), then the targets (``3 n``), see
    :mod:`hexcal.instruments.setup`.
    """

    name = "targets"

    def __init__(self, setup: Setup | None = None) -> None:
        self.setup = Setup(None, {"t1": np.zeros(3)}) if setup is None else setup
        if self.setup.kind != "targets":
            raise UsageError("the target model needs a setup with targets")
        self.n_targets = len(self.setup.targets)
        self.size = 3 * self.n_targets

    def describe(self) -> str:
        frame = f"frame {self.setup.frame_state}"
        return f"{self.n_targets} target position(s) in the instrument frame ({frame})"

    def observed(self, data: TargetMeasurements) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        if tuple(data.names) != self.setup.target_names:
            raise UsageError(f"the data have targets {data.names}, the setup {self.setup.target_names}")
        present = np.repeat(data.seen, 3, axis=1)
        return np.nan_to_num(data.targets.reshape(len(data), -1)), present

    # The functions below are batch-first: ``setup`` (..., 6 + 3 n) and ``poses`` (..., m, 6)
    # with broadcasting batch shapes (one campaign: ``setup`` (q,), ``poses`` (m, 6)).
    def _points(self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str) -> tuple:
        rot_f, t_f = frame_transform(setup[..., :6], euler)
        q = setup[..., 6:].reshape(*np.shape(setup)[:-1], -1, 3)
        rot_p, pos = pose_frames(poses, euler)
        rq = np.einsum("...mjk,...ik->...mij", rot_p, q)  # (..., m, n, 3)
        return rot_f, t_f, q, rot_p, rq, pos[..., :, None, :] + rq

    def predict(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        rot_f, t_f, _, _, _, p = self._points(setup, poses, euler)
        values = np.einsum("...ij,...mnj->...mni", rot_f, p) + t_f[..., None, None, :]
        return values.reshape(*values.shape[:-2], -1)

    def pose_jacobian(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        rot_f, _, _, _, rq, _ = self._points(setup, poses, euler)
        lead, n = rq.shape[:-2], rq.shape[-2]
        axes = euler_axes(poses[..., 3:], euler)  # (..., m, 3, 3) rows w_k
        jac = np.empty((*lead, n, 3, 6))
        jac[..., :3] = rot_f[..., None, None, :, :]
        jac[..., 3:] = np.einsum("...ab,...mnbk->...mnak", rot_f, cross_axes(axes[..., :, None, :, :], rq))
        return jac.reshape(*lead, 3 * n, 6)

    def setup_jacobian(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        rot_f, _, _, rot_p, _, p = self._points(setup, poses, euler)
        lead, n = p.shape[:-2], p.shape[-2]
        axes_f = euler_axes(setup[..., 3:6], euler)[..., None, None, :, :]
        jac = np.zeros((*lead, n, 3, 6 + 3 * n))
        jac[..., :3] = np.eye(3)
        jac[..., 3:6] = cross_axes(axes_f, np.einsum("...ij,...mnj->...mni", rot_f, p))
        rr = rot_f[..., None, :, :] @ rot_p  # d y_i / d q_i, (..., m, 3, 3)
        for i in range(n):  # loop over targets, not poses
            jac[..., i, :, 6 + 3 * i : 9 + 3 * i] = rr
        return jac.reshape(*lead, 3 * n, -1)

    def covariance(self, noise: NoiseModel) -> NDArray[np.float64]:
        return noise.sigmas[1] ** 2 * np.eye(self.size)

    def platform_setup(
        self, values: NDArray[np.float64], platform: tuple[NDArray, NDArray], euler: str
    ) -> NDArray[np.float64]:
        rp, tp = platform
        points = values.reshape(*np.shape(values)[:-1], -1, 3)
        moved = points @ np.swapaxes(rp, -1, -2) + np.asarray(tp)[..., None, :]
        return moved.reshape(np.shape(values))

    def group_labels(self) -> dict[str, str]:
        return {"position": "targets"}

    def value_groups(self) -> tuple[tuple[str, NDArray[np.intp]], ...]:
        return tuple(
            (f"target {name}", np.arange(3 * i, 3 * i + 3)) for i, name in enumerate(self.setup.target_names)
        )

    def without_values(self, data: TargetMeasurements, j: int, values: NDArray[np.intp]) -> Any:
        targets = np.array(data.targets).reshape(len(data), -1)
        targets[j, values] = np.nan
        if np.isnan(targets[j]).all():
            return data.subset(np.delete(np.arange(len(data)), j))
        return data.replace(targets=targets.reshape(data.targets.shape))

    def register(self, geometry: Geometry, data: TargetMeasurements) -> tuple[Any, Registration | None]:
        if not self.setup.auto:
            return self, None
        reg = register_targets(geometry, self.setup, data)
        return self.with_values(np.concatenate([reg.frame, self.setup.vector()[6:]])), reg

    def simulate(
        self,
        setup: NDArray[np.float64],
        poses: NDArray[np.float64],
        readings: NDArray[np.float64],
        euler: str,
        noise: NoiseModel | None,
        rng: np.random.Generator,
        ids: tuple[str, ...] = (),
        missing_rate: float = 0.0,
    ) -> TargetMeasurements:
        """Target positions at true poses plus noise; each target observation is lost with
        probability ``missing_rate``, and a pose with every target lost is not recorded (the
        ids keep the others' labels)."""
        m, n = len(poses), self.n_targets
        values = self.predict(setup, poses, euler).reshape(m, n, 3)
        if noise is not None:
            values = values + noise.pose_errors(rng, (m, n))[..., :3]
        lost = rng.random((m, n)) < missing_rate
        values[lost] = np.nan
        keep = ~lost.all(axis=1)
        labels = tuple(ids) or tuple(str(k + 1) for k in range(m))
        return TargetMeasurements(
            readings[keep],
            values[keep],
            self.setup.target_names,
            tuple(labels[k] for k in np.flatnonzero(keep)),
        )

    def variants(self, data: TargetMeasurements) -> tuple[tuple[str, str, Any], ...]:
        return tuple(
            (
                f"length-units-{unit}",
                f"the target coordinates look like {unit}",
                data.replace(targets=data.targets * f),
            )
            for unit, f in LENGTH_UNITS
        )

    def errors(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], data: TargetMeasurements, euler: str
    ) -> dict[str, NDArray[np.float64]]:
        """Distance (mm) between each measured and predicted target (NaN where not seen)."""
        predicted = self.predict(setup, poses, euler).reshape(data.targets.shape)
        return {"target": np.linalg.norm(predicted - data.targets, axis=-1)}
