"""The one campaign protocol: trial seeds, true machines, simulated data and validation.

Every simulation of hexcal (``hexcal paper``, ``hexcal simulate``, ``hexcal
synthesize`` and the selection study) follows the seed paper's protocol:

1. the true machine is a given geometry, or the nominal one plus uniform errors;
2. leg readings come from the nominal inverse kinematics of the commanded poses,
   ``dl = (IK_nominal(pose) - l0_nominal) / g_nominal``;
3. the machine really reaches the forward kinematics of the true geometry at
   ``l0_true + g_true dl + e`` with the leg sensor error ``e``;
4. the measured pose is that pose plus the measurement noise;
5. identification starts from the nominal geometry;
6. validation commands further poses (with the nominal or the identified parameters)
   and compares where the true machine goes with the targets.

Seeding: trial ``t`` draws from its own generator, the ``t``-th child of the seed
(:class:`TrialSeeds`), and further streams of the trial are keyed under that child; so
a trial's numbers do not depend on how trials are grouped or where they run.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core import (
    N_BASE_PARAMETERS,
    Geometry,
    NoiseModel,
    forward_kinematics_from_arrays,
    inverse_kinematics,
    leg_readings,
    leg_vectors_from_arrays,
    pose_errors,
)
from hexcal.core.legs import LegModel, LinearLegs
from hexcal.core.parameters import JOINT_NAMES, PARAMETER_NAMES
from hexcal.errors import SimulationError
from hexcal.instruments import Measurements
from hexcal.instruments.base import MeasurementModel, Session
from hexcal.instruments.covariates import Covariates


@dataclass(frozen=True)
class TrialSeeds:
    """The seeding scheme: one :class:`numpy.random.SeedSequence` child per trial.

    ``generator(t)`` is the generator of the ``t``-th child of the seed, the same as
    ``default_rng(SeedSequence(seed).spawn(T)[t])``; ``generator(t, *stream)`` is an
    independent stream of trial ``t`` keyed by further integers (e.g. one per study cell).

    Parameters
    ----------
    entropy : int or sequence of int
        The seed's entropy (:attr:`numpy.random.SeedSequence.entropy`).
    key : tuple of int
        The seed's own spawn key (empty for a seed given as a number).

    Examples
    --------
    >>> import numpy as np
    >>> seeds = TrialSeeds.from_seed(7)
    >>> child = np.random.SeedSequence(7).spawn(3)[2]
    >>> bool(seeds.generator(2).random() == np.random.default_rng(child).random())
    True
    >>> seeds.generator(2, 0, 15).random() == seeds.generator(2).random()
    False
    """

    entropy: int | tuple[int, ...]
    key: tuple[int, ...] = ()

    @classmethod
    def from_seed(cls, seed: int | Sequence[int] | np.random.SeedSequence | TrialSeeds | None) -> TrialSeeds:
        """The trial seeds of a seed (``None``: fresh entropy from the operating system)."""
        if isinstance(seed, TrialSeeds):
            return seed
        seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        entropy = seq.entropy if isinstance(seq.entropy, int) else tuple(int(e) for e in seq.entropy)
        return cls(entropy, tuple(int(k) for k in seq.spawn_key))

    def generator(self, trial: int, *stream: int) -> np.random.Generator:
        """The generator of trial ``trial`` (and of its sub-stream ``stream``)."""
        key = (*self.key, int(trial), *(int(s) for s in stream))
        return np.random.default_rng(np.random.SeedSequence(self.entropy, spawn_key=key))


@dataclass(frozen=True)
class MachineBatch:
    """Kinematic parameters of ``T`` machines as arrays (one per trial), with one leg model.

    Attributes
    ----------
    base_joints, platform_joints : ndarray, shape (T, 6, 3)
    legs : ndarray, shape (T, p)
        Each machine's leg-model block (``l0``, gains, the model's terms).
    leg_model : LegModel
        How a reading becomes a length (:mod:`hexcal.core.legs`).

    Examples
    --------
    >>> from hexcal.core import preset
    >>> machines = MachineBatch.from_vectors(np.stack([preset("paper-hmt").to_vector()] * 2), np.ones(6))
    >>> machines.lengths(np.zeros((2, 1, 6)), "xyz").shape
    (2, 1, 6)
    """

    base_joints: NDArray[np.float64]
    platform_joints: NDArray[np.float64]
    legs: NDArray[np.float64]
    leg_model: LegModel = field(default_factory=LinearLegs)

    @classmethod
    def from_vectors(cls, vectors: NDArray[np.float64], gains: NDArray[np.float64]) -> MachineBatch:
        """Linear-leg machines from 42-vectors ``(T, 42)`` (joints and ``l0``, the seed paper's
        parameters) and leg gains ``(6,)`` or ``(T, 6)``."""
        t = vectors.shape[0]
        named = dict(zip(PARAMETER_NAMES, range(len(PARAMETER_NAMES)), strict=False))
        l0 = vectors[:, [named[f"l0_{i}"] for i in range(1, 7)]]
        joints = vectors[:, [named[n] for n in JOINT_NAMES]]
        return cls(
            joints[:, :18].reshape(t, 6, 3),
            joints[:, 18:].reshape(t, 6, 3),
            np.concatenate([l0, np.broadcast_to(gains, (t, 6))], axis=1),
        )

    @classmethod
    def from_geometry(cls, geometry: Geometry, vectors: NDArray[np.float64] | None = None) -> MachineBatch:
        """Machines of ``geometry``'s leg model from machine vectors ``(T, 36 + p)`` (the order of
        :meth:`Geometry.machine_names`; default the geometry itself, ``T = 1``)."""
        vectors = geometry.machine_vector()[None] if vectors is None else np.asarray(vectors, dtype=float)
        params = geometry.machine_parameters()
        joints, legs = vectors[:, params.span("joints")], vectors[:, params.span("legs")]
        t = len(vectors)
        return cls(joints[:, :18].reshape(t, 6, 3), joints[:, 18:].reshape(t, 6, 3), legs, geometry.leg_model)

    @property
    def leg_gains(self) -> NDArray[np.float64]:
        """Each machine's gains ``(T, 6)`` (the leg model's first-order term)."""
        return self.leg_model.thetas(self.legs)[..., 1]

    def lengths(self, poses: NDArray[np.float64], euler: str) -> NDArray[np.float64]:
        """Leg lengths of poses ``(T, n, 6)`` on each trial's machine, ``(T, n, 6)`` mm."""
        legs, _ = leg_vectors_from_arrays(
            self.base_joints[:, None], self.platform_joints[:, None], poses, euler
        )
        return np.linalg.norm(legs, axis=-1)

    def commands(self, targets: NDArray[np.float64], euler: str) -> NDArray[np.float64]:
        """Leg readings ``(T, n, 6)`` that bring these machines to ``targets`` ``(T, n, 6)``."""
        return self.leg_model.readings(self.legs[:, None], self.lengths(targets, euler))

    def reach(
        self,
        readings: NDArray[np.float64],
        guess: NDArray[np.float64],
        euler: str,
        strict: bool = True,
        sensor: NDArray[np.float64] | None = None,
    ) -> NDArray[np.float64]:
        """Poses ``(T, n, 6)`` the machines reach for readings ``(T, n, 6)`` (forward kinematics),
        their legs off by the sensor errors ``sensor`` (mm, same shape) when given.

        Raises :class:`~hexcal.errors.SimulationError` if a pose is unreachable, unless
        ``strict`` is false: then its row is NaN.
        """
        lengths = self.leg_model.lengths(self.legs[:, None], readings)
        if sensor is not None:
            lengths = lengths + sensor
        result = forward_kinematics_from_arrays(
            self.base_joints[:, None], self.platform_joints[:, None], lengths, guess, euler
        )
        if strict and not result.all_converged:
            bad = int(np.sum(~result.converged))
            raise SimulationError(
                f"forward kinematics did not converge for {bad} simulated pose(s): "
                "the commanded poses are not reachable by the simulated machine"
            )
        return result.poses


