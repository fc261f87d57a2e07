"""The data an instrument records: leg readings with measured poses or target positions.

:class:`Measurements` holds measured poses (a full pose in the base frame, or a tool's pose
in an instrument frame) and the leg readings at each; :class:`TargetMeasurements` the
positions of targets on the platform in an instrument frame (a target not seen is NaN). Each
carries the :class:`~hexcal.instruments.covariates.Covariates` of its rows (time, the legs'
temperatures, the payload; none present by default), kept by every copy and subset.
Imports :mod:`hexcal.core` only.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.conventions import as_poses
from hexcal.errors import UsageError
from hexcal.instruments.covariates import NO_COVARIATES, Covariates, check_rows


@dataclass(frozen=True, eq=False)
class Measurements:
    """Measured poses and the leg readings at each.

    Parameters
    ----------
    poses : array_like, shape (m, 6)
        Measured poses, mm and rad, in the geometry's Euler convention.
    readings : array_like, shape (m, 6)
        Leg readings ``dl_i``, mm.
    ids : sequence of str, optional
        Pose labels; default ``"1" ... "m"`` (the row numbers).
    covariates : Covariates, optional
        The rows' time, leg temperatures and payload; default none present.
    """

    poses: NDArray[np.float64]
    readings: NDArray[np.float64]
    ids: tuple[str, ...] = field(default=())
    covariates: Covariates = field(default=NO_COVARIATES)

    def __post_init__(self) -> None:
        poses = np.array(as_poses(self.poses, "measured poses"), dtype=float)
        readings = np.array(self.readings, dtype=float)
        if poses.ndim != 2:
            raise UsageError(f"measured poses must have shape (m, 6), got {poses.shape}")
        if readings.shape != poses.shape:
            raise UsageError(
                f"leg readings must have shape {poses.shape} like the poses, got {readings.shape}"
            )
        for what, arr in (("measured poses", poses), ("leg readings", readings)):
            bad = np.flatnonzero(~np.all(np.isfinite(arr), axis=1))
            if bad.size:
                raise UsageError(f"{what} contain NaN or inf (row {bad[0] + 1})")
        ids = tuple(str(i) for i in self.ids) or tuple(str(k + 1) for k in range(len(poses)))
        if len(ids) != len(poses):
            raise UsageError(f"{len(ids)} ids for {len(poses)} poses")
        poses.flags.writeable = False
        readings.flags.writeable = False
        object.__setattr__(self, "poses", poses)
        object.__setattr__(self, "readings", readings)
        object.__setattr__(self, "ids", ids)
        object.__setattr__(self, "covariates", check_rows(self.covariates, len(poses)))

    def __len__(self) -> int:
        return int(self.poses.shape[0])

    def subset(self, index: ArrayLike) -> Measurements:
        """The measurements at ``index`` (an integer or boolean index)."""
        idx = np.arange(len(self))[np.asarray(index)]
        return Measurements(
            self.poses[idx], self.readings[idx], tuple(self.ids[i] for i in idx), self.covariates.subset(idx)
        )

    def replace(self, **changes: Any) -> Measurements:
        """Copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True, eq=False)
class TargetMeasurements:
    """Leg readings and measured target positions of every pose.

    Parameters
    ----------
    readings : array_like, shape (m, 6)
        Leg readings ``dl``, mm.
    targets : array_like, shape (m, n, 3)
        Target positions in the instrument frame, mm; a target not seen is NaN (all three).
    names : sequence of str
        Target names ``t1 ...`` (``n``).
    ids : sequence of str, optional
        Pose labels; default the row numbers.
    covariates : Covariates, optional
        The rows' time, leg temperatures and payload; default none present.
    """

    readings: NDArray[np.float64]
    targets: NDArray[np.float64]
    names: tuple[str, ...]
    ids: tuple[str, ...] = field(default=())
    covariates: Covariates = field(default=NO_COVARIATES)

    def __post_init__(self) -> None:
        readings = np.array(self.readings, dtype=float)
        targets = np.array(self.targets, dtype=float)
        names = tuple(self.names)
        m = len(readings)
        if readings.ndim != 2 or readings.shape[1] != 6:
            raise UsageError(f"leg readings must have shape (m, 6), got {readings.shape}")
        if targets.shape != (m, len(names), 3):
            raise UsageError(f"target positions must have shape ({m}, {len(names)}, 3), got {targets.shape}")
        ids = tuple(str(i) for i in self.ids) or tuple(str(k + 1) for k in range(m))
        if len(ids) != m:
            raise UsageError(f"{len(ids)} ids for {m} poses")
        bad = np.flatnonzero(~np.all(np.isfinite(readings), axis=1))
        if bad.size:
            raise UsageError(f"leg readings contain NaN or inf (pose {ids[bad[0]]}, row {bad[0] + 1})")
        nan = np.isnan(targets)
        partial = np.flatnonzero(np.any(nan.any(axis=2) & ~nan.all(axis=2), axis=1))
        if partial.size or np.isinf(targets).any():
            k = partial[0] if partial.size else int(np.argwhere(np.isinf(targets))[0, 0])
            raise UsageError(f"pose {ids[k]} (row {k + 1}): a target needs all three coordinates or none")
        unseen = np.flatnonzero(nan.all(axis=(1, 2)))
        if unseen.size:
            k = unseen[0]
            raise UsageError(f"pose {ids[k]} (row {k + 1}): no target seen (every target cell is empty)")
        for arr in (readings, targets):
            arr.flags.writeable = False
        object.__setattr__(self, "readings", readings)
        object.__setattr__(self, "targets", targets)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "ids", ids)
        object.__setattr__(self, "covariates", check_rows(self.covariates, m))

    def __len__(self) -> int:
        return int(self.readings.shape[0])

    @property
    def seen(self) -> NDArray[np.bool_]:
        """Which target was seen at which pose, ``(m, n)``."""
        return ~np.isnan(self.targets[..., 0])

    def subset(self, index: ArrayLike) -> TargetMeasurements:
        """The poses at ``index`` (integer or boolean)."""
        idx = np.arange(len(self))[np.asarray(index)]
        return TargetMeasurements(
            self.readings[idx],
            self.targets[idx],
            self.names,
            tuple(self.ids[i] for i in idx),
            self.covariates.subset(idx),
        )

    def replace(self, **changes: Any) -> TargetMeasurements:
        """Copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)
