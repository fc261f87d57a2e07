"""Measurement noise: leg sensor, position and orientation errors (:class:`NoiseModel`).

Imports numpy and :mod:`hexcal.errors`.

>>> noise = NoiseModel(leg=0.01, position=0.025, orientation=0.001)   # uniform half-widths
>>> [round(float(s), 6) for s in noise.sigmas]
[0.005774, 0.014434, 0.000577]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hexcal.errors import InputError, UsageError


@dataclass(frozen=True, eq=False)
class NoiseModel:
    """Measurement noise: leg sensor, position and orientation.

    Parameters
    ----------
    leg : float
        Leg sensor error, mm.
    position : float
        Position measurement error per coordinate, mm.
    orientation : float
        Orientation measurement error per Euler angle, rad.
    distribution : {"uniform", "normal"}
        With ``uniform`` the values are half-widths ``a`` of ``U(-a, a)`` (standard
        deviation ``a / sqrt(3)``); with ``normal`` they are standard deviations.
    pose_covariance : array_like, shape (6, 6), optional
        Full covariance of the pose measurement error (mm², mm·rad, rad²), replacing
        ``position`` and ``orientation``; its errors are drawn from a normal distribution.

    The defaults are the seed paper's section VI: ±0.01 mm, ±0.025 mm, ±0.001 rad.
    """

    leg: float = 0.01
    position: float = 0.025
    orientation: float = 0.001
    distribution: str = "uniform"
    pose_covariance: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        if self.pose_covariance is not None:
            cov = np.array(self.pose_covariance, dtype=float)
            if cov.shape != (6, 6) or not np.all(np.isfinite(cov)):
                raise UsageError(f"pose covariance must be a finite 6x6 matrix, got shape {cov.shape}")
            if not np.allclose(cov, cov.T, rtol=1e-9, atol=0) or np.linalg.eigvalsh(cov)[0] < 0:
                raise UsageError("pose covariance must be symmetric positive semi-definite")
            cov.flags.writeable = False
            object.__setattr__(self, "pose_covariance", cov)
        if self.distribution not in ("uniform", "normal"):
            raise UsageError(f"noise distribution must be 'uniform' or 'normal', got {self.distribution!r}")
        for name in ("leg", "position", "orientation"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise UsageError(f"noise {name} must be a finite value >= 0, got {value!r}")

    @property
    def sigmas(self) -> tuple[float, float, float]:
        """Standard deviations ``(leg, position, orientation)``; with a ``pose_covariance``, the
        position and orientation ones are the RMS of its diagonal's square roots (its own)."""
        k = 1 / np.sqrt(3) if self.distribution == "uniform" else 1.0
        if self.pose_covariance is not None:
            diag = np.diag(np.asarray(self.pose_covariance, dtype=float))
            return (self.leg * k, float(np.sqrt(np.mean(diag[:3]))), float(np.sqrt(np.mean(diag[3:]))))
        return (self.leg * k, self.position * k, self.orientation * k)

    @property
    def has_pose_noise(self) -> bool:
        """Whether the pose measurement has any noise at all."""
        return bool(np.any(self.pose_cov() != 0))

    def pose_cov(self) -> NDArray[np.float64]:
        """Covariance of the pose measurement error, shape (6, 6)."""
        if self.pose_covariance is not None:
            return np.array(self.pose_covariance)
        _, s_pos, s_ang = self.sigmas
        return np.diag([s_pos**2] * 3 + [s_ang**2] * 3)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready form: the values as given and the standard deviations they imply."""
        out: dict[str, object] = {
            "leg": self.leg,
            "position": self.position,
            "orientation": self.orientation,
            "distribution": self.distribution,
            "sigmas": {"leg": self.sigmas[0], "position": self.sigmas[1], "orientation": self.sigmas[2]},
        }
        if self.pose_covariance is not None:
            out["pose_covariance"] = self.pose_covariance.tolist()
        return out

    def describe(self) -> str:
        """One line for reports."""
        if self.pose_covariance is not None:
            return f"leg σ {self.sigmas[0]:.4g} mm, full 6x6 pose covariance"
        kind = "uniform ±" if self.distribution == "uniform" else "normal σ "
        return (
            f"{kind}{self.leg:g} mm legs, {kind}{self.position:g} mm position, "
            f"{kind}{self.orientation:g} rad orientation"
        )

    def _draw(self, rng: np.random.Generator, scale: float, shape: tuple[int, ...]) -> NDArray:
        if self.distribution == "uniform":
            return rng.uniform(-scale, scale, size=shape)
        return rng.normal(0.0, scale, size=shape)

    def leg_errors(self, rng: np.random.Generator, shape: tuple[int, ...]) -> NDArray:
        """Leg sensor errors of shape ``shape + (6,)``, mm."""
        return self._draw(rng, self.leg, (*shape, 6))

    def pose_errors(self, rng: np.random.Generator, shape: tuple[int, ...]) -> NDArray:
        """Pose measurement errors of shape ``shape + (6,)``, mm and rad."""
        if self.pose_covariance is not None:
            return rng.multivariate_normal(np.zeros(6), self.pose_covariance, size=shape, method="eigh")
        pos = self._draw(rng, self.position, (*shape, 3))
        ang = self._draw(rng, self.orientation, (*shape, 3))
        return np.concatenate([pos, ang], axis=-1)


def require_noise(noise: NoiseModel, what: str, pose_noise: bool = True) -> NoiseModel:
    """``noise``, unless it is zero in every group the measurement sees (the legs, and the pose
    when ``pose_noise``, else only its position: a ballbar's reading): then no weight, bound
    or prediction can come from it, and :class:`~hexcal.errors.InputError` says so (``what``:
    what would need it). Every function that predicts an accuracy or weighs data calls this,
    as ``identify`` refuses a zero ``--noise``.

    >>> require_noise(NoiseModel(leg=0.01), "every predicted accuracy").leg
    0.01
    >>> require_noise(NoiseModel(leg=0, position=0, orientation=0), "every bound")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    hexcal.errors.InputError: --noise: every noise is 0, so every bound would be 0 by construction; ...
    """
    seen = noise.has_pose_noise if pose_noise else noise.sigmas[1] > 0
    if noise.leg == 0 and not seen:
        zero = "every noise is 0" if pose_noise else "leg and pos are 0 (the noise of the legs and the bar)"
        raise InputError(
            f"--noise: {zero}, so {what} would be 0 by construction; give the instruments' "
            "σ (e.g. leg=0.01,pos=0.025,ang=0.001), or leave --noise out to learn it from the data"
        )
    return noise
