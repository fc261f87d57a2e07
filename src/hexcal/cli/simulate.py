"""Monte Carlo subcommands of ``hexcal``: ``simulate`` (studies of campaigns) and
``paper`` (the seed paper's Table I).

Imports only the standard library and :mod:`hexcal.cli.common` at its top; each command
imports the library parts it needs when it runs.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Any

from hexcal.cli.common import (
    GEOMETRY_HELP,
    CommandError,
    Progress,
    check_trials,
    int_list,
    load_geometry,
    noise_from_args,
    noise_options,
    output_folder,
    parse_noise,
)


def _names(text: str, known: list[str], option: str) -> list[str]:
    """The comma-separated names of an option, each one of ``known``."""
    names = [s.strip() for s in text.split(",") if s.strip()]
    unknown = [s for s in names if s not in known]
    if unknown or not names:
        raise CommandError(
            f"{option}: unknown {', '.join(unknown) or 'empty list'}; choose from {', '.join(known)}"
        )
    return names


def _noise_levels(text: str) -> list[float]:
    try:
        levels = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise CommandError(f"--noise-levels: {text!r} is not a list of numbers") from None
    if not levels or any(not math.isfinite(v) or v < 0 for v in levels):
        raise CommandError(f"--noise-levels: give finite factors >= 0, got {text!r}")
    return levels


def cmd_simulate(args: argparse.Namespace) -> None:
    """Monte Carlo study of calibration campaigns: strategies x pose counts x noise x methods."""
    if args.setup:  # an instrument setup: cli/instrument_plan.py
        from hexcal.cli.instrument_plan import simulate_with_setup

        return simulate_with_setup(args)
    from hexcal.core import NoiseModel
    from hexcal.design.planning import optimal_poses
    from hexcal.estimation import ESTIMATORS
    from hexcal.simulation import STRATEGIES, fixed_strategy, run_study

    nominal = load_geometry(args.geometry)
    true = None if args.true == "random" else load_geometry(args.true)
    check_trials(args.trials)
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    bad = [m for m in methods if m not in ESTIMATORS]
    if bad or not methods:
        raise CommandError(
            f"--methods: unknown {', '.join(bad) or 'empty list'}; choose from {', '.join(ESTIMATORS)}"
        )
    names = _names(args.strategies, [*STRATEGIES, "selected"], "--strategies")
    counts = int_list(args.poses, "--poses")
    base = noise_from_args(args)
    strategies = {s: STRATEGIES[s] for s in names if s in STRATEGIES}
    if "selected" in names:
        strategies["selected"] = fixed_strategy(
            {n: optimal_poses(nominal, n, base, args.seed) for n in counts}
        )
    levels = _noise_levels(args.noise_levels)
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
    out = output_folder(args.out)
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
        progress=Progress("identifications", args.quiet),
    )
    from hexcal.report import render

    rows = [c.row() for c in cells]
    print(render("study", rows))
    if out is not None:
        from hexcal.io import atomic_write, write_table
        from hexcal.report import plot_study, study_table

        out.mkdir(parents=True, exist_ok=True)
        study = {"trials": args.trials, "seed": args.seed, "noise": base.describe(), "cells": rows}
        with atomic_write(out / "study.json") as fh:
            fh.write(render("study", study, "json"))
        columns, values, ids, comment = study_table(rows)
        write_table(out / "study.csv", columns, values, ids=ids, comment=comment)
        plot_study(rows, out / "study.png")
        print(f"wrote {out / 'study.json'}, study.csv and study.png")


def cmd_paper(args: argparse.Namespace) -> None:
    """The seed paper's experiment by Monte Carlo: Table I and Figs. 10-11."""
    from hexcal.design.planning import optimal_poses
    from hexcal.report import render
    from hexcal.simulation import run_paper_experiment

    nominal = load_geometry(args.geometry)
    true = None if args.true == "random" else load_geometry(args.true)
    check_trials(args.trials)
    noise = parse_noise(args.noise, args.noise_dist)
    out = output_folder(args.out)
    print(
        f"Simulating the seed paper's experiment: {args.trials} trials, "
        f"nominal {nominal.name or args.geometry}, "
        f"true machine {true.name if true else 'nominal + U(±5 mm)'}, seed {args.seed}",
        file=sys.stderr,
    )
    start = time.perf_counter()
    selected = optimal_poses(nominal, 15, noise, args.seed)
    experiment = run_paper_experiment(
        nominal,
        true,
        trials=args.trials,
        rng=args.seed,
        noise=noise,
        method=args.method,
        jobs=args.jobs,
        progress=Progress("identifications", args.quiet),
        extra_rows=(("boundary_ml", "boundary", "ml"), ("selected_ml", "selected", "ml")),
        selected_poses=selected,
    )
    summary = experiment.to_dict(
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
    print(render("paper", summary))
    print(f"({elapsed:.1f} s)")
    if out is not None:
        from hexcal.io import atomic_write
        from hexcal.report import paper_figure_data, plot_parameter_errors, plot_validation_errors

        out.mkdir(parents=True, exist_ok=True)
        figures = paper_figure_data(experiment)
        plot_parameter_errors(figures, out / "fig10_parameter_errors.png")
        plot_validation_errors(figures, out / "fig11_validation_errors.png")
        with atomic_write(out / "table1.json") as fh:
            fh.write(render("paper", summary, "json"))
        print(
            f"wrote {out / 'table1.json'} and the figures fig10_parameter_errors.png, "
            "fig11_validation_errors.png"
        )


def register(sub: Any) -> None:
    """Add ``simulate`` and ``paper`` to the ``hexcal`` parser's subparsers."""
    p = sub.add_parser("simulate", help="Monte Carlo study of calibration campaigns")
    p.add_argument("--geometry", default="paper-hmt", help=f"nominal {GEOMETRY_HELP}")
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
    noise_options(p)
    p.add_argument("--noise-levels", default="1", help="factors applied to the noise, e.g. 0.5,1,2")
    p.add_argument("--trials", type=int, default=100)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--jobs", type=int, default=None, help="processes (default: all cores)")
    p.add_argument("--out", help="folder for study.json, study.csv and study.png")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--setup", metavar="FILE", help="true tracker setup YAML: campaigns with targets (ml)")
    p.add_argument("--missing-rate", type=float, default=0.0, help="with --setup: share of lost targets")
    p.set_defaults(
        func=cmd_simulate,
        inputs=("geometry", "true", "pose_covariance", "setup"),
        outputs=(),
        folders=("out",),
    )

    p = sub.add_parser("paper", help="reproduce the seed paper's Table I by Monte Carlo")
    p.add_argument("--geometry", default="paper-hmt", help=f"nominal {GEOMETRY_HELP}")
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
    p.set_defaults(func=cmd_paper, inputs=("geometry", "true"), outputs=(), folders=("out",))
