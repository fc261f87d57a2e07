"""Leg models with covariates: legs that grow with temperature and give under load.

:class:`CovariateLegs` adds to a leg model of readings (linear legs, or the stroke model)
terms of each pose's conditions, per leg ``i``:

- **thermal**: the leg grows by its coefficient ``kt_i`` (mm/K) per kelvin of its temperature
  ``T_i`` above the reference ``T_ref`` (a setting, default 20 °C),
  ``+ kt_i (T_i - T_ref)``; or, with ``per_length``, in proportion to its length: its
  expansion coefficient ``cte_i`` (1/K), ``l_i = l_base,i (1 + cte_i (T_i - T_ref))``;
- **compliance**: the leg shortens by its compliance ``kc_i`` (mm/N) times its axial force
  ``F_i`` (N, compression positive), ``- kc_i F_i``. The forces are those that hold the
  platform's and the payload's weight at the pose: with ``n_i`` the unit vector of leg ``i``
  (base joint to platform joint) and ``r_i = R s_i`` its platform joint about the platform's
  origin, the static equilibrium ``Σ F_i n_i + W = 0``, ``Σ F_i (r_i × n_i) + M = 0`` with
  the weight ``W = (m_p + m) g`` and its moment ``M = R c_p × m_p g + R c × m g`` (``g`` the
  gravity, default ``(0, 0, -9.80665)`` m/s² in the base frame; the platform's mass ``m_p``
  and centre of mass ``c_p`` settings of the model, the payload's ``m``, ``c`` the
  ``payload_kg`` and ``payload_x/y/z`` columns). The 6 × 6 matrix of the ``n_i`` and
  ``r_i × n_i`` is the transpose of the statics Jacobian (``J⁻ᵀ`` maps the wrench to the leg
  forces).

**First order.** The forces are computed once per pose, at the pose the data give (the target
of ``ik`` and ``compensate``, the measured or start pose of an identification, the reached
pose of a simulation) on the geometry at hand, and held: a leg's deflection (hundredths of a
millimetre) changes the directions, and so the forces, by parts in 10⁵, far below any
measurement. This keeps every leg's equation a function of its own parameters (the leg
equations stay separable), and the compliance term linear in ``kc``. The platform's mass and
centre of mass are therefore given (they would couple the legs): a platform mass left at 0
means the compliance sees the payload alone, and the platform's own weight, the same in every
session, is then part of the geometry the calibration fits.

The per-pose inputs are ``ΔT_i = T_i - T_ref`` (K) and ``F_i`` (N): the columns
:attr:`CovariateLegs.inputs` of the array ``(m, 6, K)`` that the leg equations receive beside
the readings (:meth:`CovariateLegs.leg_inputs`; the poses of readings under them:
:func:`hexcal.core.kinematics.forward_with_covariates`). Without inputs (planning, the
predicted accuracy over a workspace) the model is at its reference conditions: ``ΔT = 0``, no
force.

The geometry file's form, beside the stroke model's::

    leg_model:
      kind: stroke+thermal+compliance     # or thermal, compliance, thermal+compliance, ...
      degree: 3                           # the stroke model's keys, when kind has stroke
      stroke: {low: [...], high: [...]}
      thermal: {reference: 20.0, per_length: false}
      compliance: {platform_mass: 12.0, platform_com: [0, 0, 30], gravity: [0, 0, -9.80665]}
      terms: {p2: [...], p3: [...], kt: [6 values, mm/K], kc: [6 values, mm/N]}

Imports numpy and the rest of :mod:`hexcal.core`.

>>> legs = CovariateLegs(thermal=True)
>>> legs.name, legs.names()[12:14], legs.inputs
('thermal', ('kt_1', 'kt_2'), ('dT',))
>>> block = np.concatenate([np.full(6, 600.0), np.ones(6), np.full(6, 0.01)])
>>> dt = np.full((1, 6, 1), 5.0)  # 5 K above the reference
>>> legs.lengths(block, np.full((1, 6), 10.0), dt)[0, 0].round(6)
np.float64(610.05)
"""

from __future__ import annotations

from itertools import combinations
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core.conventions import as_poses, rotation_matrices
from hexcal.core.legs import N_LEGS, LegModel, LinearLegs, leg_model_from_dict, register_leg_model
from hexcal.core.stroke_legs import StrokeLegs
from hexcal.errors import GeometryError, InputError

