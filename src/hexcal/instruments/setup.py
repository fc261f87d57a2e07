"""The instrument setup: where the instrument stands and what it sees on the platform.

A :class:`Setup` holds the instrument frame (the base frame's pose in the instrument frame,
docs/formats.md "Setup file", or ``None`` for ``auto``), the targets on the platform
(position instruments: laser-tracker SMRs) or the tool frame (pose instruments: 6-DOF probes,
cameras), and which of them are ``fixed``. Its parameters, appended after the machine's 48,
are ``frame.x frame.y frame.z frame.a frame.b frame.c``, then ``t1.x t1.y t1.z ...`` or
``tool.x ... tool.c``, in the groups ``frame``, ``targets`` and ``tool`` (so ``--fit`` and
``--fix`` accept them). Lengths mm (scale 1 mm), angles rad (scale 1 mrad: a milliradian
moves a point a metre away by a millimetre).

Transform convention: a base-frame point ``p`` has instrument coordinates ``R_F p + t_F``;
a target ``q`` at platform pose ``(o, R_P)`` is measured at ``R_F (o + R_P q) + t_F``.

>>> setup = Setup.from_dict({"units": "mm", "instrument_frame": "auto",
...                          "targets": {"t1": [0, 0, 60]}})
>>> setup.kind, setup.target_names, setup.parameters("XYZ").names[:3]
('targets', ('t1',), ('frame.x', 'frame.y', 'frame.z'))
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.conventions import POSE_NAMES, check_euler, rotation_matrices, rotations_of
from hexcal.core.parameters import ParameterSet
from hexcal.errors import InputError
from hexcal.instruments.known_noise import Device, declared_noise, device_for, noise_mapping

#: Setup quantities that ``fixed`` may name.
FIXABLE = ("instrument_frame", "targets", "tool")
#: Keys a setup mapping may have.
SETUP_KEYS = (
    "units",
    "euler",
    "instrument",
    "instrument_frame",
    "targets",
    "tool",
    "fixed",
    "noise",
    "columns",
    "calibration",
)
#: Solver scale of a setup angle (rad).
ANGLE_SCALE = 1e-3
TARGET_NAME = re.compile(r"^t[1-9][0-9]*$")
#: Targets a setup file may hold (a tracker follows a few; the limit bounds the work of a file).
MAX_TARGETS = 64
#: Two targets closer than this (mm) are one point: a setup file naming both is refused.
TARGET_SEPARATION = 1e-6


def _distinct_targets(targets: dict[Any, Any]) -> None:
    """Refuse two targets of a setup file at one point (:class:`InputError`, naming both)."""
    names = list(targets)
    points = np.array([targets[n] for n in names], dtype=float)
    gaps = np.linalg.norm(points[:, None, :] - points[None, :, :], axis=2)
    close = np.argwhere(np.triu(gaps <= TARGET_SEPARATION, k=1))
    if close.size:
        i, j = close[0]
        raise InputError(
            f"targets {names[i]} and {names[j]} are at one point {points[i].tolist()} (mm); "
            "each target is a distinct point of the platform"
        )


FRAME_NAMES = tuple(f"frame.{k}" for k in POSE_NAMES)
TOOL_NAMES = tuple(f"tool.{k}" for k in POSE_NAMES)
POSE_SCALES = np.array([1.0, 1.0, 1.0, ANGLE_SCALE, ANGLE_SCALE, ANGLE_SCALE])
#: Units of a frame's or a tool's six quantities: a position in mm, angles in rad.
POSE_UNITS = ("mm", "mm", "mm", "rad", "rad", "rad")


def _pose(value: Any, where: str) -> NDArray[np.float64]:
    """A pose mapping ``{x, y, z, a|a_deg, b|b_deg, c|c_deg}`` as mm and rad."""
    if not isinstance(value, dict):
        raise InputError(f"{where} must be a mapping x, y, z, a_deg, b_deg, c_deg (or a, b, c in rad)")
    allowed = set("xyzabc") | {"a_deg", "b_deg", "c_deg"}
    unknown = sorted(set(map(str, value)) - allowed)
    if unknown:
        raise InputError(
            f"{where}: unknown key {unknown[0]!r} (keys: x, y, z, a_deg, b_deg, c_deg or a, b, c)"
        )
    out = np.zeros(6)
    for k, name in enumerate("xyzabc"):
        deg = f"{name}_deg" if k >= 3 else None
        if deg is not None and name in value and deg in value:
            raise InputError(f"{where}: both {name} and {deg}; give one")
        key = deg if deg is not None and deg in value else name
        if key not in value:
            raise InputError(f"{where}: missing {name if k < 3 else deg}")
        number = _number(value[key], f"{where}.{key}")
        out[k] = np.deg2rad(number) if key.endswith("_deg") else number
    return out


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
        raise InputError(f"{where}: not a finite number: {value!r}")
    return float(value)


def _columns(value: Any) -> dict[str, str]:
    """A setup's ``columns`` mapping (hexcal name -> file column), its form checked here (the
    names against hexcal's columns when read from a file, :func:`hexcal.io.load_setup`)."""
    if not isinstance(value, dict) or not value:
        raise InputError(
            "columns must be a mapping of hexcal names to file columns, e.g. {dl1: leg_length_1}"
        )
    for ours, theirs in value.items():
        if not isinstance(ours, str) or not isinstance(theirs, str) or not theirs.strip():
            raise InputError(f"columns.{ours}: must name a file column (text), got {theirs!r}")
    return {ours: theirs.strip() for ours, theirs in value.items()}


