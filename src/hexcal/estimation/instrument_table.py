"""Which instrument identifies which parameters: ranks and null spaces computed by hexcal.

For a machine and a pose set, :func:`instrument_identifiability` builds, for each instrument
(full pose, a 6-DOF tool, one target, three targets) with the instrument frame known or free,
the noise-free identification problem and reports the number of parameters, the gauge
freedoms (:mod:`hexcal.estimation.gauge`), the rank of the projected Jacobian
(:mod:`hexcal.estimation.model_bounds`) and the combinations no data determine beyond the
gauges. :func:`format_table` prints it (the README table).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from hexcal.core.geometry import Geometry
from hexcal.core.linalg import numerical_rank, scaled_svd
from hexcal.core.noise import NoiseModel
from hexcal.estimation.gauge import gauge_freedoms, unidentifiable
from hexcal.estimation.instrument import instrument_parameters
from hexcal.estimation.model_bounds import gauge_fixed_covariance, projected_jacobian
from hexcal.estimation.problem import Problem
from hexcal.instruments.instrument_data import (
    instrument_model,
    simulate_target_measurements,
    simulate_tool_measurements,
)
from hexcal.instruments.setup import Setup

#: The frame the table's instrument stands in (any frame gives the same ranks).
TABLE_FRAME = np.array([2500.0, -800.0, 300.0, 0.1, -0.2, 0.6])
TABLE_TARGETS = {"t1": [0.0, 0.0, 60.0], "t2": [150.0, 20.0, 55.0], "t3": [-40.0, 160.0, 70.0]}


def _setups(frame_free: bool) -> list[tuple[str, Setup]]:
    fixed_frame = () if frame_free else ("instrument_frame",)
    return [
        ("full pose", Setup(TABLE_FRAME, tool=np.zeros(6), fixed=(*fixed_frame, "tool"))),
        ("6-DOF tool", Setup(TABLE_FRAME, tool=[20.0, -10.0, 80.0, 0.0, 0.0, 0.3], fixed=fixed_frame)),
        ("one target", Setup(TABLE_FRAME, {"t1": TABLE_TARGETS["t1"]}, fixed=fixed_frame)),
        ("three targets", Setup(TABLE_FRAME, TABLE_TARGETS, fixed=fixed_frame)),
    ]


def instrument_identifiability(
    geometry: Geometry, poses: ArrayLike, fit: str | None = None, noise: NoiseModel | None = None
) -> list[dict[str, Any]]:
    """Identifiability of machine and setup parameters per instrument, frame known and free.

    Parameters
    ----------
    geometry : Geometry
        The machine (nominal = true: a planning question).
    poses : array_like, shape (m, 6)
        Measurement poses.
    fit : str, optional
        Machine groups (default ``joints,l0``); the setup's free groups are added.
    noise : NoiseModel, optional

    Returns
    -------
    list of dict
        ``instrument``, ``frame`` (``known``/``free``), ``parameters``, ``gauges``, ``rank``,
        ``identifiable`` (rank = parameters - gauges), ``unidentifiable`` (combinations),
        ``joint_bound_mm`` (median Cramér–Rao σ of the gauge-fixed joint coordinates).
    """
    noise = NoiseModel() if noise is None else noise
    rows = []
    for frame_free in (False, True):
        for label, setup in _setups(frame_free):
            if setup.kind == "targets":
                data = simulate_target_measurements(geometry, geometry, setup, poses)
            else:
                data = simulate_tool_measurements(geometry, geometry, setup, poses)
            groups = None if fit is None else ",".join([fit, *[g for g in ("frame", setup.kind)]])
            params = instrument_parameters(geometry, setup, groups)
            problem = Problem(geometry, data, instrument_model(setup), parameters=params)
            true_poses = problem.model.start_poses(geometry, setup.vector(), data)
            jac = projected_jacobian(problem, noise, problem.full0, true_poses)
            gauge = gauge_freedoms(problem, problem.full0)
            rank = numerical_rank(scaled_svd(jac).singular_values)
            weak = unidentifiable(problem, jac, gauge)
            bound = np.sqrt(np.clip(np.diag(gauge_fixed_covariance(problem, jac, gauge)), 0, None))
            rows.append(
                {
                    "instrument": label,
                    "frame": "free" if frame_free else "known",
                    "parameters": problem.n_free,
                    "machine_parameters": int(problem.machine_mask.sum()),
                    "gauges": gauge.size,
                    "rank": rank,
                    "identifiable": rank == problem.n_free - gauge.size,
                    "unidentifiable": weak,
                    "joint_bound_mm": float(np.median(bound[:36])),
                }
            )
    return rows


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
        out.append(
            f"| {r['instrument']} | {r['frame']} | {r['machine_parameters']} + {setup_n} | "
            f"{r['gauges']} | {r['rank']} | {ok} | {1000 * r['joint_bound_mm']:.1f} |"
        )
    return "\n".join(out)
