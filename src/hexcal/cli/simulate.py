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
    output_folder,
    show_defaults,
)
from hexcal.cli.noise import noise_from_args, noise_options, parse_noise


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


def _true_machine(args: argparse.Namespace, default: str) -> tuple[Any, str | None]:
    """The ``--true`` machine (None: random errors around the nominal, one per trial) and,
    when ``--true`` is not given and the machine is random, the line that says so."""
    spec = args.true or default
    note = None
    if args.true is None and spec == "random":
        note = (
            "hexcal: no --true: the simulated real machines are random errors around the nominal "
            "geometry (U(±5 mm), one machine per trial)"
        )
    return (None if spec == "random" else load_geometry(spec)), note


def _machines(nominal: Any, true: Any) -> dict[str, Any]:
    """The nominal and true geometries, recorded in every output."""
    return {
        "nominal_geometry": nominal.to_dict(),
        "true_geometry": true.to_dict() if true is not None else "random: nominal + U(±5 mm) per trial",
    }


#: The files ``simulate`` and ``paper`` write into their ``--out`` folder (declared outputs:
#: each checked before any work, like every output).
SIMULATE_FILES = ("study.json", "study.csv", "study.png")
PAPER_FILES = ("table1.json", "fig10_parameter_errors.png", "fig11_validation_errors.png")


def cmd_simulate(args: argparse.Namespace) -> None:
    """Monte Carlo study of calibration campaigns: strategies x pose counts x noise x methods,
    measured by any instrument (``--setup``: its true setup)."""
    from hexcal.core import NoiseModel
    from hexcal.design.planning import optimal_poses
    from hexcal.estimation import ESTIMATORS
    from hexcal.io import load_instrument
    from hexcal.simulation import STRATEGIES, fixed_strategy, instrument_campaign, run_study

    nominal = load_geometry(args.geometry)
    instrument = load_instrument(args.setup, nominal.euler)
    campaign = instrument_campaign(instrument, args.fit, missing_rate=args.missing_rate)
    true, note = _true_machine(args, default="random")
    check_trials(args.trials)
    methods = None if args.methods is None else [m.strip() for m in args.methods.split(",") if m.strip()]
    bad = [m for m in methods or () if m not in ESTIMATORS]
    if bad or methods == []:
        raise CommandError(
            f"--methods: unknown {', '.join(bad) or 'empty list'}; choose from {', '.join(ESTIMATORS)}"
        )
    names = _names(args.strategies, [*STRATEGIES, "selected"], "--strategies")
    counts = int_list(args.poses, "--poses")
    base = noise_from_args(args, [instrument])
    strategies = {s: STRATEGIES[s] for s in names if s in STRATEGIES}
    if "selected" in names:
        strategies["selected"] = fixed_strategy(
            {n: optimal_poses(nominal, n, base, args.seed, instrument) for n in counts}
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
    if note:
        print(note, file=sys.stderr)
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
        executor=args.executor,
        campaign=campaign,
        fit=args.fit,
    )
    from hexcal.report import render

    rows = [c.row() for c in cells]
    print(render("study", rows))
    failed = sum(int(r.get("failures", 0)) for r in rows)
    if failed:
        print(
            f"{failed} of {len(rows) * args.trials} trial(s) failed (a simulated machine could not reach a "
            "pose, or the identification failed): left out of the statistics, counted in 'failures'"
        )
    study = {
        "instrument": instrument.describe(),
        "fit": args.fit,
        "trials": args.trials,
        "seed": args.seed,
        "noise": base.describe(),
        "noise_sigmas": dict(zip(("leg", "position", "orientation"), base.sigmas, strict=True)),
        **_machines(nominal, true),
        "cells": rows,
    }
    study["true_machine"] = true.name if true else "random"
    if args.html:
        files = {"geometry": args.geometry, "true": args.true, "setup": args.setup}
        _write_html(args, "study_report", study, files)
    if out is not None:
        from hexcal.io import atomic_write, write_table
        from hexcal.report import plot_study, study_table

        out.mkdir(parents=True, exist_ok=True)
        with atomic_write(out / "study.json") as fh:
            fh.write(render("study", study, "json"))
        columns, values, ids, comment = study_table(rows)
        write_table(out / "study.csv", columns, values, ids=ids, comment=comment)
        from hexcal.report import study_note

        plot_study(rows, out / "study.png", study_note(study))
        print(f"wrote {out / 'study.json'}, study.csv and study.png")


