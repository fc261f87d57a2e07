"""The ``hexcal`` command line: thin subcommands over the library.

Every known failure (bad file, bad option, unreachable pose, no convergence) ends
with one line ``hexcal: error: ...`` on stderr and exit status 1, and no output file.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hexcal.cli.linuxcnc import register as register_linuxcnc
from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import forward_kinematics, inverse_kinematics, leg_lengths, leg_readings
from hexcal.core.noise import NoiseModel
from hexcal.core.presets import PRESETS
from hexcal.core.workspace import is_feasible, leg_limit_violations
from hexcal.errors import HexcalError, UsageError
from hexcal.io import (
    atomic_write,
    load_geometry,
    read_legs,
    read_poses,
    save_geometry,
    write_legs,
    write_poses,
)


class CommandError(UsageError):
    """A failure of a command's options to report as one line."""


def _id_list(ids: Sequence[str], most: int = 20) -> str:
    return ", ".join(ids[:most]) + (f" ... ({len(ids)} in all)" if len(ids) > most else "")


def _geometry(spec: str, euler: str | None = None) -> Geometry:
    geometry = load_geometry(spec)
    return geometry.replace(euler=euler) if euler else geometry


def parse_noise(text: str | None, distribution: str = "uniform") -> NoiseModel:
    """Parse ``leg=0.01,pos=0.025,ang=0.001`` (any subset; others keep the paper's values)."""
    keys = {"leg": "leg", "pos": "position", "ang": "orientation"}
    values: dict[str, float] = {}
    for item in (text or "").split(","):
        item = item.strip()
        if not item:
            continue
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or key not in keys:
            raise CommandError(f"--noise: cannot read {item!r}; write e.g. leg=0.01,pos=0.025,ang=0.001")
        try:
            number = float(value)
        except ValueError:
            raise CommandError(f"--noise: {key}={value!r} is not a number") from None
        if not np.isfinite(number) or number < 0:
            raise CommandError(f"--noise: {key} must be a finite value >= 0, got {value}")
        values[keys[key]] = number
    try:
        return NoiseModel(distribution=distribution, **values)
    except ValueError as exc:
        raise CommandError(f"--noise: {exc}") from None


# -- subcommands ------------------------------------------------------------------


def cmd_preset(args: argparse.Namespace) -> None:
    save_geometry(_geometry(args.name), args.out)
    print(f"wrote preset {args.name} to {args.out}")


def cmd_ik(args: argparse.Namespace) -> None:
    geometry = _geometry(args.geometry, args.euler)
    poses, ids = read_poses(args.poses, geometry.euler)
    lengths = inverse_kinematics(geometry, poses)
    feasible = is_feasible(geometry, poses, margin=1e-6)
    if not feasible.all():
        bad = [ids[k] for k in np.flatnonzero(~feasible)]
        print(
            f"hexcal: warning: {len(bad)} pose(s) outside the leg length limits: {_id_list(bad)}",
            file=sys.stderr,
        )
    write_legs(args.out, lengths, leg_readings(geometry, lengths), ids)
    print(f"wrote leg lengths of {len(ids)} pose(s) to {args.out}")


def cmd_fk(args: argparse.Namespace) -> None:
    geometry = _geometry(args.geometry, args.euler)
    legs = read_legs(args.legs)
    lengths = legs.lengths if legs.lengths is not None else leg_lengths(geometry, legs.readings)
    short, long = leg_limit_violations(geometry, lengths)
    outside = np.flatnonzero(short | long)
    if outside.size:
        lo, hi = geometry.leg_length_limits
        bad = [legs.ids[k] for k in outside]
        raise CommandError(
            f"{args.legs}: {len(bad)} row(s) outside the leg length limits "
            f"[{lo:g}, {hi:g}] mm (ids {_id_list(bad)})"
        )
    if args.guess:
        guess, _ = read_poses(args.guess, geometry.euler)
        if len(guess) != len(lengths):
            raise CommandError(
                f"{args.guess}: {len(guess)} guess poses for {len(lengths)} rows of {args.legs}"
            )
    elif geometry.home_pose is not None:
        guess = geometry.home_pose
    else:
        raise CommandError("the geometry has no home_pose: give starting poses with --guess")
    result = forward_kinematics(geometry, lengths, guess=guess, tol=args.tol)
    if not result.all_converged:
        bad = [legs.ids[k] for k in np.flatnonzero(~result.converged)]
        raise CommandError(
            f"forward kinematics did not converge for {len(bad)} row(s) of {args.legs} "
            f"(ids {_id_list(bad)}): leg lengths "
            "out of reach, or start too far (try --guess)"
        )
    write_poses(args.out, result.poses, legs.ids)
    print(
        f"wrote {len(legs.ids)} pose(s) to {args.out} (max leg residual "
        f"{result.residual.max():.1e} mm, at most {result.iterations.max()} iterations)"
    )


