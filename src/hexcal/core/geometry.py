"""The hexapod geometry: an immutable value object and its named parameter vector.

Parameter order and names follow FORMATS.md: ``u1.x u1.y u1.z ... u6.z``,
``s1.x ... s6.z``, ``l0_1 ... l0_6`` and, optionally, ``g1 ... g6``.
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.conventions import DEFAULT_EULER, N_LEGS, POSE_NAMES, check_euler
from hexcal.core.parameters import N_ALL_PARAMETERS, N_BASE_PARAMETERS, PARAMETER_NAMES
from hexcal.errors import GeometryError


def _frozen(arr: ArrayLike, shape: tuple[int, ...], what: str) -> NDArray[np.float64]:
    try:
        out = np.array(arr, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise GeometryError(f"{what} must be numeric: {_short(exc)}") from None
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

    def __post_init__(self) -> None:
        put = object.__setattr__
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
                raise GeometryError(
                    f"home_pose: {POSE_NAMES[k]} = {home[k]:g} is outside the workspace "
                    f"[{self.workspace[k, 0]:g}, {self.workspace[k, 1]:g}]"
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

    def replace(self, **changes: Any) -> Geometry:
        """Copy with some fields changed (``dataclasses.replace``)."""
        return dataclasses.replace(self, **changes)

    # -- dict / YAML form --------------------------------------------------
    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Geometry:
        """Build from the YAML mapping of FORMATS.md (validated)."""
        if not isinstance(data, dict):
            raise GeometryError("geometry must be a mapping of keys to values")
        for key in ("units", "base_joints", "platform_joints", "initial_leg_lengths"):
            if key not in data:
                raise GeometryError(f"missing required key '{key}'")
        if data["units"] != "mm":
            raise GeometryError(f"units must be 'mm' (the only supported unit), got {_short(data['units'])}")
        if not isinstance(data.get("name", ""), (str, int, float, type(None))):
            raise GeometryError(f"name must be text, got {_short(data['name'])}")
        if not isinstance(data.get("euler", DEFAULT_EULER), str):
            raise GeometryError(f"euler must be a sequence name such as XYZ, got {_short(data['euler'])}")
        known = {
            "name",
            "units",
            "euler",
            "base_joints",
            "platform_joints",
            "initial_leg_lengths",
            "leg_gains",
            "leg_length_limits",
            "home_pose",
            "workspace",
            "calibration",
        }
        unknown = sorted(map(repr_key, set(data) - known))
        if unknown:
            raise GeometryError(f"unknown key(s): {', '.join(unknown)}")
        kwargs: dict[str, Any] = dict(
            base_joints=data["base_joints"],
            platform_joints=data["platform_joints"],
            initial_leg_lengths=data["initial_leg_lengths"],
            euler=data.get("euler", DEFAULT_EULER),
            name=str(data.get("name", "") or ""),
        )
        if data.get("leg_gains") is not None:
            kwargs["leg_gains"] = data["leg_gains"]
        if data.get("leg_length_limits") is not None:
            kwargs["leg_length_limits"] = data["leg_length_limits"]
        if data.get("home_pose") is not None:
            kwargs["home_pose"] = _pose_from_mapping(data["home_pose"], "home_pose")
        if data.get("workspace") is not None:
            kwargs["workspace"] = _box_from_mapping(data["workspace"])
        if data.get("calibration") is not None:
            if not isinstance(data["calibration"], dict):
                raise GeometryError("calibration must be a mapping")
            kwargs["calibration"] = data["calibration"]
        return cls(**kwargs)

    def to_dict(self) -> dict[str, Any]:
        """The YAML mapping of FORMATS.md (angles written in degrees)."""
        out: dict[str, Any] = {}
        if self.name:
            out["name"] = self.name
        out["units"] = "mm"
        out["euler"] = self.euler
        out["base_joints"] = self.base_joints.tolist()
        out["platform_joints"] = self.platform_joints.tolist()
        out["initial_leg_lengths"] = self.initial_leg_lengths.tolist()
        out["leg_gains"] = self.leg_gains.tolist()
        if self.leg_length_limits is not None:
            out["leg_length_limits"] = self.leg_length_limits.tolist()
        if self.home_pose is not None:
            out["home_pose"] = _pose_to_mapping(self.home_pose)
        if self.workspace is not None:
            out["workspace"] = _box_to_mapping(self.workspace)
        if self.calibration is not None:
            out["calibration"] = copy.deepcopy(self.calibration)
        return out


def _short(value: Any, most: int = 60) -> str:
    """``repr`` of a value for a one-line message, cut to ``most`` characters."""
    text = repr(value) if not isinstance(value, BaseException) else str(value)
    text = " ".join(text.split())
    return text if len(text) <= most else text[: most - 3] + "..."


def repr_key(key: Any) -> str:
    """A mapping key for a message: strings as they are, other keys (numbers...) as repr."""
    return key if isinstance(key, str) else repr(key)


def _angle_key(mapping: dict[str, Any], axis: str, where: str) -> tuple[Any, bool]:
    """Value of angle ``axis`` and whether it was given in degrees."""
    has_rad, has_deg = axis in mapping, f"{axis}_deg" in mapping
    if has_rad and has_deg:
        raise GeometryError(f"{where}: give '{axis}' or '{axis}_deg', not both")
    if has_deg:
        return mapping[f"{axis}_deg"], True
    if has_rad:
        return mapping[axis], False
    raise GeometryError(f"{where}: missing key '{axis}' (rad) or '{axis}_deg'")


_POSE_KEYS = {"x", "y", "z", "a", "b", "c", "a_deg", "b_deg", "c_deg"}


def _coordinates(mapping: Any, where: str, expected: str) -> list[tuple[str, Any, bool]]:
    """``(axis, value, in_degrees)`` of the six pose coordinates of a YAML mapping."""
    if not isinstance(mapping, dict):
        raise GeometryError(f"{where} must be a mapping {expected}")
    extra = sorted(map(repr_key, set(mapping) - _POSE_KEYS))
    if extra:
        raise GeometryError(f"{where}: unknown key(s) {', '.join(extra)}")
    out = []
    for axis in POSE_NAMES:
        if axis in "xyz":
            if axis not in mapping:
                raise GeometryError(f"{where}: missing key '{axis}'")
            out.append((axis, mapping[axis], False))
        else:
            out.append((axis, *_angle_key(mapping, axis, where)))
    return out


def _pose_from_mapping(mapping: Any, where: str) -> NDArray[np.float64]:
    pose = np.empty(6)
    expected = "with keys x, y, z, a|a_deg, b|b_deg, c|c_deg"
    for k, (axis, value, deg) in enumerate(_coordinates(mapping, where, expected)):
        try:
            v = float(value)
        except (TypeError, ValueError, OverflowError):
            raise GeometryError(f"{where}: '{axis}' must be a number, got {_short(value)}") from None
        pose[k] = np.deg2rad(v) if deg else v
    return pose


def _box_from_mapping(mapping: Any) -> NDArray[np.float64]:
    where = "workspace"
    box = np.empty((6, 2))
    coordinates = _coordinates(mapping, where, "of pose coordinates to [low, high]")
    for k, (axis, value, deg) in enumerate(coordinates):
        try:
            rng = np.array(value, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise GeometryError(f"{where}: '{axis}' must be [low, high], got {_short(value)}") from None
        if rng.shape != (2,):
            raise GeometryError(f"{where}: '{axis}' must be [low, high], got {_short(value)}")
        box[k] = np.deg2rad(rng) if deg else rng
    return box


def _deg(value: float) -> float:
    return float(np.round(np.rad2deg(value), 12))


def _pose_to_mapping(pose: NDArray[np.float64]) -> dict[str, float]:
    out = {axis: float(pose[k]) for k, axis in enumerate("xyz")}
    out.update({f"{axis}_deg": _deg(pose[k + 3]) for k, axis in enumerate("abc")})
    return out


def _box_to_mapping(box: NDArray[np.float64]) -> dict[str, list[float]]:
    out = {axis: box[k].tolist() for k, axis in enumerate("xyz")}
    out.update({f"{axis}_deg": [_deg(v) for v in box[k + 3]] for k, axis in enumerate("abc")})
    return out
