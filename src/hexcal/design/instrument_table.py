"""What an instrument identifies from a pose set: parameters, gauges, rank, bounds.

For a machine, an instrument and a pose set, :func:`instrument_plan` builds the noise-free
identification problem (:func:`hexcal.estimation.uncertainty.planned_session`) and reports
the parameters varied, the gauge freedoms (:mod:`hexcal.estimation.gauge`), the rank of the
pose-eliminated Jacobian, the combinations no data determine beyond the gauges (named), and
the Cramér–Rao σ of every gauge-fixed parameter (infinite for a parameter that an
undetermined combination moves: the pose set cannot identify it). The same analysis serves
every instrument (a full pose, a 6-DOF tool, targets) with its frame known or free.
:func:`instrument_identifiability` tabulates it for the common instruments (the README table),
:func:`format_table` prints it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from hexcal.core.geometry import Geometry
from hexcal.core.linalg import numerical_rank, scaled_svd
from hexcal.core.noise import NoiseModel
from hexcal.estimation.gauge import complement_basis, gauge_freedoms, unidentifiable
from hexcal.estimation.problem import Problem
from hexcal.estimation.uncertainty import gauge_fixed_covariance, planned_session, projected_jacobian
from hexcal.instruments.base import MeasurementModel
from hexcal.instruments.pose import FullPoseModel, ToolModel
from hexcal.instruments.setup import Setup
from hexcal.instruments.targets import TargetModel

#: The frame the table's instrument stands in (any frame gives the same ranks).
TABLE_FRAME = np.array([2500.0, -800.0, 300.0, 0.1, -0.2, 0.6])
TABLE_TARGETS = {"t1": [0.0, 0.0, 60.0], "t2": [150.0, 20.0, 55.0], "t3": [-40.0, 160.0, 70.0]}


def planned_instrument(geometry: Geometry, instrument: MeasurementModel | None) -> MeasurementModel | None:
    """The instrument to plan for through the identification :class:`Problem`, or ``None``
    where the classical analysis of the 48 linear-leg parameters from a full pose applies.

    The Problem serves every instrument and leg model; the classical pose-set analysis (the
    leg-length Jacobian, the least-squares estimators ``length`` and ``paper``) knows only a
    full pose and linear legs. A leg model with terms of its own (``stroke``) therefore plans
    through the Problem too, with the full pose in the base frame when no setup is given.
    """
    if instrument is not None and not instrument.determines_pose:
        return instrument
    if geometry.leg_model.terms:
        return instrument if instrument is not None else FullPoseModel()
    return None


def default_flags(geometry: Geometry) -> np.ndarray:
    """The machine parameters planned for by default: joints and ``l0``, and the leg model's own
    terms when it has them (as ``identify`` fits them)."""
    from hexcal.calibration.leg_model_choice import fit_for

    return np.asarray(geometry.machine_parameters(fit_for(None, geometry.leg_model)).vary, dtype=bool)


def plan_problem(
    geometry: Geometry,
    instrument: MeasurementModel,
    poses: ArrayLike,
    fit: str | None = None,
    fix: Any = (),
    mask: ArrayLike | None = None,
    covariates: Any = None,
) -> Problem:
    """The noise-free problem of ``instrument`` at ``poses`` (an unknown frame stands at its
    start: ranks and isotropic bounds do not depend on where the instrument stands), under
    the poses' ``covariates`` for a leg model that reads them."""
    if instrument.unregistered:
        instrument = instrument.with_values(instrument.parameters().values)
    if mask is None and fit is None:
        mask = default_flags(geometry)
    session = planned_session(geometry, instrument, poses, covariates)
    return Problem(geometry, session, mask=mask, fit=fit, fix=fix)


