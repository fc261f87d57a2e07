"""Trials of campaigns measured by any instrument: the protocol's steps 2 to 6 for a session.

For an instrument other than the full pose (targets, a tool, an instrument in its own frame)
each trial simulates the session the instrument records at the commanded poses
(:func:`hexcal.simulation.protocol.simulate_session`: the true machine, the true setup, the
noise), identifies it from the start the user would have (an unknown frame ``auto``, nominal
targets or tool) with :func:`hexcal.calibration.estimate`, and measures:

- the mean absolute error of the machine's joints and initial lengths against the truth
  expressed under the identification's gauge convention (the frames no data can fix are
  those of the convention for both);
- its Cramér–Rao bound at the truth (gauge-fixed the same way);
- the validation pose error: the controller commands random workspace poses with the
  identified parameters and the real machine (in the convention's frames) goes where its
  forward kinematics says, noise-free, as for the full pose.

A failed identification or an unreachable pose gives NaN for the trial. Each trial's data come
from its own generator and its frame is registered on its own; the trials of a cell are then
identified together by the solvers of the built-in estimators (a stack of the trials,
:func:`hexcal.estimation.batched.estimate_stack`), or one at a time by a registered estimator
without one, so the numbers do not depend on the executor, and on the chunks only in the last
digits.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexcal.core import Geometry, NoiseModel
from hexcal.errors import HexcalError
from hexcal.instruments.base import MeasurementModel, Session
from hexcal.simulation.protocol import MachineBatch, simulate_session, validate

#: Length parameters whose mean absolute error a study reports (as for the full pose).
_LENGTH_GROUPS = ("joints", "l0")


@dataclass(frozen=True)
class InstrumentCampaign:
    """The instrument of a study: the ``true`` setup that records the data (frame known) and the
    ``start`` the identification begins from (its frame ``auto``, nominal targets or tool),
    the machine groups ``fit`` and the simulation ``options`` (a target ``missing_rate``)."""

    true: MeasurementModel
    start: MeasurementModel
    fit: str = "joints,l0"
    options: tuple[tuple[str, Any], ...] = ()


def _length_rows(names: tuple[str, ...], geometry: Geometry) -> NDArray[np.bool_]:
    groups = geometry.machine_parameters().groups
    lengths = {n for g in _LENGTH_GROUPS for n in groups[g]}
    return np.array([n in lengths for n in names])


def _simulate(nominal, true, campaign, commanded, noise, rng):
    """One trial's session, or None where the true machine cannot reach a pose."""
    try:
        return simulate_session(nominal, true, campaign.true, commanded, noise, rng, **dict(campaign.options))
    except (HexcalError, ValueError):
        return None


def _evaluate(nominal, true, campaign, session, values, noise, targets):
    """``(error, bound, position errors, orientation errors)`` of one trial's identified
    ``values`` (all the problem's parameters, under the gauge convention)."""
    from hexcal.estimation import Problem, apply_convention, cramer_rao, gauge_freedoms

    start = session.instrument
    problem = Problem(nominal, Session(session.data, start), fit=campaign.fit)
    fitted = problem.geometry(values)
    calibrated = start.with_values(values[problem.parts[0].block])
    problem = Problem(fitted, Session(session.data, calibrated), fit=campaign.fit)
    full_true = np.array(problem.full0)
    full_true[problem.machine] = true.machine_vector()
    full_true[problem.parts[0].block] = campaign.true.parameters().values
    gauge = gauge_freedoms(problem, full_true)
    truth = apply_convention(problem, full_true, gauge) if gauge.size else full_true
    rows = _length_rows(problem.names, nominal)
    error = float(np.mean(np.abs(problem.full0[problem.mask] - truth[problem.mask])[rows]))
    try:
        cov = cramer_rao(problem, noise, truth)
        bound = float(np.sqrt(2 / np.pi) * np.mean(np.sqrt(np.clip(np.diag(cov), 0, None))[rows]))
    except (HexcalError, ValueError, np.linalg.LinAlgError):
        bound = float("nan")
    if gauge.size:  # the frames that fit the validation poses best, as a re-registration would
        truth = aligned_truth(problem, truth, targets)
    real = MachineBatch.from_geometry(problem.geometry(truth))
    position, orientation = validate(
        nominal, real, targets[None], identified=MachineBatch.from_geometry(fitted)
    )
    return error, bound, position[0], orientation[0]


