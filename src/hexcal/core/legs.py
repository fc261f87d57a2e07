"""Leg models: how a leg's reading becomes its length, the one leg equation of hexcal.

Leg ``i`` joins base joint ``u_i`` to platform joint ``s_i``; its length ``|o + R s_i - u_i|``
is what the controller's reading ``dl_i`` says through the leg model,

    l_i = f(θ_i, dl_i),

with the leg's parameters ``θ_i``. Every model starts with the initial length ``l0_i`` and
the gain ``g_i`` (the length at reading 0 and its first-order change per unit of reading);
:class:`LinearLegs` is ``l0_i + g_i dl_i`` (the seed paper's model), and a model may add
per-leg terms (a stroke-dependent correction of the reading). Kinematics, every residual,
compensation, simulation and export evaluate the legs here and nowhere else.

The parameters of the six legs form one *block* of the machine's parameters, grouped by
kind: ``l0_1 ... l0_6``, ``g1 ... g6``, then each extra term for the six legs.
:meth:`LegModel.index` gathers the ``(6, per_leg)`` table of one leg per row, so that the
per-leg functions work on ``θ (..., 6, per_leg)`` broadcast against readings ``(..., 6)``.

A new leg model is one subclass (its terms, :meth:`~LegModel.length` and
:meth:`~LegModel.length_jacobian`) plus one line in :data:`LEG_MODELS`.

**Per-pose inputs.** A model may also read the conditions of each pose (the legs'
temperatures, the payload): it names the covariates it needs in :attr:`LegModel.covariates`
and its per-leg input columns in :attr:`LegModel.inputs`, and receives them as one array
``inputs (..., m, 6, K)`` beside the readings ``(..., m, 6)`` (built once per data set by
:meth:`LegModel.leg_inputs`; :mod:`hexcal.core.covariate_legs`). Every block function takes
``inputs=None``; a model without inputs never sees the argument, so models written for
readings alone keep working unchanged.

Imports numpy and :mod:`hexcal.errors`.

>>> legs = LinearLegs()
>>> block = np.concatenate([np.full(6, 600.0), np.ones(6)])
>>> legs.lengths(block, np.full((2, 6), 10.0))[0].tolist()
[610.0, 610.0, 610.0, 610.0, 610.0, 610.0]
>>> legs.names()[:2], legs.names()[6:8]
(('l0_1', 'l0_2'), ('g1', 'g2'))
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.errors import GeometryError

N_LEGS = 6

#: Solver scale of an initial length (mm) and, relative to the gain, of a gain: a relative
#: gain change of 1e-3 moves a leg by about a millimetre at a metre of reading travel.
L0_SCALE, GAIN_SCALE = 1.0, 1e-3


class LegModel:
    """The relation between each leg's reading and its length (see the module).

    Subclasses set :attr:`name` and :attr:`terms` (names of the per-leg terms beyond ``l0``
    and ``g``) and implement :meth:`length` and :meth:`length_jacobian` for one leg;
    everything else follows. An instance may hold settings (a reading range, a degree);
    the parameter values are always passed in (a block, or one leg's ``θ``).
    """

    name: ClassVar[str] = ""
    #: Per-leg terms beyond ``l0`` and ``g`` (their parameter names are ``{term}_{leg}``).
    terms: tuple[str, ...] = ()
    #: The covariates the model reads (names of :class:`hexcal.instruments.Covariates`
    #: quantities: ``temperatures``, ``payload_kg``, ...); none for a model of readings alone.
    covariates: tuple[str, ...] = ()
    #: Its per-leg input columns (the last axis of ``inputs``), none without covariates.
    inputs: tuple[str, ...] = ()
    #: Whether its inputs depend on the pose (an axial force does, a temperature does not).
    inputs_need_poses: bool = False

    # -- the per-leg functions --------------------------------------------------------
    def length(self, theta: NDArray[np.float64], reading: NDArray[np.float64]) -> NDArray[np.float64]:
        """Length of a leg with parameters ``theta (..., per_leg)`` at ``reading (...)``."""
        raise NotImplementedError

    def length_jacobian(
        self, theta: NDArray[np.float64], reading: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """``d length / d theta``, shape ``(..., per_leg)`` (broadcast of both inputs)."""
        raise NotImplementedError

    def slope(self, theta: NDArray[np.float64], reading: NDArray[np.float64]) -> NDArray[np.float64]:
        """``d length / d reading`` (by default from the gain column of the Jacobian's
        neighbourhood: central differences; a model overrides it with its own)."""
        step = 1e-6 * np.maximum(1.0, np.abs(reading))
        return (self.length(theta, reading + step) - self.length(theta, reading - step)) / (2 * step)

    # -- the block --------------------------------------------------------------------
    @property
    def per_leg(self) -> int:
        """Parameters of one leg."""
        return 2 + len(self.terms)

    @property
    def size(self) -> int:
        """Parameters of the block (six legs)."""
        return N_LEGS * self.per_leg

    def names(self) -> tuple[str, ...]:
        """Parameter names of the block: ``l0_1 .. l0_6, g1 .. g6``, then the terms."""
        out = [f"l0_{i}" for i in range(1, 7)] + [f"g{i}" for i in range(1, 7)]
        for term in self.terms:
            out += [f"{term}_{i}" for i in range(1, 7)]
        return tuple(out)

    def groups(self) -> dict[str, tuple[str, ...]]:
        """Named groups of the block (``l0``, ``gains``, and the model's own)."""
        names = self.names()
        out = {"l0": names[:6], "gains": names[6:12]}
        if self.terms:
            out[self.name] = names[12:]
        return out

    def index(self) -> NDArray[np.intp]:
        """Block positions of each leg's parameters, shape ``(6, per_leg)``."""
        return np.arange(self.size).reshape(self.per_leg, N_LEGS).T.copy()

    def legs(self) -> NDArray[np.intp]:
        """The leg (0-based) of each block parameter, shape ``(size,)``."""
        return np.tile(np.arange(N_LEGS), self.per_leg)

    def own_groups(self) -> tuple[str, ...]:
        """The groups of the model's own terms (``--fit`` names them; none for linear legs)."""
        return tuple(g for g in self.groups() if g not in ("l0", "gains"))

    def leg_inputs(
        self, covariates: Any, poses: ArrayLike | None = None, geometry: Any = None, where: str = "the data"
    ) -> NDArray[np.float64] | None:
        """Each pose's per-leg inputs ``(m, 6, K)`` of ``covariates`` (a
        :class:`hexcal.instruments.Covariates`; at ``poses`` ``(m, 6)`` on ``geometry`` when
        :attr:`inputs_need_poses`), or None for a model without covariates. A missing
        covariate is one line naming ``where`` and the quantity."""
        return None

    def stroke_range(self) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """Each leg's reading range ``(low, high)`` over which the model's own terms are
        defined (a curve of the stroke), or ``None`` when they hold everywhere (linear legs):
        planning says how much of it a pose set covers."""
        return None

    def term_scales(self) -> NDArray[np.float64]:
        """Solver scales of the extra terms, one per term (default 1 mm)."""
        return np.ones(len(self.terms))

    def term_units(self) -> tuple[str, ...]:
        """The unit of each extra term (default ``mm``: a term that adds to the length; a
        model whose term multiplies a power of the reading says so, ``1/mm``)."""
        return ("mm",) * len(self.terms)

    def units(self) -> tuple[str, ...]:
        """Units of the block's parameters (order of :meth:`names`): mm for ``l0``, 1 for the
        gains, the model's own for its terms."""
        out = ["mm"] * N_LEGS + ["1"] * N_LEGS
        for unit in self.term_units():
            out += [unit] * N_LEGS
        return tuple(out)

    def scales(self, block: ArrayLike) -> NDArray[np.float64]:
        """Solver scales of the block's parameters: 1 mm for ``l0``, ``1e-3 |g|`` for a gain,
        the model's own for its terms."""
        block = np.asarray(block, dtype=float)
        gains = np.abs(block[6:12])
        parts = [np.full(6, L0_SCALE), GAIN_SCALE * np.where(gains > 0, gains, 1.0)]
        parts += [np.full(6, s) for s in self.term_scales()]
        return np.concatenate(parts)

    def thetas(self, block: ArrayLike) -> NDArray[np.float64]:
        """Each leg's parameters ``(..., 6, per_leg)`` of blocks ``(..., size)``."""
        return np.asarray(block, dtype=float)[..., self.index()]

    def leg_length(
        self, theta: NDArray[np.float64], reading: NDArray[np.float64], inputs: NDArray | None = None
    ) -> NDArray[np.float64]:
        """:meth:`length` with the per-pose ``inputs`` ``(..., 6, K)`` when there are any (a model
        of readings alone is called as it was written, without them)."""
        return self.length(theta, reading) if inputs is None else self.length(theta, reading, inputs)

    def leg_length_jacobian(
        self, theta: NDArray[np.float64], reading: NDArray[np.float64], inputs: NDArray | None = None
    ) -> NDArray[np.float64]:
        """:meth:`length_jacobian` with the per-pose ``inputs`` when there are any."""
        if inputs is None:
            return self.length_jacobian(theta, reading)
        return self.length_jacobian(theta, reading, inputs)

    def lengths(
        self, block: ArrayLike, readings: ArrayLike, inputs: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """Leg lengths ``(..., 6)`` of readings ``(..., 6)`` for blocks ``(..., size)``
        (batch shapes broadcast; ``inputs`` ``(..., 6, K)``: each pose's, for a model with
        covariates)."""
        inputs = None if inputs is None else np.asarray(inputs, dtype=float)
        return self.leg_length(self.thetas(block), np.asarray(readings, dtype=float), inputs)

    def jacobian(
        self, block: ArrayLike, readings: ArrayLike, inputs: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """``d lengths / d block``, shape ``(..., 6, size)``: leg ``i`` depends only on its own
        parameters (the other columns are zero)."""
        readings = np.asarray(readings, dtype=float)
        inputs = None if inputs is None else np.asarray(inputs, dtype=float)
        local = self.leg_length_jacobian(self.thetas(block), readings, inputs)  # (..., 6, per_leg)
        out = np.zeros((*local.shape[:-1], self.size))
        rows = np.arange(N_LEGS)[:, None]
        out[..., rows, self.index()] = local
        return out

    def readings(
        self, block: ArrayLike, lengths: ArrayLike, inputs: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """Readings ``(..., 6)`` that give ``lengths`` (the inverse; Newton's method unless a
        model overrides it; ``inputs`` as in :meth:`lengths`)."""
        if inputs is not None:
            raise NotImplementedError(f"the {self.name} leg model has no inverse with per-pose inputs")
        theta = self.thetas(block)
        lengths = np.asarray(lengths, dtype=float)
        reading = (lengths - theta[..., 0]) / theta[..., 1]
        for _ in range(50):
            error = self.length(theta, reading) - lengths
            step = error / self.slope(theta, reading)
            reading = reading - step
            if np.all(np.abs(step) <= 1e-13 * (1.0 + np.abs(reading))):
                break
        return reading

    # -- settings and files -----------------------------------------------------------
    def to_dict(self, block: ArrayLike) -> Any:
        """The geometry file's ``leg_model:`` value (``linear`` is the word)."""
        return self.name

    @classmethod
    def from_dict(cls, value: Any, where: str = "leg_model") -> tuple[LegModel, NDArray[np.float64]]:
        """The model and its extra terms ``(6, len(terms))`` of a ``leg_model:`` value."""
        return cls(), np.zeros((N_LEGS, 0))

    def __eq__(self, other: object) -> bool:
        return type(self) is type(other) and self.settings() == other.settings()

    def __hash__(self) -> int:
        return hash((type(self), self.settings()))

    def settings(self) -> tuple[Any, ...]:
        """What distinguishes two instances of the model (none for the linear model)."""
        return ()

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


class LinearLegs(LegModel):
    """``l = l0 + g dl``: the seed paper's leg model (Agheli & Nategh 2009, eq. 1)."""

    name = "linear"

    def length(self, theta: NDArray[np.float64], reading: NDArray[np.float64]) -> NDArray[np.float64]:
        return theta[..., 0] + theta[..., 1] * reading

    def length_jacobian(
        self, theta: NDArray[np.float64], reading: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        one = np.ones(np.broadcast_shapes(theta.shape[:-1], np.shape(reading)))
        return np.stack([one, one * reading], axis=-1)

    def slope(self, theta: NDArray[np.float64], reading: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.broadcast_to(theta[..., 1], np.broadcast_shapes(theta.shape[:-1], np.shape(reading)))

    def readings(
        self, block: ArrayLike, lengths: ArrayLike, inputs: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        theta = self.thetas(block)
        return (np.asarray(lengths, dtype=float) - theta[..., 0]) / theta[..., 1]


#: Leg models by name: a new model is one subclass plus one line here.
LEG_MODELS: dict[str, type[LegModel]] = {LinearLegs.name: LinearLegs}


def register_leg_model(model: type[LegModel], names: tuple[str, ...] = ()) -> type[LegModel]:
    """Add a leg model class to :data:`LEG_MODELS` (replacing one of the same name), under its
    ``name`` or, for a class that makes several models (a combination of terms), ``names``."""
    for name in names or (model.name,):
        LEG_MODELS[name] = model
    return model


def leg_model_from_dict(value: Any) -> tuple[LegModel, NDArray[np.float64]]:
    """The leg model and its extra terms of a geometry file's ``leg_model:`` value (a name,
    or a mapping with ``kind``); :class:`GeometryError` naming the problem."""
    kind = value.get("kind") if isinstance(value, dict) else value
    if not isinstance(kind, str) or kind not in LEG_MODELS:
        raise GeometryError(f"leg_model: unknown kind {kind!r}; choose from {', '.join(LEG_MODELS)}")
    return LEG_MODELS[kind].from_dict(value)