def cmd_paper(args: argparse.Namespace) -> None:
    """The seed paper's experiment by Monte Carlo: Table I and Figs. 10-11."""
    from hexcal.design.planning import optimal_poses
    from hexcal.report import render
    from hexcal.simulation import run_paper_experiment

    nominal = load_geometry(args.geometry)
    # the seed paper's machine by default; random errors around any other --geometry
    true, note = _true_machine(args, default="paper-hmt-true" if args.geometry == "paper-hmt" else "random")
    check_trials(args.trials)
    noise = parse_noise(args.noise, args.noise_dist)
    out = output_folder(args.out)
    if note:
        print(note, file=sys.stderr)
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
        executor=args.executor,
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
            "sigmas": dict(zip(("leg", "position", "orientation"), noise.sigmas, strict=True)),
        },
        **_machines(nominal, true),
    )
    elapsed = time.perf_counter() - start
    print(render("paper", summary))
    print(f"({elapsed:.1f} s)")
    from hexcal.report import paper_figure_data, paper_note

    figures = paper_figure_data(experiment) | {"note": paper_note(summary)}
    if args.html:
        _write_html(args, "paper_report", summary, {"geometry": args.geometry, "true": args.true}, figures)
    if out is not None:
        from hexcal.io import atomic_write
        from hexcal.report import plot_parameter_errors, plot_validation_errors

        out.mkdir(parents=True, exist_ok=True)
        plot_parameter_errors(figures, out / "fig10_parameter_errors.png")
        plot_validation_errors(figures, out / "fig11_validation_errors.png")
        with atomic_write(out / "table1.json") as fh:
            fh.write(render("paper", summary, "json"))
        print(
            f"wrote {out / 'table1.json'} and the figures fig10_parameter_errors.png, "
            "fig11_validation_errors.png"
        )


def _write_html(
    args: argparse.Namespace, builder: str, data: Any, files: dict[str, str], *extra: Any
) -> None:
    """Write the self-contained HTML report of ``builder`` (a :mod:`hexcal.report` page builder)
    atomically."""
    import hexcal.report as report
    from hexcal.cli.common import inputs_record
    from hexcal.io import atomic_write

    inputs = inputs_record({k: v for k, v in files.items() if v != "random"}, args)
    with atomic_write(args.html) as fh:
        fh.write(report.render_html(getattr(report, builder)(data, *extra, inputs)))
    print(f"wrote the HTML report to {args.html}")


def register(sub: Any) -> None:
    """Add ``simulate`` and ``paper`` to the ``hexcal`` parser's subparsers."""
    from hexcal.cli.study import SCHEDULER_HELP, with_scheduler

    p = sub.add_parser("simulate", help="Monte Carlo study of calibration campaigns")
    p.add_argument("--geometry", default="paper-hmt", help=f"nominal {GEOMETRY_HELP}")
    p.add_argument(
        "--true",
        default=None,
        help="the real machine (geometry or preset), or 'random' (nominal + U(±5 mm) per trial); "
        "default: random, announced",
    )
    p.add_argument(
        "--methods",
        help="estimators, comma-separated: ml, gls, length, paper (default paper,ml, those the "
        "instrument allows: ml for targets and a ballbar)",
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
    p.add_argument("--scheduler", metavar="ADDRESS", help=SCHEDULER_HELP)
    p.add_argument("--out", help="folder for study.json, study.csv and study.png")
    p.add_argument("--html", metavar="FILE", help="save a self-contained HTML report (table, figure, inputs)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument(
        "--setup",
        metavar="FILE",
        help="true instrument setup YAML (frame given): campaigns measured by it, identified from "
        "the frame auto",
    )
    p.add_argument(
        "--missing-rate", type=float, default=0.0, help="with a target setup: share of lost targets"
    )
    p.add_argument(
        "--fit",
        default="joints,l0",
        help="machine parameter groups identified: joints, base, platform, l0, gains",
    )
    p.set_defaults(
        func=with_scheduler(cmd_simulate),
        inputs=("geometry", "true", "pose_covariance", "setup"),
        outputs=("html",),
        folders=("out",),
        folder_files={"out": SIMULATE_FILES},
    )

    p = sub.add_parser("paper", help="reproduce the seed paper's Table I by Monte Carlo")
    p.add_argument("--geometry", default="paper-hmt", help=f"nominal {GEOMETRY_HELP}")
    p.add_argument(
        "--true",
        default=None,
        help="the real machine: geometry or preset, or 'random' for nominal + U(±5 mm); default: "
        "paper-hmt-true for the paper-hmt geometry, random (announced) for any other",
    )
    p.add_argument("--trials", type=int, default=100)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--method", choices=("paper", "length"), default="paper")
    p.add_argument("--noise", help="noise half-widths, e.g. leg=0.01,pos=0.025,ang=0.001")
    p.add_argument("--noise-dist", choices=("uniform", "normal"), default="uniform")
    p.add_argument(
        "--jobs", type=int, default=None, help="processes for the identifications (default: all cores)"
    )
    p.add_argument("--scheduler", metavar="ADDRESS", help=SCHEDULER_HELP)
    p.add_argument("--out", help="folder for table1.json and the figures")
    p.add_argument(
        "--html", metavar="FILE", help="save a self-contained HTML report (tables, figures, inputs)"
    )
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(
        func=with_scheduler(cmd_paper),
        inputs=("geometry", "true"),
        outputs=("html",),
        folders=("out",),
        folder_files={"out": PAPER_FILES},
    )
    for name in ("simulate", "paper"):
        show_defaults(sub.choices[name])