def aligned_truth(
    problem: Any, truth: NDArray[np.float64], targets: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The truth moved along the gauge freedoms (rigid motions of the base and platform frames,
    which no measurement distinguishes) so that its pose errors against the identified machine
    at ``targets`` are smallest (first order, angles weighted by the platform radius): the
    validation error then describes the calibration, not the arbitrary frames."""
    from hexcal.calibration.accuracy import pose_error_map, rotation_vector_map
    from hexcal.estimation import gauge_freedoms

    gauge = gauge_freedoms(problem, truth)
    names = problem.names
    rows = np.isin(names, problem.start.machine_names())
    mask = np.isin(problem.start.machine_names(), names)
    e = pose_error_map(problem.start, targets, mask)  # (v, 6, n_machine)
    w = rotation_vector_map(problem.start, targets)
    radius = float(np.max(np.linalg.norm(problem.start.platform_joints[:, :2], axis=1)))
    e = np.concatenate([e[:, :3], radius * np.einsum("tij,tjk->tik", w, e[:, 3:])], axis=1).reshape(
        -1, mask.sum()
    )
    delta = (truth - problem.full0)[problem.mask][rows]
    g = (gauge.generators * problem.scale[:, None])[rows]
    a, *_ = np.linalg.lstsq(e @ g, e @ delta, rcond=None)
    moved = np.array(truth)
    moved[problem.mask] = truth[problem.mask] - (gauge.generators * problem.scale[:, None]) @ a
    return moved


def instrument_cell(
    nominal: Geometry,
    true_machines: list[Geometry],
    campaign: InstrumentCampaign,
    commanded: NDArray[np.float64],
    noise: NoiseModel,
    rngs: list[np.random.Generator],
    method: str,
    targets: NDArray[np.float64],
) -> dict[str, NDArray[np.float64]]:
    """The trials of one cell of a study measured by ``campaign``'s instrument: each trial's
    session simulated from its own generator, the frames registered per trial, the trials of
    the cell identified together (:func:`hexcal.estimation.estimate_stack`), then judged."""
    from hexcal.calibration import register_sessions

    t, v = len(true_machines), targets.shape[1]
    errors, bounds = np.full(t, np.nan), np.full(t, np.nan)
    pos, ang = np.full((t, v), np.nan), np.full((t, v), np.nan)
    sessions, trials = [], []
    for k, true in enumerate(true_machines):  # the data of each trial (its own random stream)
        session = _simulate(nominal, true, campaign, commanded[k], noise, rngs[k])
        if session is None:
            continue
        try:
            registered, _ = register_sessions(nominal, [Session(session.data, campaign.start)])
        except (HexcalError, ValueError, np.linalg.LinAlgError):
            continue
        sessions.append(registered[0])
        trials.append(k)
    for j, values in enumerate(_identified(nominal, sessions, campaign, method, noise)):
        if values is not None:
            k = trials[j]
            errors[k], bounds[k], pos[k], ang[k] = _evaluate(
                nominal, true_machines[k], campaign, sessions[j], values, noise, targets[k]
            )
    return {
        "errors": errors,
        "bounds": bounds,
        "position_rms": np.sqrt(np.mean(pos**2, axis=1)),
        "orientation_rms": np.sqrt(np.mean(ang**2, axis=1)),
    }


def _identified(
    nominal: Geometry, sessions: list[Session], campaign: InstrumentCampaign, method: str, noise: NoiseModel
) -> list[NDArray[np.float64] | None]:
    """Every trial's identified parameters (all the problem's; None where it failed): the trials
    together by the batched solvers of the built-in estimators, one at a time by any other."""
    from hexcal.estimation import BATCH_METHODS, Problem, Stack, estimate_stack, get_estimator

    if not sessions:
        return []
    if method in BATCH_METHODS:
        try:
            stack = Stack.of_sessions(nominal, sessions, fit=campaign.fit)
            batch = estimate_stack(stack, method, noise)
        except (HexcalError, ValueError):
            return [None] * len(sessions)
        out: list[NDArray[np.float64] | None] = []
        for j in range(len(sessions)):
            values = np.array(stack.full0[j])
            values[stack.mask] = batch.values[j]
            out.append(values if batch.converged[j] else None)
        return out
    estimator, out = get_estimator(method), []
    for session in sessions:  # an estimator without a batched solver: one trial at a time
        try:
            problem = Problem(nominal, session, fit=campaign.fit)
            result = estimator.fit(problem, noise)
        except (HexcalError, ValueError, np.linalg.LinAlgError):
            out.append(None)
            continue
        values = np.array(problem.full0)
        values[problem.mask] = result.values
        out.append(values)
    return out


def instrument_campaign(
    instrument: MeasurementModel, fit: str = "joints,l0", **options: Any
) -> InstrumentCampaign | None:
    """The campaign a study simulates for ``instrument`` (its true setup): identified from the
    start a user would have (:meth:`MeasurementModel.as_start`: an unknown frame ``auto``),
    with the simulation ``options``; None for the full pose in the base frame without options
    (the batched path of :mod:`hexcal.simulation.study`)."""
    from hexcal.errors import SimulationError

    if instrument.unregistered:
        raise SimulationError("a study needs the true instrument frame (not auto): it is the simulated truth")
    options = {k: v for k, v in options.items() if v}
    if instrument.determines_pose and instrument.name == "pose" and not options:
        return None
    return InstrumentCampaign(instrument, instrument.as_start(), fit, tuple(options.items()))
