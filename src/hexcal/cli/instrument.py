"""The instrument paths of the workflow commands: ``--setup FILE`` (issue 9).

A setup file (FORMATS.md "Measurement setup file") says what the instrument sees: target
positions (a laser tracker's reflectors) or a tool pose (a 6-DOF probe), in the instrument's
own frame, given or ``auto``. Each command of :mod:`hexcal.cli.calibrate`,
:mod:`hexcal.cli.plan` and :mod:`hexcal.cli.simulate` hands over to the function here when
``--setup`` is given:

- :func:`identify_with_setup`: maximum likelihood of machine and setup, with the frame
  registered (``auto``), the gauges removed by the documented convention, outliers checked (one
  target observation or a whole pose; ``--robust`` leaves them out); writes the calibrated
  geometry and, with ``--setup-out``, the calibrated setup;
- :func:`validate_with_setup`: held-out target (tool) positions predicted from leg readings;
- :func:`synthesize_with_setup`: simulated exports, targets lost at ``--missing-rate``;
- :func:`observability_with_setup`, :func:`select_with_setup`: planning for the instrument;
- :func:`simulate_with_setup`: Monte Carlo campaigns, identification error against its bound.

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

#: ``--delimiter`` words and the characters they stand for.
DELIMITER_WORDS = {",": ",", "comma": ",", ";": ";", "semicolon": ";", "tab": "\t"}


def export_options(p: argparse.ArgumentParser) -> None:
    """Add ``--delimiter`` and ``--decimal`` (instrument exports read with ``--setup``)."""
    p.add_argument(
        "--delimiter",
        choices=tuple(DELIMITER_WORDS),
        help="field separator of an instrument export (default: detected from the header)",
    )
    p.add_argument(
        "--decimal", choices=(".", ","), help="decimal mark of an instrument export (default: detected)"
    )


def _delimiter(args: argparse.Namespace) -> str | None:
    word = getattr(args, "delimiter", None)
    return None if word is None else DELIMITER_WORDS[word]


def _setup(path: str, geometry: Any) -> Any:
    from hexcal.io import load_setup

    return load_setup(path).in_euler(geometry.euler)


def _read(path: str, setup: Any, geometry: Any, args: argparse.Namespace) -> Any:
    """Target measurements or tool poses of an export, as the setup says."""
    from hexcal.io import read_target_measurements, read_tool_measurements

    decimal = getattr(args, "decimal", None)
    if setup.kind == "targets":
        return read_target_measurements(path, setup, _delimiter(args), decimal)
    return read_tool_measurements(path, geometry.euler, _delimiter(args), decimal)


def _fit(args: argparse.Namespace, setup: Any) -> str:
    """``--fit`` plus the setup's groups (hold them with ``--fix frame`` / ``--fix targets``)."""
    groups = [g.strip() for g in args.fit.split(",") if g.strip()]
    return ",".join(groups + [g for g in ("frame", setup.kind) if g not in groups])


def _flagged(diag: Any, data: Any) -> tuple[str, ...]:
    """Labels of the groups an outlier check flags (``pose 7``, ``pose 7 target t2``)."""
    import numpy as np

    limit = diag.limit
    out = [f"pose {data.ids[j]}" for j in np.flatnonzero(np.nan_to_num(diag.pose_pvalue, nan=1.0) < limit)]
    for j, i in zip(*np.nonzero(np.nan_to_num(diag.target_pvalue, nan=1.0) < limit), strict=True):
        out.append(f"pose {data.ids[j]} target {data.names[i]}")
    return tuple(out)


# -- identify, validate, synthesize ---------------------------------------------------------


def identify_with_setup(args: argparse.Namespace) -> None:
    """``hexcal identify --setup``: machine and setup by maximum likelihood."""
    from hexcal.estimation import identify_instrument, identify_instrument_robust, instrument_diagnostics
    from hexcal.io import atomic_write, save_geometry, save_setup
    from hexcal.report import identification_dict, identification_report_dict, render
    from hexcal.report.instrument import instrument_dict

    if args.html:
        raise CommandError("--html is not available with --setup yet; use --report or --json")
    if args.method != "ml":
        raise CommandError(f"--method {args.method}: with --setup the estimator is ml (maximum likelihood)")
    check_outputs(args.out, args.setup_out, args.report, args.json)
    nominal = load_geometry(args.geometry, args.euler)
    setup = _setup(args.setup, nominal)
    data = _read(args.data, setup, nominal, args)
    noise = noise_from_args(args)
    fit, fix = _fit(args, setup), list(args.fix or ())
    if args.robust:
        robust = identify_instrument_robust(nominal, data, setup, noise, fit, fix)
        out, outliers, flagged = robust.fit, robust.outliers, ()
    else:
        out = identify_instrument(nominal, data, setup, noise, fit, fix)
        flagged = _flagged(instrument_diagnostics(out, data, noise, fit, fix), data)
        outliers = ()
    result = out.result
    inst = instrument_dict(out, outliers, flagged)
    text = render("identification", identification_report_dict(result, outliers, flagged))
    text += "\n" + render("instrument", inst)
    calibration = result.calibration_metadata()
    calibration.update(data=str(args.data), setup=str(args.setup), outliers=list(outliers))
    calibration["gauge"] = inst["convention"]
    name = f"{nominal.name}-calibrated" if nominal.name else "calibrated"
    save_geometry(result.geometry.replace(name=name, calibration=calibration), args.out)
    if args.setup_out:
        save_setup(out.setup, args.setup_out)
    if args.report:
        with atomic_write(args.report) as fh:
            fh.write(text + "\n")
    if args.json:
        with atomic_write(args.json) as fh:
            body = identification_dict(result, outliers, flagged) | {"instrument": inst}
            fh.write(render("identification", body, "json"))
    print(text)
    print(f"wrote the calibrated geometry to {args.out}")
    if args.setup_out:
        print(f"wrote the calibrated setup to {args.setup_out}")
    elif setup.auto:
        warn("hexcal: warning: the registered frame is not saved: give --setup-out FILE to validate later")


