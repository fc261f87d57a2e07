"""A toy instrument and a toy leg model, written the way a user of hexcal would add them.

Nothing here is in ``src``: the two classes are built on the public seams only
(:class:`hexcal.instruments.MeasurementModel`, :class:`hexcal.core.legs.LegModel`) and are
registered by name in the test that uses them (:func:`registered`), to show that a new
instrument is one module plus one registration, and a new leg model likewise.

- :class:`BallBar`: a telescoping ball bar (a seventh, measuring leg) between a pivot on the
  base and a ball on the platform. One value per observation, the distance
  ``|o + R_P b - c|`` between the pivot ``c`` (base frame) and the ball ``b`` (platform
  frame); its own setup parameters are those two points (``pivot.x .. ball.z``). Unlike the
  full pose, the targets or a tool it has no frame of its own, does not give the platform
  pose (only ``ml`` can use it), and its setup is tied to both the base and the platform
  frames (so both frames are gauge freedoms).
- :class:`QuadraticLegs`: ``l = l0 + g dl + q dl²`` (a stroke-dependent error of the leg's
  scale), one extra term ``q_i`` per leg, in the group ``quadratic``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.conventions import euler_axes
from hexcal.core.geometry import Geometry
from hexcal.core.legs import LEG_MODELS, LegModel, register_leg_model
from hexcal.core.machine import pose_frames
from hexcal.core.noise import NoiseModel
from hexcal.core.parameters import ParameterSet
from hexcal.design import PlannedMeasurements
from hexcal.errors import GeometryError, InputError, UsageError
from hexcal.instruments import (
    MODELS,
    InstrumentKind,
    MeasurementModel,
    cross_axes,
    fk_start_poses,
    register_instrument,
    unregister_instrument,
)
from hexcal.io import read_table, write_table

# -- the toy leg model -------------------------------------------------------------------


class QuadraticLegs(LegModel):
    """``l = l0 + g dl + q dl²``: the linear model plus one quadratic term per leg."""

    name = "quadratic"
    terms = ("q",)

    def length(self, theta: NDArray[np.float64], reading: NDArray[np.float64]) -> NDArray[np.float64]:
        return theta[..., 0] + theta[..., 1] * reading + theta[..., 2] * reading**2

    def length_jacobian(
        self, theta: NDArray[np.float64], reading: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        one = np.ones(np.broadcast_shapes(theta.shape[:-1], np.shape(reading)))
        return np.stack([one, one * reading, one * reading**2], axis=-1)

    def slope(self, theta: NDArray[np.float64], reading: NDArray[np.float64]) -> NDArray[np.float64]:
        return theta[..., 1] + 2 * theta[..., 2] * reading

    def term_scales(self) -> NDArray[np.float64]:
        return np.array([1e-5])  # 1e-5 / mm moves a leg by 0.1 mm at 100 mm of reading

    def term_units(self) -> tuple[str, ...]:
        return ("1/mm",)  # q multiplies a squared reading (mm²) to give a length

    def to_dict(self, block: ArrayLike) -> Any:
        return {"kind": self.name, "q": [float(v) for v in np.asarray(block)[12:18]]}

    @classmethod
    def from_dict(cls, value: Any, where: str = "leg_model") -> tuple[LegModel, NDArray[np.float64]]:
        q = value.get("q", [0.0] * 6) if isinstance(value, dict) else [0.0] * 6
        if not isinstance(q, list) or len(q) != 6:
            raise GeometryError(f"{where}.q: six numbers, one per leg")
        return cls(), np.asarray(q, dtype=float).reshape(6, 1)


# -- the toy instrument ------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class BarMeasurements:
    """Leg readings ``(m, 6)`` and the ball bar's length ``(m,)`` at each observation."""

    readings: NDArray[np.float64]
    lengths: NDArray[np.float64]
    ids: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        readings = np.array(self.readings, dtype=float).reshape(-1, 6)
        lengths = np.array(self.lengths, dtype=float).reshape(len(readings))
        ids = tuple(str(i) for i in self.ids) or tuple(str(k + 1) for k in range(len(readings)))
        object.__setattr__(self, "readings", readings)
        object.__setattr__(self, "lengths", lengths)
        object.__setattr__(self, "ids", ids)

    def __len__(self) -> int:
        return len(self.readings)

    def subset(self, index: ArrayLike) -> BarMeasurements:
        idx = np.arange(len(self))[np.asarray(index)]
        return BarMeasurements(self.readings[idx], self.lengths[idx], tuple(self.ids[i] for i in idx))

    def replace(self, **changes: Any) -> BarMeasurements:
        return dataclasses.replace(self, **changes)


