"""The geometry file's YAML mapping: its keys, the pose and box mappings (angles in radians
or, with ``_deg``, degrees) and the checks of the schema (docs/formats.md, "Geometry file").
:class:`hexcal.core.geometry.Geometry` converts through here (``from_dict``, ``to_dict``).
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core.conventions import DEFAULT_EULER, POSE_NAMES
from hexcal.core.covariate_legs import CovariateLegs  # noqa: F401  (registers its kinds by name)
from hexcal.core.legs import leg_model_from_dict
from hexcal.core.stroke_legs import StrokeLegs  # noqa: F401  (registers the stroke model by name)
from hexcal.errors import GeometryError


def short_repr(value: Any, most: int = 60) -> str:
    """``repr`` of a value for a one-line message, cut to ``most`` characters."""
    text = repr(value) if not isinstance(value, BaseException) else str(value)
    text = " ".join(text.split())
    return text if len(text) <= most else text[: most - 3] + "..."


def geometry_kwargs(data: Any) -> dict[str, Any]:
    """The keyword arguments of :class:`~hexcal.core.geometry.Geometry` of a YAML mapping."""
    if not isinstance(data, dict):
        raise GeometryError("geometry must be a mapping of keys to values")
    for key in ("units", "base_joints", "platform_joints", "initial_leg_lengths"):
        if key not in data:
            raise GeometryError(f"missing required key '{key}'")
    if data["units"] != "mm":
        raise GeometryError(f"units must be 'mm' (the only supported unit), got {short_repr(data['units'])}")
    if not isinstance(data.get("name", ""), (str, int, float, type(None))):
        raise GeometryError(f"name must be text, got {short_repr(data['name'])}")
    if not isinstance(data.get("euler", DEFAULT_EULER), str):
        raise GeometryError(f"euler must be a sequence name such as XYZ, got {short_repr(data['euler'])}")
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
        "leg_model",
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
    if data.get("leg_model") is not None:
        kwargs["leg_model"], kwargs["leg_terms"] = leg_model_from_dict(data["leg_model"])
    return kwargs


def geometry_mapping(geometry: Any) -> dict[str, Any]:
    """The YAML mapping of a :class:`~hexcal.core.geometry.Geometry` (angles in degrees; this
    module does not import the class, which imports it)."""
    out: dict[str, Any] = {}
    if geometry.name:
        out["name"] = geometry.name
    out["units"] = "mm"
    out["euler"] = geometry.euler
    out["base_joints"] = geometry.base_joints.tolist()
    out["platform_joints"] = geometry.platform_joints.tolist()
    out["initial_leg_lengths"] = geometry.initial_leg_lengths.tolist()
    out["leg_gains"] = geometry.leg_gains.tolist()
    if geometry.leg_model.terms or geometry.leg_model.settings():  # linear legs: the key is left out
        out["leg_model"] = geometry.leg_model.to_dict(geometry.leg_block())
    if geometry.leg_length_limits is not None:
        out["leg_length_limits"] = geometry.leg_length_limits.tolist()
    if geometry.home_pose is not None:
        out["home_pose"] = _pose_to_mapping(geometry.home_pose)
    if geometry.workspace is not None:
        out["workspace"] = _box_to_mapping(geometry.workspace)
    if geometry.calibration is not None:
        out["calibration"] = copy.deepcopy(geometry.calibration)
    return out


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
            raise GeometryError(f"{where}: '{axis}' must be a number, got {short_repr(value)}") from None
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
            raise GeometryError(f"{where}: '{axis}' must be [low, high], got {short_repr(value)}") from None
        if rng.shape != (2,):
            raise GeometryError(f"{where}: '{axis}' must be [low, high], got {short_repr(value)}")
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
