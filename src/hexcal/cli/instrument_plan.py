"""Planning and Monte Carlo with an instrument setup: ``hexcal observability --setup``,
``hexcal select --setup`` and ``hexcal simulate --setup`` (issue 9).

- :func:`observability_with_setup`: parameters, gauge freedoms, rank, the combinations not
  determined beyond the gauges, and the Cramér–Rao σ of the gauge-fixed parameters of a pose
  set for the instrument of the setup, beside a full-pose instrument on the same poses (a single
  target sees less than a full pose);
- :func:`select_with_setup`: poses optimal for that instrument (greedy + exchange on the
  per-pose information with the poses and the gauges eliminated), against random candidates;
- :func:`simulate_with_setup`: campaigns with the setup as the true one: each trial identifies
  from ``instrument_frame: auto``; the machine's identification error against its Cramér–Rao
  bound and held-out target positions, per strategy and pose count.

Imports only the standard library and :mod:`hexcal.cli.common` at its top.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

from hexcal.cli.common import (
    CommandError,
    candidate_spec,
    check_outputs,
    check_trials,
    feasible_candidates,
    int_list,
    load_geometry,
    noise_from_args,
    parse_noise,
    warn,
)


def _problem(geometry: Any, setup: Any, poses: Any, fit: str) -> tuple[Any, Any]:
    """The noise-free identification problem of ``setup`` at ``poses`` and its true poses."""
    from hexcal.estimation import Problem, instrument_parameters
    from hexcal.instruments import instrument_model, simulate_target_measurements, simulate_tool_measurements

    if setup.auto:  # the ranks and (isotropic) bounds do not depend on where the instrument stands
        setup = setup.with_vector(setup.vector())
    if setup.kind == "targets":
        data = simulate_target_measurements(geometry, geometry, setup, poses)
    else:
        data = simulate_tool_measurements(geometry, geometry, setup, poses)
    params = instrument_parameters(geometry, setup, fit)
    problem = Problem(geometry, data, instrument_model(setup), parameters=params)
    return problem, problem.model.start_poses(geometry, setup.vector(), data)


def instrument_plan(geometry: Any, setup: Any, poses: Any, noise: Any, fit: str) -> dict[str, Any]:
    """Parameters, gauges, rank, unidentifiable combinations and Cramér–Rao σ of a pose set."""
    import numpy as np

    from hexcal.core import numerical_rank, scaled_svd
    from hexcal.estimation import gauge_fixed_covariance, gauge_freedoms, projected_jacobian, unidentifiable

    problem, true = _problem(geometry, setup, poses, fit)
    jac = projected_jacobian(problem, noise, problem.full0, true)
    gauge = gauge_freedoms(problem, problem.full0)
    sigma = np.sqrt(np.clip(np.diag(gauge_fixed_covariance(problem, jac, gauge)), 0, None))
    names = np.array(problem.names)
    joints = sigma[np.char.startswith(names, "u") | np.char.startswith(names, "s")]
    l0 = sigma[np.char.startswith(names, "l0")]
    return {
        "instrument": f"{len(setup.target_names)} target(s)" if setup.kind == "targets" else "tool pose",
        "poses": len(poses),
        "parameters": problem.n_free,
        "machine_parameters": int(problem.machine_mask.sum()),
        "gauges": gauge.size,
        "gauge_labels": list(gauge.labels),
        "rank": numerical_rank(scaled_svd(jac).singular_values),
        "unidentifiable": unidentifiable(problem, jac, gauge),
        "joint_bound_mm": float(np.median(joints)) if joints.size else None,
        "joint_bound_max_mm": float(joints.max()) if joints.size else None,
        "l0_bound_mm": float(np.median(l0)) if l0.size else None,
        "stderr_bound": dict(zip(problem.names, sigma.tolist(), strict=True)),
    }


def _full_pose(setup: Any) -> Any:
    import numpy as np

    from hexcal.instruments import Setup

    return Setup(setup.frame_or_identity(), tool=np.zeros(6), fixed=("instrument_frame", "tool"))


def _plan_noise(args: argparse.Namespace) -> Any:
    if args.noise_dist not in ("uniform", "normal"):
        raise CommandError(f"--noise-dist: unknown {args.noise_dist!r}; choose from uniform, normal")
    return parse_noise(args.noise, args.noise_dist)


def observability_with_setup(args: argparse.Namespace) -> None:
    """``hexcal observability --setup``: what this instrument identifies from these poses."""
    from hexcal.cli.instrument import load_setup_for, setup_fit
    from hexcal.io import atomic_write, read_poses
    from hexcal.report import render

    check_outputs(args.json)
    geometry = load_geometry(args.geometry, args.euler)
    setup = load_setup_for(args.setup, geometry)
    poses, _ = read_poses(args.poses, geometry.euler)
    noise = _plan_noise(args)
    data = instrument_plan(geometry, setup, poses, noise, setup_fit(args, setup))
    full = instrument_plan(geometry, _full_pose(setup), poses, noise, args.fit)
    data["full_pose_joint_bound_mm"] = full["joint_bound_mm"]
    print(render("instrument_plan", data))
    if args.json:
        with atomic_write(args.json) as fh:
            fh.write(render("instrument_plan", data, "json"))
        print(f"wrote {args.json}")


def select_with_setup(args: argparse.Namespace) -> None:
    """``hexcal select --setup``: poses optimal for this instrument (greedy + exchange)."""
    import numpy as np

    from hexcal.cli.instrument import load_setup_for, setup_fit
    from hexcal.design import CRITERIA, select_poses
    from hexcal.estimation import complement_basis, gauge_freedoms, projected_jacobian
    from hexcal.io import atomic_write, write_poses
    from hexcal.report import render

    check_outputs(args.out, args.json)
    if args.criterion not in CRITERIA:
        raise CommandError(f"--criterion: unknown {args.criterion!r}; choose from {', '.join(CRITERIA)}")
    if args.strategy != "optimal":
        raise CommandError("--strategy: with --setup only optimal")
    geometry = load_geometry(args.geometry, args.euler)
    setup = load_setup_for(args.setup, geometry)
    noise = _plan_noise(args)
    fit = setup_fit(args, setup)
    candidates, cand_ids = candidate_spec(args.candidates, geometry, args.seed)
    feasible, kept, warning = feasible_candidates(geometry, candidates, cand_ids, args.min_distance)
    if args.n > len(kept):
        raise CommandError(f"--n {args.n}: only {len(kept)} feasible candidate pose(s)")
    problem, true = _problem(geometry, setup, feasible, fit)
    gauge = gauge_freedoms(problem, problem.full0)
    jac = projected_jacobian(problem, noise, problem.full0, true)
    blocks = jac.reshape(len(feasible), -1, problem.n_free) @ complement_basis(gauge)
    rng = np.random.default_rng(args.seed)
    chosen = select_poses(blocks, args.n, args.criterion, rng, exchange=not args.no_exchange).indices
    poses, ids = feasible[chosen], [kept[k] for k in chosen]
    data = instrument_plan(geometry, setup, poses, noise, fit)
    if data["rank"] < data["parameters"] - data["gauges"]:
        raise CommandError(
            f"--n {args.n}: these poses cannot identify every parameter with this instrument "
            f"({'; '.join(data['unidentifiable'][:2])}): select more poses"
        )
    random_set = feasible[rng.permutation(len(feasible))[: args.n]]
    random_plan = instrument_plan(geometry, setup, random_set, noise, fit)
    data["selection"] = {
        "n": args.n,
        "candidates": len(kept),
        "criterion": args.criterion,
        "random_joint_bound_mm": random_plan["joint_bound_mm"],
    }
    print(render("instrument_plan", data))
    if warning:
        warn(warning)
    write_poses(args.out, poses, ids, comment=f"hexcal select --setup {args.setup}: {args.criterion}-optimal")
    if args.json:
        with atomic_write(args.json) as fh:
            fh.write(render("instrument_plan", data, "json"))
    print(f"wrote {args.n} pose(s) to {args.out}")


# -- simulate ---------------------------------------------------------------------------------


def _cell(
    nominal: Any, true: Any, setup: Any, strategy: Any, n: int, noise: Any, args: Any, key: int
) -> dict:
    """Trials of one strategy and pose count: machine error, its bound, held-out targets."""
    import numpy as np

    from hexcal.core import random_poses
    from hexcal.errors import HexcalError
    from hexcal.estimation import (
        Problem,
        apply_convention,
        gauge_freedoms,
        identify_instrument,
        instrument_parameters,
        model_cramer_rao,
    )
    from hexcal.instruments import Setup, instrument_model, predict_instrument, simulate_target_measurements

    start = Setup(None, setup.targets, fixed=setup.fixed, euler=setup.euler)
    full_true = np.concatenate([true.to_vector(gains=True), setup.vector()])
    held = simulate_target_measurements(nominal, true, setup, random_poses(nominal, 30, args.seed + 7))
    errs, bounds, pred, seconds = [], [], [], []
    for trial in range(args.trials):
        rng = np.random.default_rng([args.seed, key, trial])
        try:
            poses = strategy(nominal, n, rng)
            data = simulate_target_measurements(nominal, true, setup, poses, noise, args.missing_rate, rng)
            t0 = time.perf_counter()
            out = identify_instrument(nominal, data, start, noise)
            seconds.append(time.perf_counter() - t0)
        except (HexcalError, ValueError):
            continue
        params = instrument_parameters(nominal, out.setup)
        problem = Problem(nominal, data, instrument_model(out.setup), parameters=params)
        fixed_true = apply_convention(problem, full_true, gauge_freedoms(problem, full_true))
        got = np.concatenate([out.geometry.to_vector(gains=True), out.setup.vector()])
        machine = problem.mask[:48]
        errs.append((got - fixed_true)[:48][machine])
        bounds.append(np.diag(model_cramer_rao(problem, noise, full_true))[: int(machine.sum())])
        p = predict_instrument(out.geometry, out.setup, held.readings)
        pred.append(np.nanmean(np.sum((p - held.targets) ** 2, axis=-1)))
    ok = len(errs)
    err = float(np.sqrt(np.mean(np.square(errs)))) if ok else float("nan")
    bound = float(np.sqrt(np.mean(bounds))) if ok else float("nan")
    return {
        "poses": n,
        "ok": ok,
        "error_mm": err,
        "bound_mm": bound,
        "ratio": err / bound if ok else float("nan"),
        "heldout_mm": float(np.sqrt(np.mean(pred))) if ok else float("nan"),
        "seconds": float(np.median(seconds)) if seconds else float("nan"),
    }


def simulate_with_setup(args: argparse.Namespace) -> None:
    """``hexcal simulate --setup``: campaigns with a tracker; the setup file is the true setup
    (frame given), and each trial identifies from ``auto`` and the setup's targets."""
    from hexcal.cli.instrument import load_setup_for
    from hexcal.io import atomic_write
    from hexcal.report import render
    from hexcal.simulation import STRATEGIES

    check_trials(args.trials)
    if args.true == "random":
        raise CommandError("--true random is not available with --setup; give the true geometry")
    if not 0.0 <= args.missing_rate < 1.0:
        raise CommandError(f"--missing-rate must be in [0, 1), got {args.missing_rate}")
    nominal = load_geometry(args.geometry)
    true = load_geometry(args.true, nominal.euler)
    setup = load_setup_for(args.setup, nominal)
    if setup.auto or setup.kind != "targets":
        raise CommandError(f"{args.setup}: simulate --setup needs targets and the true instrument frame")
    names = [s.strip() for s in args.strategies.split(",") if s.strip()]
    bad = [s for s in names if s not in STRATEGIES]
    if bad or not names:
        raise CommandError(f"--strategies: with --setup choose from {', '.join(STRATEGIES)}")
    counts = int_list(args.poses, "--poses")
    noise = noise_from_args(args)
    cells = []
    for k, name in enumerate(names):
        for j, n in enumerate(counts):
            cell = _cell(nominal, true, setup, STRATEGIES[name], n, noise, args, 100 * k + j)
            cells.append({"strategy": name, **cell})
    data = {
        "instrument": f"{len(setup.target_names)} target(s), frame auto",
        "trials": args.trials,
        "seed": args.seed,
        "missing_rate": args.missing_rate,
        "noise": noise.describe(),
        "cells": cells,
    }
    print(render("instrument_study", data))
    if args.out:
        from pathlib import Path

        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        with atomic_write(out / "study.json") as fh:
            fh.write(render("instrument_study", data, "json"))
        print(f"wrote {out / 'study.json'}")