def _pose_mapping(pose: NDArray[np.float64]) -> dict[str, float]:
    keys = ("x", "y", "z", "a_deg", "b_deg", "c_deg")
    values = list(pose[:3]) + list(np.rad2deg(pose[3:]))
    return {k: float(v) for k, v in zip(keys, values, strict=True)}


@dataclass(frozen=True, eq=False)
class Setup:
    """An instrument setup (docs/formats.md "Setup file").

    Parameters
    ----------
    frame : array_like, shape (6,), or None
        The base frame's pose in the instrument frame (mm, rad); ``None`` for ``auto``.
    targets : mapping of str to array_like (3,), optional
        Target positions on the platform (platform frame, mm), by name ``t1, t2, ...``.
    tool : array_like, shape (6,), optional
        The measured frame's pose in the platform frame (mm, rad).
    fixed : sequence of str
        Quantities held exactly: any of ``instrument_frame``, ``targets``, ``tool``.
    euler : str, optional
        Euler sequence of the setup's angles (default: the geometry's).
    calibration : mapping, optional
        Standard errors of a calibrated setup.
    columns : mapping of str to str, optional
        How the instrument's data files name their columns: hexcal's name -> the file's
        (``{"dl1": "leg_length_1", "qw": "orientation_w"}``); kept by a calibrated setup.
    noise : mapping of str to float, optional
        The instrument's own noise as declared, one σ by noise group (``position`` mm,
        ``orientation`` rad): what the verdict holds the learned noise against.
    instrument : str, optional
        The kind of instrument (:data:`hexcal.instruments.known_noise.DEVICES`:
        ``laser-tracker``, ``6dof-tracker``, ``motion-capture``); default by the setup's kind.
    """

    frame: NDArray[np.float64] | None = None
    targets: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    tool: NDArray[np.float64] | None = None
    fixed: tuple[str, ...] = ()
    euler: str | None = None
    calibration: dict[str, Any] | None = None
    columns: dict[str, str] | None = None
    noise: dict[str, float] | None = None
    instrument: str | None = None

    def __post_init__(self) -> None:
        if self.targets and self.tool is not None:
            raise InputError(
                "a setup has targets (position instrument) or a tool (pose instrument), not both"
            )
        if not self.targets and self.tool is None:
            raise InputError("a setup needs targets (position instrument) or a tool (pose instrument)")
        targets = {}
        for name, value in self.targets.items():
            if not TARGET_NAME.match(str(name)):
                raise InputError(f"target name {name!r}: names are t followed by a number (t1, t2, ...)")
            arr = np.array(value, dtype=float)
            if arr.shape != (3,) or not np.all(np.isfinite(arr)):
                raise InputError(f"target {name}: must be three finite numbers [x, y, z] (mm)")
            targets[str(name)] = arr
        object.__setattr__(self, "targets", targets)
        for what in ("frame", "tool"):
            value = getattr(self, what)
            if value is not None:
                arr = np.array(value, dtype=float)
                if arr.shape != (6,) or not np.all(np.isfinite(arr)):
                    raise InputError(f"{what} must be a finite pose of 6 values")
                object.__setattr__(self, what, arr)
        fixed = tuple(self.fixed)
        for name in fixed:
            if name not in FIXABLE:
                raise InputError(f"fixed: unknown quantity {name!r}; choose from {', '.join(FIXABLE)}")
        if ("targets" in fixed and not self.targets) or ("tool" in fixed and self.tool is None):
            raise InputError(f"fixed: the setup has no {'targets' if 'targets' in fixed else 'tool'}")
        object.__setattr__(self, "fixed", fixed)
        if self.columns is not None:
            object.__setattr__(self, "columns", _columns(self.columns))
        device_for(self.kind, self.instrument)  # refuses a kind that does not measure this setup
        if self.noise is not None:
            allowed = {"position"} if self.kind == "targets" else {"position", "orientation"}
            if not set(self.noise) <= allowed or not all(v > 0 for v in self.noise.values()):
                raise InputError(f"noise: a {self.kind} setup declares {', '.join(sorted(allowed))} (σ > 0)")
            object.__setattr__(self, "noise", {k: float(v) for k, v in self.noise.items()})
        if self.euler is not None:
            try:
                check_euler(self.euler)
            except ValueError as exc:
                raise InputError(f"euler: {exc}") from None

    # -- description --------------------------------------------------------------------
    @property
    def kind(self) -> str:
        """``"targets"`` (position instrument) or ``"tool"`` (pose instrument)."""
        return "targets" if self.targets else "tool"

    @property
    def frame_state(self) -> str:
        """How the instrument frame enters a calibration: ``auto`` (registered from the data,
        then identified), ``fixed`` (held as given) or ``free`` (identified from the value given)."""
        if self.frame is None:
            return "auto"
        return "fixed" if "instrument_frame" in self.fixed else "free"

    @property
    def auto(self) -> bool:
        """Whether the instrument frame is to be registered from the data."""
        return self.frame is None

    @property
    def target_names(self) -> tuple[str, ...]:
        return tuple(self.targets)

    @property
    def target_array(self) -> NDArray[np.float64]:
        """Target positions ``(n, 3)``, mm, platform frame."""
        return np.array([self.targets[n] for n in self.target_names]).reshape(-1, 3)

    @property
    def device(self) -> Device:
        """The kind of instrument (named by ``instrument``, else by the setup's kind) and the
        noise such instruments have."""
        return device_for(self.kind, self.instrument)

    def frame_or_identity(self) -> NDArray[np.float64]:
        return np.zeros(6) if self.frame is None else np.array(self.frame)

    # -- parameters ---------------------------------------------------------------------
    def names(self) -> tuple[str, ...]:
        """Parameter names of the setup (frame first)."""
        if self.kind == "targets":
            return FRAME_NAMES + tuple(f"{t}.{ax}" for t in self.target_names for ax in "xyz")
        return FRAME_NAMES + TOOL_NAMES

    def vector(self) -> NDArray[np.float64]:
        """The setup's parameter values (frame, then targets or tool); frame 0 when ``auto``."""
        rest = self.target_array.ravel() if self.kind == "targets" else self.tool
        return np.concatenate([self.frame_or_identity(), rest])

    def parameters(self, euler: str | None = None) -> ParameterSet:
        """The setup's :class:`ParameterSet`: groups ``frame``, ``targets`` / ``tool`` (positions
        in mm, angles in rad); the quantities in ``fixed`` are not varied. ``euler`` is only
        checked."""
        names = self.names()
        n_rest = len(names) - 6
        scales = np.concatenate([POSE_SCALES, np.ones(n_rest) if self.kind == "targets" else POSE_SCALES])
        vary = np.ones(len(names), dtype=bool)
        if "instrument_frame" in self.fixed:
            vary[:6] = False
        if self.kind in self.fixed:
            vary[6:] = False
        groups = {"frame": names[:6], self.kind: names[6:]}
        blocks = {"frame": (0, 6), self.kind: (6, len(names))}
        units = POSE_UNITS + (("mm",) * n_rest if self.kind == "targets" else POSE_UNITS)
        return ParameterSet(names, self.vector(), vary, scales, groups, blocks, units)

    def with_vector(self, values: ArrayLike, calibration: dict[str, Any] | None = None) -> Setup:
        """The setup with parameter values ``values`` (order of :meth:`names`)."""
        values = np.asarray(values, dtype=float)
        if values.shape != (len(self.names()),):
            raise InputError(f"setup values must have shape ({len(self.names())},), got {values.shape}")
        if self.kind == "targets":
            targets = dict(zip(self.target_names, values[6:].reshape(-1, 3), strict=True))
            return replace(self, frame=values[:6], targets=targets, calibration=calibration)
        return replace(self, frame=values[:6], tool=values[6:], calibration=calibration)

    def in_euler(self, euler: str) -> Setup:
        """The same setup with its angles in the Euler sequence ``euler`` (the geometry's):
        a setup file's own ``euler`` is converted, one without keeps its angles."""
        if self.euler is None or self.euler == euler:
            return replace(self, euler=euler) if self.euler is None else self
        changes: dict[str, Any] = {"euler": euler}
        for what in ("frame", "tool"):
            pose = getattr(self, what)
            if pose is not None:
                angles = matrix_to_euler(rotation_matrices(pose[3:], self.euler), euler, orthonormal=True)
                changes[what] = np.concatenate([pose[:3], angles])
        return replace(self, **changes)

    # -- files --------------------------------------------------------------------------
    @classmethod
    def from_dict(cls, data: Any) -> Setup:
        """A setup from its YAML mapping; one :class:`InputError` line per problem."""
        if not isinstance(data, dict):
            raise InputError("a setup file must be a mapping (units, instrument_frame, targets or tool)")
        unknown = [k for k in data if k not in SETUP_KEYS]
        if unknown:
            raise InputError(f"unknown key {unknown[0]!r}; a setup has {', '.join(SETUP_KEYS)}")
        if "units" not in data:
            raise InputError("missing units (write 'units: mm')")
        if data["units"] != "mm":
            raise InputError(f"units: only mm is supported, got {data['units']!r}")
        if "instrument_frame" not in data:
            raise InputError("missing instrument_frame (a pose mapping, or the word auto)")
        frame_spec = data["instrument_frame"]
        frame = None if frame_spec == "auto" else _pose(frame_spec, "instrument_frame")
        targets = data.get("targets")
        if targets is not None:
            if not isinstance(targets, dict) or not targets:
                raise InputError("targets must be a non-empty mapping like {t1: [x, y, z]}")
            if len(targets) > MAX_TARGETS:
                raise InputError(f"targets: {len(targets):,} targets, over the limit of {MAX_TARGETS}")
            for name, value in targets.items():
                if not isinstance(value, list | tuple) or len(value) != 3:
                    raise InputError(f"targets.{name}: must be a list [x, y, z] (mm)")
                for k, v in enumerate(value):
                    _number(v, f"targets.{name}[{k}]")
            _distinct_targets(targets)
        tool = data.get("tool")
        if tool is not None:
            if targets is not None:
                raise InputError(
                    "a setup has targets (position instrument) or a tool (pose instrument), not both"
                )
            tool = _pose(tool, "tool")
        fixed = data.get("fixed", [])
        if isinstance(fixed, str):
            fixed = [fixed]
        if not isinstance(fixed, list) or not all(isinstance(f, str) for f in fixed):
            raise InputError("fixed must be a list of instrument_frame, targets, tool")
        euler = data.get("euler")
        if euler is not None and not isinstance(euler, str):
            raise InputError(f"euler: must be a sequence like XYZ, got {euler!r}")
        calibration = data.get("calibration")
        if calibration is not None and not isinstance(calibration, dict):
            raise InputError("calibration must be a mapping")
        columns = _columns(data["columns"]) if "columns" in data else None
        kind = "targets" if targets is not None else "tool"
        instrument = data.get("instrument")
        if instrument is not None:
            device_for(kind, instrument if isinstance(instrument, str) else repr(instrument))
        noise = declared_noise(data["noise"], kind, instrument) if "noise" in data else None
        return cls(
            frame, dict(targets or {}), tool, tuple(fixed), euler, calibration, columns, noise, instrument
        )

    def to_dict(self) -> dict[str, Any]:
        """The YAML mapping (docs/formats.md "Setup file"): angles in degrees, ``auto`` for an
        unknown frame."""
        out: dict[str, Any] = {"units": "mm"}
        if self.euler is not None:
            out["euler"] = self.euler
        out["instrument_frame"] = "auto" if self.frame is None else _pose_mapping(self.frame)
        if self.kind == "targets":
            out["targets"] = {n: [float(v) for v in self.targets[n]] for n in self.target_names}
        else:
            out["tool"] = _pose_mapping(self.tool)
        if self.fixed:
            out["fixed"] = list(self.fixed)
        if self.instrument is not None:
            out["instrument"] = self.instrument
        if self.noise:
            out["noise"] = noise_mapping(self.noise, self.kind)
        if self.columns:
            out["columns"] = dict(self.columns)
        if self.calibration is not None:
            out["calibration"] = self.calibration
        return out