#: The covariate terms, in the order a kind names them.
TERMS = ("thermal", "compliance")
#: Default reference temperature of the thermal term, °C.
REFERENCE_TEMPERATURE = 20.0
#: Standard gravity, m/s², along -z of the base frame by default.
GRAVITY = (0.0, 0.0, -9.80665)
#: Solver scales: a thermal coefficient (mm/K; a 600 mm steel strut has about 0.007), an
#: expansion coefficient (1/K; steel 1.2e-5), a compliance (mm/N; a strut of 10⁴ N/mm).
KT_SCALE, CTE_SCALE, KC_SCALE = 0.01, 1e-5, 1e-4
#: Every kind this module makes: a base model of readings, then its covariate terms.
KINDS = tuple(
    "+".join(((base,) if base != LinearLegs.name else ()) + extra)
    for base in (LinearLegs.name, StrokeLegs.name)
    for r in (1, 2)
    for extra in combinations(TERMS, r)
)


def parse_kind(kind: str) -> tuple[str, bool, bool]:
    """``(base, thermal, compliance)`` of a kind such as ``stroke+thermal``."""
    parts = str(kind).split("+")
    base = parts[0] if parts[0] not in TERMS else LinearLegs.name
    extra = parts[1:] if parts[0] not in TERMS else parts
    if (
        base not in (LinearLegs.name, StrokeLegs.name)
        or not extra
        or any(e not in TERMS for e in extra)
        or (len(set(extra)) != len(extra))
    ):
        raise GeometryError(f"leg_model: unknown kind {kind!r}; choose from {', '.join(KINDS)}")
    return base, "thermal" in extra, "compliance" in extra