def _check_outputs(*paths: str | None) -> None:
    """Fail before any work when an output's folder does not exist."""
    for path in paths:
        if path is None:
            continue
        folder = Path(path).parent
        if not folder.is_dir():
            raise CommandError(f"{path}: the folder {folder} does not exist")
        if Path(path).is_dir():
            raise CommandError(f"{path}: is a folder, not a file")


def _noise(args: argparse.Namespace) -> NoiseModel:
    """The noise model of ``--noise``, ``--noise-dist`` and ``--pose-covariance``."""
    noise = parse_noise(args.noise, args.noise_dist)
    path = getattr(args, "pose_covariance", None)
    if path:
        from hexcal.io import read_matrix

        try:
            noise = NoiseModel(
                leg=noise.leg, distribution=noise.distribution, pose_covariance=read_matrix(path, (6, 6))
            )
        except ValueError as exc:
            raise CommandError(f"{path}: {exc}") from None
    return noise


def cmd_identify(args: argparse.Namespace) -> None:
    from hexcal.core.parameters import select_parameters
    from hexcal.estimation.fitting import estimate
    from hexcal.estimation.robust import identify_robust, pose_diagnostics
    from hexcal.io import read_measurements
    from hexcal.report.text import format_identification_report, identification_summary

    _check_outputs(args.out, args.report, args.json)
    nominal = _geometry(args.geometry, args.euler)
    data = read_measurements(args.data, nominal.euler)
    noise = _noise(args)
    try:
        mask = select_parameters(args.fit, args.fix or ())
    except ValueError as exc:
        raise CommandError(str(exc)) from None
    outliers: tuple[str, ...] = ()
    # poses are checked on the generalised least-squares fit, whose whitened deletion
    # statistic follows a known F distribution under the noise model; the chosen
    # estimator then runs on the poses kept
    if args.robust:
        robust = identify_robust(nominal, data, mask=mask, noise=noise)
        outliers, used, diag = robust.outliers, data.subset(robust.kept), robust.diagnostics
    else:
        used = data
    result = estimate(nominal, used, args.method, mask, noise)
    if not args.robust:
        gls = (
            result
            if args.method == "gls"
            else estimate(nominal, used, "gls", mask, noise=noise, with_bound=False)
        )
        diag = pose_diagnostics(gls, used, mask, noise=noise)
    flagged = tuple(used.ids[k] for k in diag.flagged)
    text = format_identification_report(result, outliers, flagged)
    calibration = result.calibration_metadata()
    calibration["data"] = str(args.data)
    calibration["outliers"] = list(outliers)
    name = f"{nominal.name}-calibrated" if nominal.name else "calibrated"
    save_geometry(result.geometry.replace(name=name, calibration=calibration), args.out)
    if args.report:
        with atomic_write(args.report) as fh:
            fh.write(text + "\n")
    if args.json:
        with atomic_write(args.json) as fh:
            json.dump(identification_summary(result, outliers, flagged), fh, indent=2)
            fh.write("\n")
    print(text)
    print(f"wrote the calibrated geometry to {args.out}")


def cmd_validate(args: argparse.Namespace) -> None:
    from hexcal.estimation.validation import validate
    from hexcal.io import read_measurements, write_table
    from hexcal.report.text import format_validation

    _check_outputs(args.out)
    geometry = _geometry(args.geometry, args.euler)
    data = read_measurements(args.data, geometry.euler)
    calibrated = validate(geometry, data)
    nominal = validate(_geometry(args.nominal, geometry.euler), data) if args.nominal else None
    print(format_validation(calibrated.summary(), nominal.summary() if nominal else None))
    if args.out:
        columns = ["leg_rms", "position_error", "orientation_error"]
        results = [calibrated] + ([nominal] if nominal else [])
        table = []
        for res in results:
            table += [
                np.sqrt(np.mean(res.leg_residuals**2, axis=1)),
                res.position_error,
                res.orientation_error,
            ]
        if nominal:
            columns += ["nominal_leg_rms", "nominal_position_error", "nominal_orientation_error"]
        write_table(
            args.out,
            columns,
            np.column_stack(table),
            data.ids,
            comment="per-pose validation: mm and rad; leg_rms is the RMS of the six leg residuals",
        )
        print(f"wrote the per-pose table to {args.out}")