BAR_NAMES = ("pivot.x", "pivot.y", "pivot.z", "ball.x", "ball.y", "ball.z")


def _point(value: Any, where: str) -> NDArray[np.float64]:
    if not isinstance(value, list) or len(value) != 3 or not all(isinstance(v, int | float) for v in value):
        raise InputError(f"toybar.{where}: three numbers [x, y, z] (mm)")
    return np.array(value, dtype=float)


@dataclass(frozen=True, eq=False)
class BarSetup:
    """The ball bar's setup: ``pivot`` (base frame, mm), ``ball`` (platform frame, mm), ``fixed``
    (``pivot`` and/or ``ball``, known exactly). Its file: ``units: mm``, ``toybar: {pivot: [x, y,
    z], ball: [x, y, z]}``, optional ``fixed: [...]`` and, once calibrated, ``calibration``."""

    pivot: NDArray[np.float64]
    ball: NDArray[np.float64]
    fixed: tuple[str, ...] = ()
    calibration: dict[str, Any] | None = None
    columns: dict[str, str] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "pivot", np.array(self.pivot, dtype=float).reshape(3))
        object.__setattr__(self, "ball", np.array(self.ball, dtype=float).reshape(3))
        object.__setattr__(self, "fixed", tuple(self.fixed))

    kind = "toybar"
    auto = False

    def names(self) -> tuple[str, ...]:
        return BAR_NAMES

    def vector(self) -> NDArray[np.float64]:
        return np.concatenate([self.pivot, self.ball])

    def parameters(self, euler: str | None = None) -> ParameterSet:
        vary = np.array([("pivot" not in self.fixed)] * 3 + [("ball" not in self.fixed)] * 3)
        groups = {"pivot": BAR_NAMES[:3], "ball": BAR_NAMES[3:]}
        return ParameterSet(BAR_NAMES, self.vector(), vary, np.ones(6), groups, units="mm")

    def with_vector(self, values: ArrayLike, calibration: dict[str, Any] | None = None) -> BarSetup:
        values = np.asarray(values, dtype=float)
        return dataclasses.replace(self, pivot=values[:3], ball=values[3:6], calibration=calibration)

    def in_euler(self, euler: str) -> BarSetup:
        return self  # no angles

    @classmethod
    def from_dict(cls, data: Any) -> BarSetup:
        if not isinstance(data, dict) or set(data) - {"units", "toybar", "fixed", "calibration"}:
            raise InputError("a toybar setup has the keys units, toybar, fixed, calibration")
        if data.get("units") != "mm":
            raise InputError("units: only mm")
        bar = data["toybar"]
        if not isinstance(bar, dict) or set(bar) != {"pivot", "ball"}:
            raise InputError("toybar: a mapping {pivot: [x, y, z], ball: [x, y, z]}")
        fixed = tuple(data.get("fixed") or ())
        if set(fixed) - {"pivot", "ball"}:
            raise InputError("fixed: pivot and/or ball")
        return cls(_point(bar["pivot"], "pivot"), _point(bar["ball"], "ball"), fixed, data.get("calibration"))

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "units": "mm",
            "toybar": {"pivot": self.pivot.tolist(), "ball": self.ball.tolist()},
        }
        if self.fixed:
            out["fixed"] = list(self.fixed)
        if self.calibration is not None:
            out["calibration"] = self.calibration
        return out