def true_machines(
    nominal: Geometry,
    true: Geometry | None,
    rngs: Sequence[np.random.Generator],
    error: float,
) -> tuple[NDArray[np.float64], MachineBatch]:
    """The true 42-vectors ``(T, 42)`` of the trials and their machines.

    ``true`` in every trial, or (``true`` None) the nominal vector plus uniform errors in
    ``[-error, error]`` mm, drawn from each trial's generator; the machines keep the leg
    model of their geometry and its other parameters (gains, the model's own terms).
    """
    if true is None:
        vectors = random_machines(nominal, len(rngs), error, list(rngs))
        machines = np.stack([nominal.with_vector(v).machine_vector() for v in vectors])
        return vectors, MachineBatch.from_geometry(nominal, machines)
    vectors = np.broadcast_to(true.to_vector(), (len(rngs), N_BASE_PARAMETERS)).copy()
    machines = np.broadcast_to(true.machine_vector(), (len(rngs), len(true.machine_names())))
    return vectors, MachineBatch.from_geometry(true, machines)


def random_machines(
    nominal: Geometry, trials: int, error: float, rngs: list[np.random.Generator]
) -> NDArray[np.float64]:
    """True 42-vectors ``(trials, 42)``: nominal plus uniform errors in ``[-error, error]`` mm."""
    base = nominal.to_vector()
    return np.stack([base + r.uniform(-error, error, base.size) for r in rngs[:trials]])