def cmd_compensate(args: argparse.Namespace) -> None:
    from hexcal.core.compensation import compensate

    _check_outputs(args.out, args.corrected_poses)
    if args.corrected_poses and not args.nominal:
        raise CommandError("--corrected-poses needs --nominal (the controller's geometry)")
    geometry = _geometry(args.geometry, args.euler)
    targets, ids = read_poses(args.poses, geometry.euler)
    nominal = _geometry(args.nominal, geometry.euler) if args.nominal else None
    comp = compensate(geometry, targets, ids, nominal)
    bad = comp.infeasible_ids
    if bad and not args.skip_infeasible:
        raise CommandError(
            f"{len(bad)} target(s) outside the leg length limits: {_id_list(list(bad))} "
            "(nothing written; --skip-infeasible writes the others)"
        )
    keep = comp.feasible
    kept_ids = [i for i, k in zip(ids, keep, strict=True) if k]
    write_legs(args.out, comp.lengths[keep], comp.readings[keep], kept_ids)
    if args.corrected_poses and comp.corrected_poses is not None:
        write_poses(args.corrected_poses, comp.corrected_poses[keep], kept_ids)
        print(f"wrote corrected target poses for the nominal controller to {args.corrected_poses}")
    if bad:
        print(
            f"hexcal: warning: skipped {len(bad)} infeasible target(s): {_id_list(list(bad))}",
            file=sys.stderr,
        )
    print(f"wrote leg commands for {len(kept_ids)} target(s) to {args.out}")


def cmd_synthesize(args: argparse.Namespace) -> None:
    from hexcal.io import write_measurements
    from hexcal.simulation.campaign import simulate_measurements

    _check_outputs(args.out)
    nominal = _geometry(args.nominal, args.euler)
    true = _geometry(args.true, nominal.euler)
    poses, ids = read_poses(args.poses, nominal.euler)
    noise = parse_noise(args.noise, args.noise_dist)
    data = simulate_measurements(nominal, true, poses, noise, args.seed, ids)
    write_measurements(
        args.out,
        data,
        nominal.euler,
        args.orientation,
        comment=f"simulated: nominal {args.nominal}, true {args.true}, seed {args.seed}, noise {noise}",
    )
    print(f"wrote {len(data)} simulated measurement(s) to {args.out}")