class BallBar(MeasurementModel):
    """A ball bar of a :class:`BarSetup`: between ``pivot`` (base frame, mm) and ``ball``
    (platform frame, mm). Noise: the ``position`` standard deviation of the
    :class:`NoiseModel` (the bar's length error).
    """

    name = "toybar"
    size = 1

    def __init__(self, setup: BarSetup) -> None:
        self.setup = setup
        self.pivot, self.ball, self.fixed = setup.pivot, setup.ball, setup.fixed

    # -- parameters ----------------------------------------------------------------------
    def parameters(self) -> ParameterSet:
        return self.setup.parameters()

    def with_values(self, values: NDArray[np.float64], calibration: dict[str, Any] | None = None) -> BallBar:
        return BallBar(self.setup.with_vector(values, calibration))

    def describe(self) -> str:
        return "ball bar between a base pivot and a platform ball"

    def setup_dict(self) -> dict[str, Any] | None:
        return self.setup.to_dict()

    # -- data ----------------------------------------------------------------------------
    def observed(self, data: BarMeasurements) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        values = data.lengths[:, None]
        return values, np.ones(values.shape, dtype=bool)

    # -- the model (batch-first: setup (..., 6), poses (..., m, 6)) ----------------------
    def _vector(self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str) -> tuple:
        rot, pos = pose_frames(poses, euler)
        pivot, ball = setup[..., None, :3], setup[..., None, 3:6]
        rb = np.einsum("...ij,...j->...i", rot, np.broadcast_to(ball, pos.shape))
        v = pos + rb - pivot
        return rot, rb, v, np.linalg.norm(v, axis=-1, keepdims=True)

    def predict(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        return self._vector(setup, poses, euler)[3]

    def pose_jacobian(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        _, rb, v, d = self._vector(setup, poses, euler)
        n = v / d
        axes = euler_axes(poses[..., 3:], euler)
        angles = np.einsum("...i,...ik->...k", n, cross_axes(axes, rb))
        return np.concatenate([n, angles], axis=-1)[..., None, :]

    def setup_jacobian(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], euler: str
    ) -> NDArray[np.float64]:
        rot, _, v, d = self._vector(setup, poses, euler)
        n = v / d
        return np.concatenate([-n, np.einsum("...i,...ij->...j", n, rot)], axis=-1)[..., None, :]

    def covariance(self, noise: NoiseModel) -> NDArray[np.float64]:
        return np.array([[noise.sigmas[1] ** 2]])

    def group_labels(self) -> dict[str, str]:
        return {"position": "ball bar"}

    def start_poses(self, geometry: Geometry, setup: NDArray[np.float64], data: Any) -> NDArray[np.float64]:
        return fk_start_poses(geometry, data.readings)

    def transform_setup(
        self,
        setup: NDArray[np.float64],
        base: tuple[NDArray, NDArray],
        platform: tuple[NDArray, NDArray],
        euler: str,
    ) -> NDArray[np.float64]:
        (rb, tb), (rp, tp) = base, platform
        pivot = np.einsum("...ij,...j->...i", rb, setup[..., :3]) + tb
        ball = np.einsum("...ij,...j->...i", rp, setup[..., 3:6]) + tp
        return np.concatenate([pivot, ball], axis=-1)

    # -- simulation ----------------------------------------------------------------------
    def simulate(
        self,
        setup: NDArray[np.float64],
        poses: NDArray[np.float64],
        readings: NDArray[np.float64],
        euler: str,
        noise: NoiseModel | None,
        rng: np.random.Generator,
        ids: tuple[str, ...] = (),
    ) -> BarMeasurements:
        lengths = self.predict(setup, poses, euler)[:, 0]
        if noise is not None:
            lengths = lengths + noise.pose_errors(rng, (len(poses),))[:, 0]
        return BarMeasurements(readings, lengths, ids)

    def errors(
        self, setup: NDArray[np.float64], poses: NDArray[np.float64], data: BarMeasurements, euler: str
    ) -> dict[str, NDArray[np.float64]]:
        return {"bar": self.predict(setup, poses, euler)[:, 0] - data.lengths}


# -- its data files ----------------------------------------------------------------------

BAR_COLUMNS = ("dl1", "dl2", "dl3", "dl4", "dl5", "dl6", "bar")


def read_bar_file(
    path: Any, instrument: BallBar, euler: str, delimiter: Any, decimal: Any
) -> BarMeasurements:
    """A ball-bar data file: ``id, dl1 .. dl6, bar`` (mm), strict CSV (:func:`hexcal.io.read_table`)."""
    if delimiter is not None or decimal is not None:
        raise InputError(f"{path}: ball-bar files are plain CSV")
    table = read_table(path)
    values = table.numbers(BAR_COLUMNS)
    ids = table.ids() if table.has("id") else ()
    return BarMeasurements(values[:, :6], values[:, 6], ids)


def write_bar_file(
    path: Any, data: BarMeasurements, euler: str, orientation: str = "rad", comment: Any = None
) -> None:
    """Write a ball-bar data file (atomically, staged like every hexcal output)."""
    write_table(path, BAR_COLUMNS, np.column_stack([data.readings, data.lengths]), data.ids, comment)


# -- registration ------------------------------------------------------------------------

# -- its planner ---------------------------------------------------------------------------


class BarPlanner:
    """The ball bar's own candidate measurements: the workspace's corners and centre at
    ``levels`` heights, kept where the bar (pivot to ball) is between ``shortest`` and
    ``longest`` mm; and their selection: the ``count`` (default 30) whose bar directions are
    most spread (greedy farthest-point on the unit sphere, from the first)."""

    def candidates(
        self, geometry: Geometry, setup: BarSetup, *, min_distance: Any = None, levels: int = 4,
        shortest: float = 100.0, longest: float = 2000.0,
    ) -> PlannedMeasurements:  # fmt: skip
        from hexcal.core import workspace_corners
        from hexcal.design import MIN_SINGULARITY_DISTANCE, check_feasibility

        corners = workspace_corners(geometry)
        poses = np.concatenate([corners, corners.mean(axis=0, keepdims=True)])
        shift = np.linspace(-0.25, 0.25, levels) * np.ptp(corners[:, 2])
        poses = np.concatenate([poses + np.array([0, 0, dz, 0, 0, 0]) for dz in shift])
        bar = BallBar(setup).predict(setup.vector(), poses, geometry.euler)[:, 0]
        keep = (bar > shortest) & (bar < longest)
        keep &= check_feasibility(geometry, poses, min_distance or MIN_SINGULARITY_DISTANCE).feasible
        ids = tuple(f"bar{k + 1}" for k in range(int(keep.sum())))
        lines = [
            f"{len(ids)} toybar pose(s) of {len(poses)} with the bar {shortest:g} to {longest:g} mm long"
        ]
        return PlannedMeasurements(poses[keep], ids, lines, "toybar poses")

    def select(
        self, geometry: Geometry, setup: BarSetup, noise: Any = None, fit: str = "joints,l0",
        count: int | None = None, **options: Any,
    ) -> PlannedMeasurements:  # fmt: skip
        found = self.candidates(geometry, setup, **options)
        count = min(30 if count is None else count, len(found.ids))
        rot, pos = pose_frames(found.poses, geometry.euler)
        v = pos + np.einsum("...ij,j->...i", rot, setup.ball) - setup.pivot
        u = v / np.linalg.norm(v, axis=1, keepdims=True)
        chosen = [0]
        for _ in range(count - 1):
            gap = np.min(np.linalg.norm(u[:, None, :] - u[None, chosen, :], axis=2), axis=1)
            chosen.append(int(np.argmax(gap)))
        lines = [f"{count} toybar pose(s) chosen of {len(found.ids)}, the bar's directions spread"]
        data = {"ids": [found.ids[k] for k in chosen], "fit": fit}
        return PlannedMeasurements(
            found.poses[chosen], tuple(found.ids[k] for k in chosen), lines, "toybar", data
        )


#: The ball bar's record, its one registration: model, setup class and the key of its setup
#: files, data class, the column of its data files, their reader and writer, its planner.
TOYBAR = InstrumentKind(
    BallBar.name, BallBar, setup=BarSetup, setup_key="toybar", data=BarMeasurements, columns={"bar": "mm"},
    label="ball-bar lengths", reader=read_bar_file, writer=write_bar_file, planner=BarPlanner(),
)  # fmt: skip


@contextmanager
def registered() -> Iterator[None]:
    """The toy instrument (with its file reader and writer) and the toy leg model registered by
    name, one line each, then removed again."""
    if BallBar.name in MODELS or QuadraticLegs.name in LEG_MODELS:
        raise UsageError("the toy names are taken")
    register_instrument(TOYBAR)
    register_leg_model(QuadraticLegs)
    try:
        yield
    finally:
        unregister_instrument(BallBar.name)
        del LEG_MODELS[QuadraticLegs.name]