@dataclass(frozen=True)
class CampaignData:
    """Simulated campaigns of ``T`` trials with ``n`` poses each.

    Attributes
    ----------
    readings : ndarray, shape (T, n, 6)
        Leg readings (the nominal inverse kinematics of the commanded poses), mm.
    reached : ndarray, shape (T, n, 6)
        Poses the true machines really reached; NaN rows where unreachable.
    measured : ndarray, shape (T, n, 6)
        ``reached`` plus the pose measurement noise.
    """

    readings: NDArray[np.float64]
    reached: NDArray[np.float64]
    measured: NDArray[np.float64]

    def dataset(self, trial: int, poses: slice = slice(None)) -> Measurements:
        """The measurements of one trial (optionally a slice of its poses)."""
        return Measurements(self.measured[trial, poses], self.readings[trial, poses])


def simulate_campaigns(
    nominal: Geometry,
    machines: MachineBatch,
    commanded: NDArray[np.float64],
    leg_noise: NDArray[np.float64],
    pose_noise: NDArray[np.float64],
    strict: bool = True,
) -> CampaignData:
    """Steps 2 to 4 of the protocol for ``T`` trials.

    Parameters
    ----------
    nominal : Geometry
        The controller's geometry.
    machines : MachineBatch
        The ``T`` true machines.
    commanded : ndarray, shape (T, n, 6)
    leg_noise, pose_noise : ndarray, shape (T, n, 6)
        Leg sensor errors (mm) and pose measurement errors (mm, rad).
    strict : bool
        Raise :class:`~hexcal.errors.SimulationError` on an unreachable pose (else NaN).
    """
    readings = leg_readings(nominal, inverse_kinematics(nominal, commanded))
    reached = machines.reach(readings, commanded, nominal.euler, strict, sensor=leg_noise)
    return CampaignData(readings, reached, reached + pose_noise)


def simulate_measurements(
    nominal: Geometry,
    true: Geometry,
    poses: NDArray[np.float64],
    noise: NoiseModel | None = None,
    rng: np.random.Generator | int | None = None,
    ids: tuple[str, ...] | None = None,
) -> Measurements:
    """Simulated measurements of commanded poses on a true machine (the paper's protocol).

    Leg readings come from the nominal inverse kinematics; the true machine reaches the
    forward kinematics of its leg lengths plus the leg sensor error; the measured pose
    adds the pose measurement noise.

    Parameters
    ----------
    nominal, true : Geometry
    poses : array_like, shape (m, 6)
        Commanded poses.
    noise : NoiseModel, optional
        Default the paper's.
    rng : Generator, int or None
        Leg errors are drawn first, then pose errors.
    ids : tuple of str, optional

    Returns
    -------
    Measurements

    Examples
    --------
    >>> from hexcal.core import NoiseModel, preset
    >>> nominal = preset("paper-hmt")
    >>> data = simulate_measurements(nominal, nominal, np.zeros((2, 6)), NoiseModel(0, 0, 0), rng=0)
    >>> bool(np.allclose(data.poses, 0, atol=1e-9)), data.readings.shape
    (True, (2, 6))
    """
    noise = NoiseModel() if noise is None else noise
    rng = np.random.default_rng(rng)
    poses = np.asarray(poses, dtype=float).reshape(-1, 6)
    m = poses.shape[0]
    machine = MachineBatch.from_geometry(true)
    sensor = noise.leg_errors(rng, (m,))
    campaign = simulate_campaigns(
        nominal, machine, poses[None], sensor[None], noise.pose_errors(rng, (m,))[None]
    )
    return Measurements(campaign.measured[0], campaign.readings[0], ids or ())