def _int_list(text: str, option: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise CommandError(f"{option}: {text!r} is not a comma-separated list of integers") from None
    if not values or min(values) < 1:
        raise CommandError(f"{option}: give positive integers, got {text!r}")
    return values


def cmd_simulate(args: argparse.Namespace) -> None:
    from hexcal.estimation.registry import ESTIMATORS
    from hexcal.simulation.study import STRATEGIES, fixed_strategy, format_study, run_study

    nominal = _geometry(args.geometry)
    true = None if args.true == "random" else _geometry(args.true)
    if args.trials < 1:
        raise CommandError(f"--trials must be at least 1, got {args.trials}")
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    bad = [m for m in methods if m not in ESTIMATORS]
    if bad or not methods:
        raise CommandError(
            f"--methods: unknown {', '.join(bad) or 'empty list'}; choose from {', '.join(ESTIMATORS)}"
        )
    names = [s.strip() for s in args.strategies.split(",") if s.strip()]
    known = [*STRATEGIES, "selected"]
    unknown = [s for s in names if s not in known]
    if unknown or not names:
        raise CommandError(
            f"--strategies: unknown {', '.join(unknown) or 'empty list'}; choose from {', '.join(known)}"
        )
    counts = _int_list(args.poses, "--poses")
    base = _noise(args)
    strategies = {s: STRATEGIES[s] for s in names if s in STRATEGIES}
    if "selected" in names:
        strategies["selected"] = fixed_strategy(
            {n: _optimal_poses(nominal, n, base, args.seed) for n in counts}
        )
    try:
        levels = [float(v) for v in args.noise_levels.split(",") if v.strip()]
    except ValueError:
        raise CommandError(f"--noise-levels: {args.noise_levels!r} is not a list of numbers") from None
    if not levels or any(not np.isfinite(v) or v < 0 for v in levels):
        raise CommandError(f"--noise-levels: give finite factors >= 0, got {args.noise_levels!r}")
    noises = {
        f"x{v:g}": NoiseModel(
            base.leg * v,
            base.position * v,
            base.orientation * v,
            base.distribution,
            None if base.pose_covariance is None else base.pose_covariance * v**2,
        )
        for v in levels
    }
    out = Path(args.out) if args.out else None
    if out is not None and out.exists() and not out.is_dir():
        raise CommandError(f"--out {out}: exists and is not a folder")
    cells = run_study(
        nominal,
        true,
        methods,
        strategies,
        counts,
        noises,
        args.trials,
        args.seed,
        jobs=args.jobs,
        progress=_Progress("identifications", args.quiet),
    )
    print(format_study(cells))
    if out is not None:
        from hexcal.io import write_table
        from hexcal.report.figures import plot_study

        out.mkdir(parents=True, exist_ok=True)
        rows = [c.row() for c in cells]
        with atomic_write(out / "study.json") as fh:
            json.dump(
                {"trials": args.trials, "seed": args.seed, "noise": base.describe(), "cells": rows},
                fh,
                indent=2,
            )
            fh.write("\n")
        numeric = [
            "poses",
            "error_mean",
            "error_std",
            "bound",
            "efficiency",
            "position_rms",
            "orientation_rms",
        ]
        write_table(
            out / "study.csv",
            numeric,
            np.array([[r[k] for k in numeric] for r in rows], dtype=float),
            ids=[f"{r['strategy']}/{r['noise']}/{r['method']}" for r in rows],
            comment="id: strategy/noise/method; mm and rad",
        )
        plot_study(cells, out / "study.png")
        print(f"wrote {out / 'study.json'}, study.csv and study.png")


class _Progress:
    """Progress lines on stderr, about every 10 % (and at the end)."""

    def __init__(self, label: str, quiet: bool = False) -> None:
        self.label, self.quiet, self.last, self.start = label, quiet, -1, time.perf_counter()

    def __call__(self, done: int, total: int) -> None:
        step = int(10 * done / total)
        if self.quiet or (step == self.last and done < total):
            return
        self.last = step
        elapsed = time.perf_counter() - self.start
        print(f"  {self.label}: {done}/{total} ({elapsed:.1f} s)", file=sys.stderr, flush=True)


def _optimal_poses(nominal: Geometry, n: int, noise: NoiseModel, seed: int) -> np.ndarray:
    """``n`` A-optimal poses of the workspace boundary grid for the nominal geometry.

    A-optimality minimises the sum of the parameter variances, the criterion closest to
    the mean absolute parameter error that Table I reports.
    """
    from hexcal.design.candidates import candidate_poses, check_feasibility
    from hexcal.design.selection import information_blocks, select_poses

    candidates = candidate_poses(nominal, "grid")
    candidates = candidates[check_feasibility(nominal, candidates).feasible]
    chosen = select_poses(information_blocks(nominal, candidates, noise), n, "A", rng=seed)
    return candidates[chosen.indices]


def cmd_paper(args: argparse.Namespace) -> None:
    from hexcal.report.text import format_paper_summary, paper_summary
    from hexcal.simulation.campaign import run_paper_experiment

    nominal = _geometry(args.geometry)
    true = None if args.true == "random" else _geometry(args.true)
    if args.trials < 1:
        raise CommandError(f"--trials must be at least 1, got {args.trials}")
    noise = parse_noise(args.noise, args.noise_dist)
    out = Path(args.out) if args.out else None
    if out is not None and out.exists() and not out.is_dir():
        raise CommandError(f"--out {out}: exists and is not a folder")
    print(
        f"Simulating the seed paper's experiment: {args.trials} trials, "
        f"nominal {nominal.name or args.geometry}, "
        f"true machine {true.name if true else 'nominal + U(±5 mm)'}, seed {args.seed}",
        file=sys.stderr,
    )
    start = time.perf_counter()
    selected = _optimal_poses(nominal, 15, noise, args.seed)
    experiment = run_paper_experiment(
        nominal,
        true,
        trials=args.trials,
        rng=args.seed,
        noise=noise,
        method=args.method,
        jobs=args.jobs,
        progress=_Progress("identifications", args.quiet),
        extra_rows=(("boundary_ml", "boundary", "ml"), ("selected_ml", "selected", "ml")),
        selected_poses=selected,
    )
    summary = paper_summary(
        experiment,
        seed=args.seed,
        nominal=nominal.name or args.geometry,
        true_machine=true.name if true else "random",
        noise={
            "leg": noise.leg,
            "position": noise.position,
            "orientation": noise.orientation,
            "distribution": noise.distribution,
        },
    )
    elapsed = time.perf_counter() - start
    print(format_paper_summary(summary))
    print(f"({elapsed:.1f} s)")
    if out is not None:
        from hexcal.report.figures import plot_parameter_errors, plot_validation_errors

        out.mkdir(parents=True, exist_ok=True)
        plot_parameter_errors(experiment, out / "fig10_parameter_errors.png")
        plot_validation_errors(experiment, out / "fig11_validation_errors.png")
        with atomic_write(out / "table1.json") as fh:
            json.dump(summary, fh, indent=2)
            fh.write("\n")
        print(
            f"wrote {out / 'table1.json'} and the figures fig10_parameter_errors.png, "
            "fig11_validation_errors.png"
        )


# -- parser -------------------------------------------------------------------------


def _noise_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--noise",
        help="measurement noise: leg=MM,pos=MM,ang=RAD (default the seed paper's "
        "leg=0.01,pos=0.025,ang=0.001)",
    )
    p.add_argument(
        "--noise-dist",
        choices=("uniform", "normal"),
        default="uniform",
        help="uniform: the values are half-widths a (σ = a/√3); normal: they are σ",
    )
    p.add_argument(
        "--pose-covariance",
        metavar="FILE",
        help="full 6x6 pose covariance (mm², mm·rad, rad²; 6 rows of 6 numbers), replacing pos and ang",
    )


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hexcal", description="Kinematic calibration of hexapods (Stewart-Gough platforms)."
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    geometry_help = f"geometry YAML file or preset ({', '.join(PRESETS)})"

    p = sub.add_parser("preset", help="write a built-in geometry to a YAML file")
    p.add_argument("name", choices=sorted(PRESETS))
    p.add_argument("--out", required=True, help="YAML file to write")
    p.set_defaults(func=cmd_preset)

    p = sub.add_parser("ik", help="inverse kinematics: leg lengths of poses")
    p.add_argument("--geometry", required=True, help=geometry_help)
    p.add_argument("--poses", required=True, help="pose CSV file")
    p.add_argument("--out", required=True, help="leg CSV file to write (l1..l6, dl1..dl6)")
    p.add_argument("--euler", help="Euler sequence of the angles (default: the geometry's)")
    p.set_defaults(func=cmd_ik)

    p = sub.add_parser("fk", help="forward kinematics: poses of leg lengths or readings")
    p.add_argument("--geometry", required=True, help=geometry_help)
    p.add_argument("--legs", required=True, help="leg CSV file (l1..l6 or dl1..dl6)")
    p.add_argument("--out", required=True, help="pose CSV file to write")
    p.add_argument("--guess", help="pose CSV file of starting poses (default: the home pose)")
    p.add_argument("--euler", help="Euler sequence of the angles (default: the geometry's)")
    p.add_argument("--tol", type=float, default=1e-9, help="leg length tolerance, mm")
    p.set_defaults(func=cmd_fk)

    p = sub.add_parser("identify", help="identify the kinematic parameters from a measurement file")
    p.add_argument("--geometry", required=True, help=f"nominal {geometry_help}")
    p.add_argument("--data", required=True, help="measurement CSV file (dl1..dl6 and the measured pose)")
    p.add_argument("--out", required=True, help="calibrated geometry YAML file to write")
    p.add_argument(
        "--method",
        choices=("ml", "gls", "length", "paper"),
        default="ml",
        help="estimator: maximum likelihood (default), generalised least squares, least squares "
        "on leg lengths, or the seed paper's squared lengths (eq. 3)",
    )
    _noise_options(p)
    p.add_argument("--fit", default="joints,l0", help="parameter groups: joints, base, platform, l0, gains")
    p.add_argument("--fix", nargs="+", metavar="NAME", help="parameters to hold, e.g. u1.z l0_1")
    p.add_argument("--robust", action="store_true", help="find and leave out outlying poses")
    p.add_argument("--euler", help="Euler sequence of the angles (default: the geometry's)")
    p.add_argument("--report", help="save the report as text")
    p.add_argument("--json", help="save the result as JSON")
    p.set_defaults(func=cmd_identify)

    p = sub.add_parser("validate", help="pose errors of a geometry on held-out measurements")
    p.add_argument("--geometry", required=True, help=f"calibrated {geometry_help}")
    p.add_argument("--data", required=True, help="held-out measurement CSV file")
    p.add_argument("--nominal", help="also validate this geometry, side by side")
    p.add_argument("--out", help="per-pose table CSV file")
    p.add_argument("--euler", help="Euler sequence of the angles (default: the geometry's)")
    p.set_defaults(func=cmd_validate)

    p = sub.add_parser("compensate", help="leg commands that bring the real machine to targets")
    p.add_argument("--geometry", required=True, help=f"calibrated {geometry_help}")
    p.add_argument("--poses", required=True, help="target pose CSV file")
    p.add_argument("--out", required=True, help="leg CSV file to write (l1..l6, dl1..dl6)")
    p.add_argument("--nominal", help="the controller's (nominal) geometry")
    p.add_argument("--corrected-poses", help="pose CSV file of corrected targets for the nominal controller")
    p.add_argument("--skip-infeasible", action="store_true", help="write the feasible targets only")
    p.add_argument("--euler", help="Euler sequence of the angles (default: the geometry's)")
    p.set_defaults(func=cmd_compensate)

    p = sub.add_parser("synthesize", help="simulate a measurement file of a known machine (for rehearsal)")
    p.add_argument("--nominal", required=True, help=f"the controller's {geometry_help}")
    p.add_argument("--true", required=True, help=f"the simulated real machine: {geometry_help}")
    p.add_argument("--poses", required=True, help="commanded pose CSV file")
    p.add_argument("--out", required=True, help="measurement CSV file to write")
    p.add_argument("--noise", help="noise half-widths, e.g. leg=0.01,pos=0.025,ang=0.001 (the paper's)")
    p.add_argument("--noise-dist", choices=("uniform", "normal"), default="uniform")
    p.add_argument("--orientation", choices=("rad", "deg", "quat"), default="rad")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--euler", help="Euler sequence of the angles (default: the nominal geometry's)")
    p.set_defaults(func=cmd_synthesize)

    from hexcal.cli.plan import register

    register(sub, geometry_help)

    register_linuxcnc(sub, geometry_help)

    p = sub.add_parser("simulate", help="Monte Carlo study of calibration campaigns")
    p.add_argument("--geometry", default="paper-hmt", help=f"nominal {geometry_help}")
    p.add_argument(
        "--true", default="paper-hmt-true", help="the real machine, or 'random' (nominal + U(±5 mm))"
    )
    p.add_argument(
        "--methods", default="paper,ml", help="estimators, comma-separated: ml, gls, length, paper"
    )
    p.add_argument(
        "--strategies",
        default="corners,interior",
        help="pose strategies: corners (random of the 64), interior (random), selected (A-optimal "
        "poses of the boundary grid for the nominal geometry)",
    )
    p.add_argument("--poses", default="15", help="numbers of poses, comma-separated, e.g. 7,15,30")
    _noise_options(p)
    p.add_argument("--noise-levels", default="1", help="factors applied to the noise, e.g. 0.5,1,2")
    p.add_argument("--trials", type=int, default=100)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--jobs", type=int, default=None, help="processes (default: all cores)")
    p.add_argument("--out", help="folder for study.json, study.csv and study.png")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("paper", help="reproduce the seed paper's Table I by Monte Carlo")
    p.add_argument("--geometry", default="paper-hmt", help=f"nominal {geometry_help}")
    p.add_argument(
        "--true",
        default="paper-hmt-true",
        help="the real machine: geometry or preset, or 'random' for nominal + U(±5 mm)",
    )
    p.add_argument("--trials", type=int, default=100)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--method", choices=("paper", "length"), default="paper")
    p.add_argument("--noise", help="noise half-widths, e.g. leg=0.01,pos=0.025,ang=0.001")
    p.add_argument("--noise-dist", choices=("uniform", "normal"), default="uniform")
    p.add_argument(
        "--jobs", type=int, default=None, help="processes for the identifications (default: all cores)"
    )
    p.add_argument("--out", help="folder for table1.json and the figures")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=cmd_paper)
    return parser


def _show_warning(message: Any, category: Any, *_args: Any, **_kw: Any) -> None:
    print(f"hexcal: warning: {message}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``hexcal`` command; returns the exit status."""
    args = build_parser().parse_args(argv)
    old = warnings.showwarning
    warnings.showwarning = _show_warning
    try:
        args.func(args)
    except BrokenPipeError:  # output piped into `head`: not an error of hexcal's
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except (HexcalError, ValueError, OSError) as exc:
        print(f"hexcal: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("hexcal: interrupted", file=sys.stderr)
        return 130
    finally:
        warnings.showwarning = old
    return 0


if __name__ == "__main__":
    sys.exit(main())