class CovariateLegs(LegModel):
    """A leg model of readings plus thermal and compliance terms (see the module).

    Parameters
    ----------
    base : LegModel, optional
        The model of readings (default linear legs; or a :class:`StrokeLegs`).
    thermal, compliance : bool
        Which terms the model has (at least one).
    reference : float
        Reference temperature of the thermal term, °C.
    per_length : bool
        The thermal term as an expansion coefficient of the leg's length (``cte``, 1/K)
        instead of a coefficient per leg (``kt``, mm/K).
    platform_mass : float
        The platform's mass, kg (without payload).
    platform_com : array_like, shape (3,)
        Its centre of mass, mm, platform frame.
    gravity : array_like, shape (3,)
        The acceleration of gravity in the base frame, m/s².
    """

    def __init__(
        self,
        base: LegModel | None = None,
        thermal: bool = False,
        compliance: bool = False,
        reference: float = REFERENCE_TEMPERATURE,
        per_length: bool = False,
        platform_mass: float = 0.0,
        platform_com: ArrayLike = (0.0, 0.0, 0.0),
        gravity: ArrayLike = GRAVITY,
    ) -> None:
        base = LinearLegs() if base is None else base
        if not isinstance(base, LinearLegs | StrokeLegs):
            raise GeometryError(f"leg_model: the {base.name} model takes no covariate terms")
        if not (thermal or compliance):
            raise GeometryError("leg_model: a covariate model needs the thermal or the compliance term")
        self.base, self.thermal, self.compliance = base, bool(thermal), bool(compliance)
        self.reference = _number(reference, "leg_model.thermal.reference")
        if not -60.0 <= self.reference <= 200.0:
            raise GeometryError(
                f"leg_model.thermal.reference: {self.reference:g} °C is not a plausible temperature"
            )
        self.per_length = bool(per_length)
        self.platform_mass = _number(platform_mass, "leg_model.compliance.platform_mass")
        if self.platform_mass < 0:
            raise GeometryError(f"leg_model.compliance.platform_mass: {self.platform_mass:g} kg is negative")
        self.platform_com = _three(platform_com, "leg_model.compliance.platform_com")
        self.gravity = _three(gravity, "leg_model.compliance.gravity")
        parts = ([base.name] if base.terms else []) + [t for t in TERMS if getattr(self, t)]
        self.name = "+".join(parts)  # type: ignore[misc]  (one class, several kinds)
        own: list[str] = []
        inputs: list[str] = []
        covariates: list[str] = []
        if self.thermal:
            own.append("cte" if self.per_length else "kt")
            inputs.append("dT")
            covariates.append("temperatures")
        if self.compliance:
            own.append("kc")
            inputs.append("force")
            covariates.append("payload_kg")
        self.terms = (*base.terms, *own)
        self.inputs = tuple(inputs)
        self.covariates = tuple(covariates)
        self.inputs_need_poses = self.compliance
        self._nb = base.per_leg  # the base model's columns of a leg's θ

    # -- the per-leg functions ---------------------------------------------------------------
    def _split(self, theta: NDArray, inputs: NDArray | None) -> tuple[NDArray, NDArray, NDArray]:
        """The base θ, and the thermal and compliance terms' products ``(coef, input)``."""
        zero = np.zeros(())
        k = self._nb
        dt = force = zero
        if inputs is not None:
            col = 0
            if self.thermal:
                dt, col = inputs[..., col], col + 1
            if self.compliance:
                force = inputs[..., col]
        return theta[..., :k], dt, force

    def _coefficients(self, theta: NDArray) -> tuple[NDArray, NDArray]:
        k = self._nb
        zero = np.zeros(theta.shape[:-1])
        thermal = theta[..., k] if self.thermal else zero
        compliance = theta[..., k + int(self.thermal)] if self.compliance else zero
        return thermal, compliance

    def length(
        self, theta: NDArray[np.float64], reading: NDArray[np.float64], inputs: NDArray | None = None
    ) -> NDArray[np.float64]:
        base, dt, force = self._split(theta, inputs)
        thermal, compliance = self._coefficients(theta)
        length = self.base.length(base, reading)
        if self.per_length:
            return length * (1.0 + thermal * dt) - compliance * force
        return length + thermal * dt - compliance * force

    def length_jacobian(
        self, theta: NDArray[np.float64], reading: NDArray[np.float64], inputs: NDArray | None = None
    ) -> NDArray[np.float64]:
        base, dt, force = self._split(theta, inputs)
        thermal, _ = self._coefficients(theta)
        jac = self.base.length_jacobian(base, reading)
        shape = jac.shape[:-1]
        cols = []
        if self.per_length:
            grow = 1.0 + thermal * dt
            jac = jac * np.asarray(grow)[..., None]
            if self.thermal:
                cols.append(self.base.length(base, reading) * dt)
        elif self.thermal:
            cols.append(np.broadcast_to(dt, shape))
        if self.compliance:
            cols.append(np.broadcast_to(-force, shape))
        if not cols:
            return jac
        return np.concatenate([jac, np.stack([np.broadcast_to(c, shape) for c in cols], axis=-1)], axis=-1)

    def slope(
        self, theta: NDArray[np.float64], reading: NDArray[np.float64], inputs: NDArray | None = None
    ) -> NDArray[np.float64]:
        base, dt, _ = self._split(theta, inputs)
        slope = self.base.slope(base, reading)
        if self.per_length:
            thermal, _ = self._coefficients(theta)
            return slope * (1.0 + thermal * dt)
        return slope

    def readings(
        self, block: ArrayLike, lengths: ArrayLike, inputs: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """Readings ``(..., 6)`` of ``lengths`` at ``inputs``: the base model's inverse of the
        length without the covariate terms (exact: they do not depend on the reading)."""
        block = np.asarray(block, dtype=float)
        theta = self.thetas(block)
        _, dt, force = self._split(theta, None if inputs is None else np.asarray(inputs, dtype=float))
        thermal, compliance = self._coefficients(theta)
        lengths = np.asarray(lengths, dtype=float) + compliance * force
        lengths = lengths / (1.0 + thermal * dt) if self.per_length else lengths - thermal * dt
        return self.base.readings(block[..., : self.base.size], lengths)

    def check_invertible(self, block: ArrayLike) -> None:
        """The base model's check (the stroke model's curve must grow on its stroke)."""
        check = getattr(self.base, "check_invertible", None)
        if check is not None:
            check(np.asarray(block, dtype=float)[..., : self.base.size])

    # -- the block ---------------------------------------------------------------------------
    def groups(self) -> dict[str, tuple[str, ...]]:
        """``l0``, ``gains``, the base model's own group (``stroke``), then ``thermal`` and
        ``compliance``."""
        names = self.names()
        out = {"l0": names[:6], "gains": names[6:12]}
        at = 12
        if self.base.terms:
            out[self.base.name] = names[at : at + 6 * len(self.base.terms)]
            at += 6 * len(self.base.terms)
        for term in TERMS:
            if getattr(self, term):
                out[term] = names[at : at + 6]
                at += 6
        return out

    def stroke_range(self) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        return self.base.stroke_range()

    def term_scales(self) -> NDArray[np.float64]:
        own = ([CTE_SCALE if self.per_length else KT_SCALE] if self.thermal else []) + (
            [KC_SCALE] if self.compliance else []
        )
        return np.concatenate([self.base.term_scales(), own])

    def term_units(self) -> tuple[str, ...]:
        """The base model's units, then ``mm/K`` (``kt``) or ``1/K`` (``cte``) and ``mm/N``."""
        own = (["1/K" if self.per_length else "mm/K"] if self.thermal else []) + (
            ["mm/N"] if self.compliance else []
        )
        return (*self.base.term_units(), *own)

    # -- the per-pose inputs ------------------------------------------------------------------
    def leg_inputs(
        self, covariates: Any, poses: ArrayLike | None = None, geometry: Any = None, where: str = "the data"
    ) -> NDArray[np.float64]:
        """``(m, 6, K)``: each leg's ``ΔT`` (K) and axial force (N) at each pose (see the module);
        the forces at ``poses`` on ``geometry`` (its joints and Euler sequence)."""
        covariates.require(self.covariates, f"{where}: the {self.name} leg model")
        columns = []
        if self.thermal:
            columns.append(np.asarray(covariates.temperatures, dtype=float) - self.reference)
        if self.compliance:
            if poses is None or geometry is None:
                raise InputError(f"{where}: the {self.name} leg model needs the poses for its axial forces")
            com = covariates.payload_com
            m = len(covariates.payload_kg)
            com = np.zeros((m, 3)) if com is None else np.asarray(com, dtype=float)
            columns.append(
                axial_forces(
                    geometry.base_joints,
                    geometry.platform_joints,
                    poses,
                    geometry.euler,
                    [(self.platform_mass, self.platform_com), (covariates.payload_kg, com)],
                    self.gravity,
                )
            )
        return np.stack(columns, axis=-1)

    # -- settings and files ------------------------------------------------------------------
    def settings(self) -> tuple[Any, ...]:
        return (
            self.name,
            self.base.settings(),
            self.reference,
            self.per_length,
            self.platform_mass,
            tuple(self.platform_com.tolist()),
            tuple(self.gravity.tolist()),
        )

    def to_dict(self, block: ArrayLike) -> Any:
        block = np.asarray(block, dtype=float)
        out: dict[str, Any] = {"kind": self.name}
        base = self.base.to_dict(block[: self.base.size])
        base_terms = base.pop("terms", {}) if isinstance(base, dict) else {}
        if isinstance(base, dict):
            out.update({k: v for k, v in base.items() if k != "kind"})
        if self.thermal:
            out["thermal"] = {"reference": self.reference, "per_length": self.per_length}
        if self.compliance:
            out["compliance"] = {
                "platform_mass": self.platform_mass,
                "platform_com": self.platform_com.tolist(),
                "gravity": self.gravity.tolist(),
            }
        values = block[12:].reshape(-1, N_LEGS)[len(self.base.terms) :]
        own = self.terms[len(self.base.terms) :]
        out["terms"] = {**base_terms, **{t: row.tolist() for t, row in zip(own, values, strict=True)}}
        return out

    @classmethod
    def from_dict(cls, value: Any, where: str = "leg_model") -> tuple[LegModel, NDArray[np.float64]]:
        kind = value.get("kind") if isinstance(value, dict) else value
        base_kind, thermal, compliance = parse_kind(kind)
        value = dict(value) if isinstance(value, dict) else {"kind": kind}
        unknown = sorted(set(value) - {"kind", "degree", "stroke", "thermal", "compliance", "terms"})
        if unknown:
            raise GeometryError(f"{where}: unknown key(s): {', '.join(map(str, unknown))}")
        terms = value.get("terms") or {}
        if not isinstance(terms, dict):
            raise GeometryError(f"{where}.terms: a mapping of term names to six values each")
        own_names = {"kt", "cte", "kc"}
        base_value: Any = LinearLegs.name
        if base_kind == StrokeLegs.name:
            base_value = {k: value[k] for k in ("degree", "stroke") if k in value}
            base_value["kind"] = StrokeLegs.name
            base_value["terms"] = {k: v for k, v in terms.items() if k not in own_names}
        elif any(k in value for k in ("degree", "stroke")):
            raise GeometryError(f"{where}: degree and stroke belong to a kind with stroke (stroke+...)")
        base, base_terms = leg_model_from_dict(base_value)
        th = _mapping(value.get("thermal"), f"{where}.thermal", {"reference", "per_length"}, thermal)
        co = _mapping(
            value.get("compliance"),
            f"{where}.compliance",
            {"platform_mass", "platform_com", "gravity"},
            compliance,
        )
        per_length = th.get("per_length", False)
        if not isinstance(per_length, bool):
            raise GeometryError(f"{where}.thermal.per_length: true or false, got {per_length!r}")
        model = cls(
            base,
            thermal,
            compliance,
            th.get("reference", REFERENCE_TEMPERATURE),
            per_length,
            co.get("platform_mass", 0.0),
            co.get("platform_com", (0.0, 0.0, 0.0)),
            co.get("gravity", GRAVITY),
        )
        own = model.terms[len(base.terms) :]
        extra = sorted(set(map(str, terms)) - set(model.terms))
        if extra:
            raise GeometryError(
                f"{where}.terms: {', '.join(extra)} not terms of {model.name} ({', '.join(model.terms)})"
            )
        rows = [_six(terms.get(t, 0.0), f"{where}.terms.{t}") for t in own]
        return model, np.concatenate([base_terms, np.stack(rows, axis=1)], axis=1)

    def __repr__(self) -> str:
        return f"CovariateLegs({self.name!r})"


def covariate_model(kind: str, base: LegModel, like: LegModel | None = None) -> CovariateLegs:
    """The covariate model ``kind`` (``thermal``, ``stroke+thermal``, ...) over ``base``, its
    settings (reference temperature, the platform's mass and centre of mass, gravity) those of
    ``like`` when it is a covariate model too (the nominal geometry's), else the defaults."""
    _, thermal, compliance = parse_kind(kind)
    if not isinstance(like, CovariateLegs):
        return CovariateLegs(base, thermal, compliance)
    return CovariateLegs(
        base,
        thermal,
        compliance,
        like.reference,
        like.per_length,
        like.platform_mass,
        like.platform_com,
        like.gravity,
    )


def axial_forces(
    base_joints: ArrayLike,
    platform_joints: ArrayLike,
    poses: ArrayLike,
    euler: str,
    masses: list[tuple[ArrayLike, ArrayLike]],
    gravity: ArrayLike = GRAVITY,
) -> NDArray[np.float64]:
    """Each leg's axial force ``(..., 6)`` (N, compression positive) holding point masses at
    poses ``(..., 6)``: the static equilibrium of the module.

    ``masses`` are ``(mass, centre)`` pairs: kg ``()`` or ``(...)``, mm in the platform frame
    ``(3,)`` or ``(..., 3)``. A pose whose legs cannot hold a wrench (a singular pose) gets NaN.

    >>> from hexcal.core.presets import preset
    >>> hmt = preset("paper-hmt")  # 60 kg at the platform's origin, the platform level
    >>> f = axial_forces(hmt.base_joints, hmt.platform_joints, hmt.home_pose, hmt.euler, [(60.0, [0, 0, 0])])
    >>> f.round(1).tolist()  # each leg's share, in compression
    [101.5, 101.5, 101.5, 101.5, 101.5, 101.5]
    """
    poses = as_poses(poses, "poses")
    rot = rotation_matrices(poses[..., 3:], euler)
    rotated = np.einsum("...jk,ik->...ij", rot, np.asarray(platform_joints, dtype=float))  # R s_i
    legs = rotated + poses[..., None, :3] - np.asarray(base_joints, dtype=float)
    unit = legs / np.linalg.norm(legs, axis=-1, keepdims=True)
    a = np.concatenate([unit, np.cross(rotated, unit)], axis=-1)  # (..., 6 legs, 6): columns of J⁻ᵀ's inverse
    g = np.asarray(gravity, dtype=float)
    wrench = np.zeros((*poses.shape[:-1], 6))
    for mass, centre in masses:
        batch = poses.shape[:-1]
        weight = np.broadcast_to(np.asarray(mass, dtype=float)[..., None] * g, (*batch, 3))  # N
        centre = np.broadcast_to(np.asarray(centre, dtype=float), (*batch, 3))
        arm = np.einsum("...jk,...k->...j", rot, centre)
        wrench = wrench + np.concatenate([weight, np.cross(arm, weight)], axis=-1)
    # Σ F_i a_i + wrench = 0: solve Aᵀ F = -wrench, A rows the legs
    mat = np.swapaxes(a, -1, -2)
    ok = np.linalg.cond(mat) < 1e12
    safe = np.where(ok[..., None, None], mat, np.eye(6))
    forces = np.linalg.solve(safe, -wrench[..., None])[..., 0]
    return np.where(ok[..., None], forces, np.nan)


def geometry_inputs(
    geometry: Any, covariates: Any, poses: ArrayLike | None = None, where: str = "the data"
) -> NDArray[np.float64] | None:
    """Each pose's leg-model inputs ``(m, 6, K)`` for ``geometry``'s leg model, of
    ``covariates`` (:class:`hexcal.instruments.Covariates`) and, for forces, ``poses``
    ``(m, 6)``; None for a leg model without covariates (whatever the data carry). A missing
    covariate is one :class:`~hexcal.errors.InputError` line naming ``where``."""
    model = geometry.leg_model
    if not model.covariates:
        return None
    if covariates is None:
        raise InputError(f"{where}: the {model.name} leg model needs covariates, which the data do not have")
    return model.leg_inputs(covariates, None if poses is None else as_poses(poses, "poses"), geometry, where)


def at_conditions(geometry: Any, covariates: Any, where: str = "the program") -> Any:
    """``geometry`` with the legs of its covariate model under one set of conditions, the same
    at every pose (``covariates`` of one row): its base model (linear or stroke) with the
    thermal term folded into its parameters (``l0 + kt ΔT``, or every length parameter times
    ``1 + cte ΔT``). A model without covariates is returned as it is; one whose inputs depend
    on the pose (compliance: the axial forces) cannot be folded and is refused in one line.

    For a program of moves (``compensate --gcode``) whose every point is made at one temperature."""
    model = geometry.leg_model
    if not isinstance(model, CovariateLegs):
        return geometry
    if model.inputs_need_poses:
        raise InputError(
            f"{where}: the {model.name} leg model's axial forces change along the path, which the "
            "program filter does not follow; compensate the program's poses (--poses, --payload)"
        )
    inputs = model.leg_inputs(covariates, where=where)  # (1, 6, 1): each leg's ΔT
    dt = inputs[0, :, 0]
    block = geometry.leg_block()
    theta = model.thetas(block)  # (6, per_leg)
    base = theta[:, : model.base.per_leg].copy()
    coefficient = theta[:, model.base.per_leg]
    if model.per_length:
        base *= (1.0 + coefficient * dt)[:, None]
    else:
        base[:, 0] += coefficient * dt
    terms = base[:, 2:] if model.base.terms else None
    return geometry.replace(
        leg_model=model.base, initial_leg_lengths=base[:, 0], leg_gains=base[:, 1], leg_terms=terms
    )


def _number(value: Any, what: str) -> float:
    if isinstance(value, bool):
        raise GeometryError(f"{what}: a number, got {value!r}")
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise GeometryError(f"{what}: a number, got {value!r}") from None
    if not np.isfinite(out):
        raise GeometryError(f"{what}: a finite number, got {value!r}")
    return out


def _three(value: Any, what: str) -> NDArray[np.float64]:
    try:
        out = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise GeometryError(f"{what}: three numbers") from None
    if out.shape != (3,) or not np.all(np.isfinite(out)):
        raise GeometryError(f"{what}: three finite numbers")
    out.flags.writeable = False
    return out


def _six(value: Any, what: str) -> NDArray[np.float64]:
    try:
        out = np.array(np.broadcast_to(np.asarray(value, dtype=float), (N_LEGS,)))
    except (TypeError, ValueError):
        raise GeometryError(f"{what}: six numbers, one per leg") from None
    if np.ndim(value) not in (0, 1) or not np.all(np.isfinite(out)):
        raise GeometryError(f"{what}: six finite numbers, one per leg")
    return out


def _mapping(value: Any, what: str, keys: set[str], used: bool) -> dict[str, Any]:
    if value is None:
        return {}
    if not used:
        raise GeometryError(f"{what}: this kind has no {what.rsplit('.', 1)[-1]} term")
    if not isinstance(value, dict):
        raise GeometryError(f"{what}: a mapping of {', '.join(sorted(keys))}")
    unknown = sorted(set(map(str, value)) - keys)
    if unknown:
        raise GeometryError(f"{what}: unknown key(s): {', '.join(unknown)}")
    return value


register_leg_model(CovariateLegs, KINDS)