def simulate_session(
    nominal: Geometry,
    true: Geometry,
    instrument: MeasurementModel | None,
    poses: NDArray[np.float64],
    noise: NoiseModel | None = None,
    rng: np.random.Generator | int | None = None,
    ids: tuple[str, ...] | None = None,
    covariates: Covariates | None = None,
    **options: Any,
) -> Session:
    """A simulated session of any instrument (the paper's protocol, steps 2 to 4).

    Leg readings come from the nominal inverse kinematics of the commanded ``poses``; the
    true machine reaches the forward kinematics of its leg lengths plus the leg sensor error;
    the instrument (its true setup: the frame known) records what it sees there plus its
    noise (:meth:`MeasurementModel.simulate`; ``options`` such as a target ``missing_rate``).
    Leg errors are drawn first, then the instrument's. ``noise=None`` means the seed paper's.
    ``covariates`` (of the commanded poses: time, leg temperatures, payload) are carried into
    the data, row by row (not yet simulated: the machine does not warm or give).

    Examples
    --------
    >>> from hexcal.core import NoiseModel, preset
    >>> from hexcal.instruments import FullPoseModel
    >>> nominal = preset("paper-hmt")
    >>> quiet = NoiseModel(0, 0, 0)
    >>> session = simulate_session(nominal, nominal, FullPoseModel(), np.zeros((2, 6)), quiet, 0)
    >>> len(session), session.instrument.name
    (2, 'pose')
    """
    from hexcal.instruments.registry import full_pose

    instrument = full_pose() if instrument is None else instrument
    if instrument.unregistered:
        raise SimulationError("simulation needs the true instrument frame (not auto)")
    noise = NoiseModel() if noise is None else noise
    rng = np.random.default_rng(rng)
    poses = np.asarray(poses, dtype=float).reshape(-1, 6)
    machine = MachineBatch.from_geometry(true)
    sensor = noise.leg_errors(rng, (len(poses),))
    readings = leg_readings(nominal, inverse_kinematics(nominal, poses))
    reached = machine.reach(readings[None], poses[None], nominal.euler, sensor=sensor[None])
    data = instrument.simulate(
        instrument.parameters().values,
        reached[0],
        readings,
        nominal.euler,
        noise,
        rng,
        tuple(ids or ()),
        **options,
    )
    if covariates:  # the rows recorded (a pose with every target lost is not), by their ids
        row = {label: k for k, label in enumerate(ids or (str(k + 1) for k in range(len(poses))))}
        data = data.replace(covariates=covariates.subset([row[i] for i in instrument.ids(data)]))
    return Session(data, instrument)


def validate(
    nominal: Geometry,
    machines: MachineBatch,
    targets: NDArray[np.float64],
    vectors: NDArray[np.float64] | None = None,
    identified: MachineBatch | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Step 6: position (mm) and orientation (rad) errors ``(T, v)`` at the targets.

    The controller commands targets ``(T, v, 6)`` with the nominal parameters, with the
    identified 42-vectors ``vectors`` ``(T, 42)`` (and the nominal leg gains), or with the
    ``identified`` machines; the true ``machines`` go where their forward kinematics says.
    NaN rows for failed identifications (NaN vectors) and for targets the true machine cannot
    reach.
    """
    euler = nominal.euler
    if vectors is not None:
        ok = ~np.isnan(vectors[:, 0])
        identified = MachineBatch.from_vectors(
            np.where(ok[:, None], vectors, nominal.to_vector()), nominal.leg_gains
        )
    elif identified is not None:
        ok = np.all(np.isfinite(identified.legs), axis=1)
    if identified is None:
        commands = leg_readings(nominal, inverse_kinematics(nominal, targets))
        ok = np.ones(len(targets), dtype=bool)
    else:
        commands = identified.commands(targets, euler)
    reached = machines.reach(commands, targets, euler, strict=False)
    position, orientation = pose_errors(targets, reached, euler)
    position[~ok], orientation[~ok] = np.nan, np.nan
    return position, orientation