def frame_transform(frame: ArrayLike, euler: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rotation ``(..., 3, 3)`` and translation ``(..., 3)`` of poses ``(..., 6)``."""
    frame = np.asarray(frame, dtype=float)
    return rotation_matrices(frame[..., 3:], euler), frame[..., :3].copy()


def matrix_to_euler(matrices: ArrayLike, euler: str, *, orthonormal: bool = False) -> NDArray[np.float64]:
    """Euler angles ``(..., 3)`` of rotation matrices ``(..., 3, 3)`` (scipy's convention);
    ``orthonormal``: the matrices are rotations to rounding (products of rotation matrices), not
    checked (:func:`hexcal.core.conventions.rotations_of`)."""
    import warnings

    from scipy.spatial.transform import Rotation  # deferred: slow to import

    mats = np.asarray(matrices, dtype=float)
    batch = mats.shape[:-2]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # gimbal lock: the angles are still valid
        rotations = rotations_of(mats) if orthonormal else Rotation.from_matrix(mats.reshape(-1, 3, 3))
        angles = rotations.as_euler(euler)
    return angles.reshape(batch + (3,))


def transform_frame(frame: ArrayLike, base: tuple[NDArray, NDArray], euler: str) -> NDArray[np.float64]:
    """The instrument frame after new base coordinates ``p' = R_b p + t_b`` (same instrument).

    ``R_F' = R_F R_bᵀ``, ``t_F' = t_F - R_F R_bᵀ t_b``.
    """
    rot, trans = frame_transform(frame, euler)
    rb, tb = base
    new_rot = rot @ np.swapaxes(rb, -1, -2)
    moved = trans - np.einsum("...ij,...j->...i", new_rot, tb)
    return np.concatenate([moved, matrix_to_euler(new_rot, euler, orthonormal=True)], axis=-1)