def instrument_plan(
    geometry: Geometry,
    instrument: MeasurementModel,
    poses: ArrayLike,
    noise: NoiseModel | None = None,
    fit: str | None = None,
    fix: Any = (),
) -> dict[str, Any]:
    """Parameters, gauges, rank, unidentifiable combinations and Cramér–Rao σ of a pose set.

    Returns
    -------
    dict
        ``instrument``, ``poses``, ``parameters``, ``machine_parameters``, ``gauges``,
        ``gauge_labels``, ``rank``, ``identifiable`` (rank = parameters - gauges),
        ``unidentifiable`` (combinations), ``stderr_bound`` (name -> σ, inf where a
        combination is undetermined), ``joint_bound_mm`` / ``joint_bound_max_mm`` /
        ``l0_bound_mm`` (median and largest of the joints' and ``l0``'s σ; inf when any is
        undetermined).
    """
    noise = NoiseModel() if noise is None else noise
    problem = plan_problem(geometry, instrument, poses, fit, fix)
    jac = projected_jacobian(problem, noise)
    gauge = gauge_freedoms(problem, problem.full0)
    reduced = jac @ complement_basis(gauge)
    rank = numerical_rank(scaled_svd(reduced).singular_values)
    weak = unidentifiable(problem, jac, gauge)
    sigma = np.sqrt(np.clip(np.diag(gauge_fixed_covariance(problem, jac, gauge)), 0, None))
    if weak:  # what the null space moves is not determined at all
        from hexcal.core.linalg import null_space

        basis, _ = null_space(reduced)
        moved = np.any(np.abs(complement_basis(gauge) @ basis.T) > 1e-6, axis=1) if basis.size else []
        sigma = np.where(moved, np.inf, sigma)
    names = np.array(problem.names)
    joints = sigma[np.char.startswith(names, "u") | np.char.startswith(names, "s")]
    l0 = sigma[np.char.startswith(names, "l0")]
    return {
        "instrument": instrument.describe(),
        "poses": len(problem),
        "parameters": problem.n_free,
        "machine_parameters": int(problem.machine_mask.sum()),
        "gauges": gauge.size,
        "gauge_labels": list(gauge.labels),
        "rank": rank,
        "identifiable": not weak,
        "unidentifiable": weak,
        "joint_bound_mm": float(np.median(joints)) if joints.size else None,
        "joint_bound_max_mm": float(joints.max()) if joints.size else None,
        "l0_bound_mm": float(np.median(l0)) if l0.size else None,
        "stderr_bound": dict(zip(problem.names, sigma.tolist(), strict=True)),
    }


def _instruments(frame_free: bool) -> list[tuple[str, MeasurementModel]]:
    fixed_frame = () if frame_free else ("instrument_frame",)
    return [
        ("full pose", ToolModel(Setup(TABLE_FRAME, tool=np.zeros(6), fixed=(*fixed_frame, "tool")))),
        (
            "6-DOF tool",
            ToolModel(Setup(TABLE_FRAME, tool=[20.0, -10.0, 80.0, 0.0, 0.0, 0.3], fixed=fixed_frame)),
        ),
        ("one target", TargetModel(Setup(TABLE_FRAME, {"t1": TABLE_TARGETS["t1"]}, fixed=fixed_frame))),
        ("three targets", TargetModel(Setup(TABLE_FRAME, TABLE_TARGETS, fixed=fixed_frame))),
    ]


def instrument_identifiability(
    geometry: Geometry, poses: ArrayLike, fit: str | None = None, noise: NoiseModel | None = None
) -> list[dict[str, Any]]:
    """Identifiability of machine and instrument parameters per instrument, frame known and free.

    Parameters
    ----------
    geometry : Geometry
        The machine (nominal = true: a planning question).
    poses : array_like, shape (m, 6)
        Measurement poses.
    fit : str, optional
        Machine groups (default ``joints,l0``); the instrument's free groups are added.
    noise : NoiseModel, optional

    Returns
    -------
    list of dict
        :func:`instrument_plan` of each, with ``instrument`` the table's label and ``frame``
        (``known``/``free``).
    """
    rows = []
    for frame_free in (False, True):
        for label, instrument in _instruments(frame_free):
            groups = None if fit is None else ",".join([fit, "frame", "tool", "targets"])
            plan = instrument_plan(geometry, instrument, poses, noise, _present(groups, instrument))
            rows.append(plan | {"instrument": label, "frame": "free" if frame_free else "known"})
    return rows


def _present(groups: str | None, instrument: MeasurementModel) -> str | None:
    """The groups of ``groups`` that the machine or this instrument has."""
    if groups is None:
        return None
    own = set(instrument.parameters().groups) | {"joints", "base", "platform", "l0", "gains"}
    return ",".join(g for g in groups.split(",") if g in own)


def format_table(rows: list[dict[str, Any]]) -> str:
    """A Markdown table of :func:`instrument_identifiability`."""
    out = [
        "| instrument | frame | parameters (machine + setup) | gauge freedoms | rank "
        "| all others identified | median joint σ bound (µm) |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        setup_n = r["parameters"] - r["machine_parameters"]
        ok = (
            "yes"
            if r["identifiable"]
            else f"no: {len(r['unidentifiable'])} more ({'; '.join(r['unidentifiable'])})"
        )
        bound = r["joint_bound_mm"]
        shown = f"{1000 * bound:.1f}" if bound is not None and np.isfinite(bound) else "∞"
        out.append(
            f"| {r['instrument']} | {r['frame']} | {r['machine_parameters']} + {setup_n} | "
            f"{r['gauges']} | {r['rank']} | {ok} | {shown} |"
        )
    return "\n".join(out)
