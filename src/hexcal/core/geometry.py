"""The hexapod geometry: an immutable value object and its named parameters.

The machine's parameters are the joint block ``u1.x u1.y u1.z ... u6.z``,
``s1.x ... s6.z`` and the leg model's block (:mod:`hexcal.core.legs`): ``l0_1 ... l0_6``,
``g1 ... g6`` and the model's own terms (none for the linear model, whose 48 parameters are
the seed paper's; see the user's guide, "Geometry file").
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.conventions import DEFAULT_EULER, N_LEGS, POSE_NAMES, check_euler
from hexcal.core.geometry_mapping import short_repr
from hexcal.core.legs import LegModel, LinearLegs
from hexcal.core.parameters import (
    DEFAULT_FIT,
    JOINT_NAMES,
    N_ALL_PARAMETERS,
    N_BASE_PARAMETERS,
    PARAMETER_GROUPS,
    PARAMETER_NAMES,
    ParameterSet,
)
from hexcal.errors import GeometryError


def _frozen(arr: ArrayLike, shape: tuple[int, ...], what: str) -> NDArray[np.float64]:
    try:
        out = np.array(arr, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise GeometryError(f"{what} must be numeric: {short_repr(exc)}") from None
    if out.shape != shape:
        raise GeometryError(f"{what} must have shape {shape}, got {out.shape}")
    if not np.all(np.isfinite(out)):
        raise GeometryError(f"{what} contains NaN or inf")
    out.flags.writeable = False
    return out


#: Two joints of one frame closer than this (mm) are one joint: refused.
JOINT_SEPARATION = 1e-6


def _positive(values: NDArray[np.float64], what: str, prefix: str) -> None:
    bad = np.flatnonzero(values <= 0)
    if bad.size:
        k = int(bad[0])
        raise GeometryError(f"{what} must be > 0, got {prefix}{k + 1} = {values[k]:g}")


def _distinct(joints: NDArray[np.float64], what: str, prefix: str) -> None:
    gaps = np.linalg.norm(joints[:, None, :] - joints[None, :, :], axis=-1)
    gaps[np.diag_indices(len(joints))] = np.inf
    i, j = np.unravel_index(int(np.argmin(gaps)), gaps.shape)
    if gaps[i, j] < JOINT_SEPARATION:
        i, j = sorted((int(i), int(j)))
        raise GeometryError(
            f"{what}: joints {prefix}{i + 1} and {prefix}{j + 1} coincide ({joints[i].tolist()}); "
            "every leg needs its own joint"
        )


#: Joints of one frame all within this fraction of their spread from one line are collinear:
#: refused (such a frame turns about that line with no leg length changing).
COLLINEAR_TOLERANCE = 1e-6


def _not_collinear(joints: NDArray[np.float64], what: str) -> None:
    centred = joints - joints.mean(axis=0)
    spread = float(np.linalg.norm(centred, axis=1).max())
    direction = np.linalg.svd(centred)[2][0]
    off_line = float(np.linalg.norm(centred - np.outer(centred @ direction, direction), axis=1).max())
    if off_line <= COLLINEAR_TOLERANCE * max(1.0, spread):
        frame = "platform" if what.startswith("platform") else "base"
        raise GeometryError(
            f"{what}: the six joints lie on one line; a {frame} whose joints are collinear turns "
            "about that line with no leg length changing, so no pose of this machine can be solved"
        )


#: Largest angle of a workspace range, rad: the angles of a pose are defined within ±180°.
MAX_WORKSPACE_ANGLE = np.pi * (1 + 1e-12)


def _angle_ranges(box: NDArray[np.float64]) -> None:
    bad = np.flatnonzero(np.abs(box[3:]).max(axis=1) > MAX_WORKSPACE_ANGLE)
    if bad.size:
        k = int(bad[0]) + 3
        lo, hi = np.rad2deg(box[k])
        raise GeometryError(
            f"workspace: {POSE_NAMES[k]} ranges over [{lo:.6g}, {hi:.6g}] degrees, beyond ±180 degrees; "
            "give angle ranges within [-180, 180] degrees"
        )


@dataclass(frozen=True, eq=False)
class Geometry:
    """Kinematic geometry of a 6-6 hexapod.

    Parameters
    ----------
    base_joints : array_like, shape (6, 3)
        Base joint centres ``u_i`` in the base frame, mm.
    platform_joints : array_like, shape (6, 3)
        Platform joint centres ``s_i`` in the platform frame, mm.
    initial_leg_lengths : array_like, shape (6,)
        ``l0_i``, mm: leg length at reading ``dl_i = 0``.
    leg_gains : array_like, shape (6,), optional
        ``g_i``: leg length is ``l0_i + g_i * dl_i``. Default all 1.
    leg_length_limits : array_like, shape (2,), optional
        ``[min, max]`` absolute leg length, mm.
    home_pose : array_like, shape (6,), optional
        Pose ``(x, y, z, a, b, c)``, mm and rad.
    workspace : array_like, shape (6, 2), optional
        Box ``[low, high]`` per pose coordinate, mm and rad.
    euler : str
        scipy Euler sequence of the pose angles.
    name : str
    calibration : dict, optional
        Metadata of the identification that produced this geometry.
    leg_model : LegModel, optional
        How a reading becomes a length (:mod:`hexcal.core.legs`); default linear,
        ``l0_i + g_i dl_i``.
    leg_terms : array_like, shape (6, k), optional
        The leg model's own per-leg terms beyond ``l0`` and the gain (none for linear).
    """

    base_joints: NDArray[np.float64]
    platform_joints: NDArray[np.float64]
    initial_leg_lengths: NDArray[np.float64]
    leg_gains: NDArray[np.float64] = field(default_factory=lambda: np.ones(N_LEGS))
    leg_length_limits: NDArray[np.float64] | None = None
    home_pose: NDArray[np.float64] | None = None
    workspace: NDArray[np.float64] | None = None
    euler: str = DEFAULT_EULER
    name: str = ""
    calibration: dict[str, Any] | None = None
    leg_model: LegModel = field(default_factory=LinearLegs)
    leg_terms: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        put = object.__setattr__
        if not isinstance(self.leg_model, LegModel):
            raise GeometryError(f"leg_model must be a LegModel, got {type(self.leg_model).__name__}")
        n_terms = len(self.leg_model.terms)
        terms = np.zeros((N_LEGS, n_terms)) if self.leg_terms is None else self.leg_terms
        put(self, "leg_terms", _frozen(terms, (N_LEGS, n_terms), "leg_terms"))
        put(self, "base_joints", _frozen(self.base_joints, (6, 3), "base_joints"))
        put(self, "platform_joints", _frozen(self.platform_joints, (6, 3), "platform_joints"))
        put(
            self,
            "initial_leg_lengths",
            _frozen(self.initial_leg_lengths, (6,), "initial_leg_lengths"),
        )
        put(self, "leg_gains", _frozen(self.leg_gains, (6,), "leg_gains"))
        _positive(self.initial_leg_lengths, "initial_leg_lengths", "l0_")
        _positive(self.leg_gains, "leg_gains", "g")
        if self.leg_length_limits is not None:
            lim = _frozen(self.leg_length_limits, (2,), "leg_length_limits")
            if not 0 < lim[0] < lim[1]:
                raise GeometryError(
                    f"leg_length_limits must be [min, max] with 0 < min < max, got {lim.tolist()}"
                )
            put(self, "leg_length_limits", lim)
        if self.workspace is not None:
            box = _frozen(self.workspace, (6, 2), "workspace")
            if np.any(box[:, 0] > box[:, 1]):
                raise GeometryError("workspace ranges must be [low, high] with low <= high")
            _angle_ranges(box)
            put(self, "workspace", box)
        if self.calibration is not None:
            put(self, "calibration", copy.deepcopy(dict(self.calibration)))
        try:
            check_euler(self.euler)
        except ValueError as exc:
            raise GeometryError(str(exc)) from None
        if self.home_pose is not None:
            put(self, "home_pose", _frozen(self.home_pose, (6,), "home_pose"))

    def check_plausible(self) -> None:
        """Refuse a geometry that no machine can have (:class:`GeometryError`, one line).

        Beyond the checks of construction (finite values, shapes, positive gains and initial
        lengths, ``0 < min < max`` leg limits, ordered workspace with angle ranges within
        ±180°): every joint distinct from the other joints of its frame (within
        :data:`JOINT_SEPARATION`), the joints of each frame not all on one line (within
        :data:`COLLINEAR_TOLERANCE` of their spread), and the home pose
        inside the workspace box and within the leg length limits. Applied to every geometry
        file that hexcal loads; not at construction, where intermediate or synthetic
        geometries (tests, Monte Carlo draws) may legitimately break them.

        >>> from hexcal.core.presets import preset
        >>> preset("paper-hmt").check_plausible()
        """
        _distinct(self.base_joints, "base_joints", "u")
        _distinct(self.platform_joints, "platform_joints", "s")
        _not_collinear(self.base_joints, "base_joints")
        _not_collinear(self.platform_joints, "platform_joints")
        home = self.home_pose
        if home is None:
            return
        if self.workspace is not None:
            tol = 1e-9 * np.maximum(1.0, np.abs(self.workspace).max(axis=1))
            out = np.flatnonzero((home < self.workspace[:, 0] - tol) | (home > self.workspace[:, 1] + tol))
            if out.size:
                k = int(out[0])
                # the file's units: mm, and degrees for the angles (a_deg, b_deg, c_deg)
                scale, name, unit = (
                    (1.0, POSE_NAMES[k], "mm") if k < 3 else (180 / np.pi, f"{POSE_NAMES[k]}_deg", "deg")
                )
                raise GeometryError(
                    f"home_pose: {name} = {home[k] * scale:g} {unit} is outside the workspace "
                    f"[{self.workspace[k, 0] * scale:g}, {self.workspace[k, 1] * scale:g}] {unit}"
                )
        if self.leg_length_limits is not None:
            from scipy.spatial.transform import Rotation  # deferred: slow to import

            rot = Rotation.from_euler(self.euler, home[3:]).as_matrix()
            lengths = np.linalg.norm(home[:3] + self.platform_joints @ rot.T - self.base_joints, axis=1)
            lo, hi = self.leg_length_limits
            tol = 1e-6 * hi
            bad = np.flatnonzero((lengths < lo - tol) | (lengths > hi + tol))
            if bad.size:
                k = int(bad[0])
                raise GeometryError(
                    f"home_pose: leg {k + 1} would be {lengths[k]:.6g} mm long, outside "
                    f"leg_length_limits [{lo:g}, {hi:g}]"
                )

    # -- parameter vector -------------------------------------------------
    def to_vector(self, gains: bool = False) -> NDArray[np.float64]:
        """Parameter vector in the order of :data:`PARAMETER_NAMES` (42, or 48 with gains)."""
        parts = [
            self.base_joints.ravel(),
            self.platform_joints.ravel(),
            self.initial_leg_lengths,
        ]
        if gains:
            parts.append(self.leg_gains)
        return np.concatenate(parts)

    def with_vector(self, vector: ArrayLike) -> Geometry:
        """Copy with kinematic parameters from a 42- or 48-vector (gains kept if 42)."""
        vec = np.asarray(vector, dtype=float)
        if vec.shape not in ((N_BASE_PARAMETERS,), (N_ALL_PARAMETERS,)):
            raise ValueError(f"parameter vector must have shape (42,) or (48,), got {vec.shape}")
        changes: dict[str, Any] = dict(
            base_joints=vec[:18].reshape(6, 3),
            platform_joints=vec[18:36].reshape(6, 3),
            initial_leg_lengths=vec[36:42],
        )
        if vec.shape[0] == N_ALL_PARAMETERS:
            changes["leg_gains"] = vec[42:48]
        return dataclasses.replace(self, **changes)

    def parameters(self, gains: bool = False) -> dict[str, float]:
        """Named parameters, ``{"u1.x": ..., ...}``."""
        vec = self.to_vector(gains)
        return {n: float(v) for n, v in zip(PARAMETER_NAMES, vec, strict=False)}

    # -- named blocks: joints and the leg model ------------------------------
    def leg_block(self) -> NDArray[np.float64]:
        """The leg model's parameter values: ``l0``, gains, then the model's terms."""
        return np.concatenate([self.initial_leg_lengths, self.leg_gains, self.leg_terms.T.ravel()])

    def with_leg_block(self, block: ArrayLike) -> Geometry:
        """Copy with the leg model's parameters from a block (order of :meth:`leg_block`)."""
        block = np.asarray(block, dtype=float)
        if block.shape != (self.leg_model.size,):
            raise ValueError(f"leg block must have shape ({self.leg_model.size},), got {block.shape}")
        terms = block[12:].reshape(-1, N_LEGS).T
        return dataclasses.replace(
            self, initial_leg_lengths=block[:6], leg_gains=block[6:12], leg_terms=terms
        )

    def joint_block(self) -> NDArray[np.float64]:
        """The joint coordinates: base joints, then platform joints (36 values)."""
        return np.concatenate([self.base_joints.ravel(), self.platform_joints.ravel()])

    def machine_names(self) -> tuple[str, ...]:
        """Names of the machine's parameters: the joints, then the leg model's block."""
        return JOINT_NAMES + self.leg_model.names()

    def machine_vector(self) -> NDArray[np.float64]:
        """Values of :meth:`machine_names` (48 for linear legs: ``to_vector(gains=True)``)."""
        return np.concatenate([self.joint_block(), self.leg_block()])

    def with_machine_vector(self, vector: ArrayLike) -> Geometry:
        """Copy with the machine's parameters from a vector in the order of :meth:`machine_names`."""
        vec = np.asarray(vector, dtype=float)
        n = len(JOINT_NAMES) + self.leg_model.size
        if vec.shape != (n,):
            raise ValueError(f"machine vector must have shape ({n},), got {vec.shape}")
        joints = dataclasses.replace(
            self, base_joints=vec[:18].reshape(6, 3), platform_joints=vec[18:36].reshape(6, 3)
        )
        return joints.with_leg_block(vec[36:])

    def machine_parameters(self, fit: str | Any = DEFAULT_FIT, fix: Any = ()) -> ParameterSet:
        """The machine's :class:`ParameterSet`: blocks ``joints`` and ``legs``, the groups
        ``joints, base, platform`` and the leg model's (``l0, gains, ...``), varied by the
        groups of ``fit`` less the names in ``fix``; units mm, the gains 1, the leg model's
        terms its own (:meth:`hexcal.core.legs.LegModel.units`)."""
        legs = self.leg_model
        groups = {k: PARAMETER_GROUPS[k] for k in ("joints", "base", "platform")} | legs.groups()
        scales = np.concatenate([np.ones(len(JOINT_NAMES)), legs.scales(self.leg_block())])
        n = len(JOINT_NAMES) + legs.size
        blocks = {"joints": (0, len(JOINT_NAMES)), "legs": (len(JOINT_NAMES), n)}
        units = ("mm",) * len(JOINT_NAMES) + legs.units()
        full = ParameterSet(
            self.machine_names(), self.machine_vector(), np.zeros(n, bool), scales, groups, blocks, units
        )
        return full.select(fit, fix)

    def replace(self, **changes: Any) -> Geometry:
        """Copy with some fields changed (``dataclasses.replace``)."""
        return dataclasses.replace(self, **changes)

    # -- dict / YAML form (hexcal.core.geometry_mapping) ----------------------
    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Geometry:
        """Build from the geometry file's YAML mapping (validated; docs/formats.md)."""
        from hexcal.core.geometry_mapping import geometry_kwargs

        return cls(**geometry_kwargs(data))

    def to_dict(self) -> dict[str, Any]:
        """The geometry file's YAML mapping (angles written in degrees; docs/formats.md)."""
        from hexcal.core.geometry_mapping import geometry_mapping

        return geometry_mapping(self)