def validate_with_setup(args: argparse.Namespace) -> None:
    """``hexcal validate --setup``: held-out instrument values predicted from leg readings."""
    import numpy as np

    from hexcal.io import write_table
    from hexcal.models import validate_instrument
    from hexcal.report import render
    from hexcal.report.instrument import instrument_validation_dict

    if args.html:
        raise CommandError("--html is not available with --setup yet")
    if args.nominal:
        raise CommandError(
            "--nominal with --setup: the setup was calibrated with the machine; validate the "
            "nominal machine with its own identified setup instead"
        )
    check_outputs(args.out)
    geometry = load_geometry(args.geometry, args.euler)
    setup = _setup(args.setup, geometry)
    if setup.auto:
        raise CommandError(
            f"{args.setup}: the instrument frame is auto; validate with the calibrated setup "
            "(hexcal identify --setup-out FILE)"
        )
    data = _read(args.data, setup, geometry, args)
    result = validate_instrument(geometry, setup, data)
    print(render("instrument_validation", instrument_validation_dict({"calibrated": result}, setup.kind)))
    if args.out:
        errors = np.asarray(result.errors, dtype=float).reshape(len(data.readings), -1)
        columns = [f"{t}.error" for t in setup.target_names] if setup.kind == "targets" else ["error"]
        write_table(args.out, columns, errors, list(data.ids), comment="distance measured - predicted, mm")
        print(f"wrote the per-pose table to {args.out}")


def synthesize_with_setup(args: argparse.Namespace) -> None:
    """``hexcal synthesize --setup``: a simulated instrument export of a known machine and setup."""
    from hexcal.io import read_poses, write_measurements, write_target_measurements
    from hexcal.models import simulate_target_measurements, simulate_tool_measurements

    check_outputs(args.out)
    if not 0.0 <= args.missing_rate < 1.0:
        raise CommandError(f"--missing-rate must be in [0, 1), got {args.missing_rate}")
    nominal = load_geometry(args.nominal, args.euler)
    true = load_geometry(args.true, nominal.euler)
    setup = _setup(args.setup, nominal)
    if setup.auto:
        raise CommandError(f"{args.setup}: simulation needs the true instrument frame, not auto")
    poses, _ = read_poses(args.poses, nominal.euler)
    noise = parse_noise(args.noise, args.noise_dist)
    comment = (
        f"simulated: nominal {args.nominal}, true {args.true}, setup {args.setup}, seed {args.seed}, "
        f"noise {noise}"
    )
    if setup.kind == "targets":
        data = simulate_target_measurements(nominal, true, setup, poses, noise, args.missing_rate, args.seed)
        comment += f", missing rate {args.missing_rate:g}"
        write_target_measurements(args.out, data, comment=comment)
        lost = int((~data.seen).sum())
        print(
            f"wrote {len(data)} simulated pose(s) of {len(setup.target_names)} target(s) to {args.out} "
            f"({lost} target observation(s) lost, {len(poses) - len(data)} pose(s) with none seen)"
        )
    else:
        if args.missing_rate:
            raise CommandError("--missing-rate applies to targets; the setup has a tool")
        data = simulate_tool_measurements(nominal, true, setup, poses, noise, args.seed)
        write_measurements(args.out, data, nominal.euler, args.orientation, comment=comment)
        print(f"wrote {len(data)} simulated tool pose(s) to {args.out}")


# -- planning ---------------------------------------------------------------------------------


def _problem(geometry: Any, setup: Any, poses: Any, fit: str) -> tuple[Any, Any]:
    """The noise-free identification problem of ``setup`` at ``poses`` and its true poses."""
    from hexcal.estimation import Problem, instrument_parameters
    from hexcal.models import instrument_model, simulate_target_measurements, simulate_tool_measurements

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

    from hexcal.models import Setup

    return Setup(setup.frame_or_identity(), tool=np.zeros(6), fixed=("instrument_frame", "tool"))


def _plan_noise(args: argparse.Namespace) -> Any:
    if args.noise_dist not in ("uniform", "normal"):
        raise CommandError(f"--noise-dist: unknown {args.noise_dist!r}; choose from uniform, normal")
    return parse_noise(args.noise, args.noise_dist)


def observability_with_setup(args: argparse.Namespace) -> None:
    """``hexcal observability --setup``: what this instrument identifies from these poses."""
    from hexcal.io import atomic_write, read_poses
    from hexcal.report import render

    check_outputs(args.json)
    geometry = load_geometry(args.geometry, args.euler)
    setup = _setup(args.setup, geometry)
    poses, _ = read_poses(args.poses, geometry.euler)
    noise = _plan_noise(args)
    data = instrument_plan(geometry, setup, poses, noise, _fit(args, setup))
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
    setup = _setup(args.setup, geometry)
    noise = _plan_noise(args)
    fit = _fit(args, setup)
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


def _cell(nominal: Any, true: Any, setup: Any, strategy: Any, n: int, noise: Any, args: Any, key: int) -> dict:
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
    from hexcal.models import Setup, instrument_model, predict_instrument, simulate_target_measurements

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
    setup = _setup(args.setup, nominal)
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
