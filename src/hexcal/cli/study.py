"""Study subcommands of ``hexcal``: ``study selection`` (how much the measurement poses matter),
and :func:`executor_for`, the executor of the ``--scheduler`` option of the Monte Carlo
commands (``paper``, ``simulate``, ``study``).

Imports only the standard library and :mod:`hexcal.cli.common` at its top; each command
imports the library parts it needs when it runs.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any

from hexcal.cli.common import (
    GEOMETRY_HELP,
    CommandError,
    Progress,
    check_trials,
    int_list,
    load_geometry,
    output_folder,
)
from hexcal.cli.noise import parse_noise

#: Help of the ``--scheduler`` option.
SCHEDULER_HELP = (
    "address of a running Dask scheduler, e.g. tcp://127.0.0.1:8786: run the trials on its "
    "workers (pip install hexcal[dask]; the same numbers as locally)"
)


@contextlib.contextmanager
def executor_for(address: str | None) -> Iterator[Any]:
    """The executor of ``--scheduler ADDRESS`` (``None`` without it: local, by ``--jobs``).

    Connects within a few seconds or fails with one line; cancels the cluster's pending
    tasks and disconnects on leaving, also on Ctrl-C.
    """
    if not address:
        yield None
        return
    from hexcal.simulation.dask_executor import dask_executor

    with dask_executor(address) as executor:
        print(
            f"running on the Dask cluster at {address} ({executor.workers} worker threads)", file=sys.stderr
        )
        yield executor


def with_scheduler(command: Callable[[argparse.Namespace], None]) -> Callable[[argparse.Namespace], None]:
    """``command`` run with ``args.executor``, the executor of its ``--scheduler`` option.

    The connection comes first (a bad address fails at once, before any work) and is
    closed when the command ends, also on errors and Ctrl-C.
    """

    @functools.wraps(command)
    def run(args: argparse.Namespace) -> None:
        with executor_for(getattr(args, "scheduler", None)) as executor:
            args.executor = executor
            command(args)

    return run


def cmd_study_selection(args: argparse.Namespace) -> None:
    """Mean parameter error and bound of interior, corner and selected poses, per pose count."""
    from hexcal.simulation.selection import run_selection_study

    nominal = load_geometry(args.geometry)
    true = None if args.true == "random" else load_geometry(args.true)
    check_trials(args.trials)
    counts = int_list(args.poses, "--poses")
    if min(counts) < 8 or max(counts) > 64:
        raise CommandError(f"--poses: give numbers from 8 to 64, got {args.poses}")
    noise = parse_noise(args.noise, args.noise_dist)
    out = output_folder(args.out)
    start = time.perf_counter()
    cells = run_selection_study(
        nominal,
        true,
        noise,
        args.trials,
        args.seed,
        counts,
        args.method,
        jobs=args.jobs,
        progress=Progress("identifications", args.quiet),
        executor=args.executor,
    )
    from hexcal.report import render

    rows = [c.row() for c in cells]
    print(render("study", rows))
    print(f"({time.perf_counter() - start:.1f} s)")
    if out is not None:
        from hexcal.io import atomic_write, write_table
        from hexcal.report import plot_study, study_table

        out.mkdir(parents=True, exist_ok=True)
        study = cells.to_dict(
            study="selection",
            trials=args.trials,
            seed=args.seed,
            method=args.method,
            nominal=nominal.name or args.geometry,
            true_machine=true.name if true else "random",
            noise=noise.describe(),
        )
        with atomic_write(out / "selection.json") as fh:
            fh.write(render("study", study, "json"))
        columns, values, ids, comment = study_table(rows)
        write_table(out / "selection.csv", columns, values, ids=ids, comment=comment)
        plot_study(rows, out / "selection.png")
        print(f"wrote {out / 'selection.json'}, selection.csv and selection.png")


def register(sub: Any) -> None:
    """Add ``study`` (with ``selection``) to the ``hexcal`` parser's subparsers."""
    study = sub.add_parser("study", help="Monte Carlo studies: how to calibrate (selection)")
    kinds = study.add_subparsers(dest="study", required=True, metavar="STUDY")
    p = kinds.add_parser(
        "selection",
        help="parameter error and bound of random interior poses, the paper's corners and "
        "optimally selected poses, as the number of poses grows",
    )
    p.add_argument("--geometry", default="paper-hmt", help=f"nominal {GEOMETRY_HELP}")
    p.add_argument(
        "--true", default="paper-hmt-true", help="the real machine, or 'random' (nominal + U(±5 mm))"
    )
    p.add_argument(
        "--poses", default="8,10,15,20,30,45,64", help="numbers of poses (8 to 64), comma-separated"
    )
    p.add_argument("--method", choices=("paper", "length", "ml"), default="length", help="the estimator")
    p.add_argument("--noise", help="noise half-widths, e.g. leg=0.01,pos=0.025,ang=0.001")
    p.add_argument("--noise-dist", choices=("uniform", "normal"), default="uniform")
    p.add_argument("--trials", type=int, default=100)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--jobs", type=int, default=None, help="processes (default: all cores)")
    p.add_argument("--scheduler", metavar="ADDRESS", help=SCHEDULER_HELP)
    p.add_argument("--out", help="folder for selection.json, selection.csv and selection.png")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(
        func=with_scheduler(cmd_study_selection),
        inputs=("geometry", "true"),
        outputs=(),
        folders=("out",),
        folder_files={"out": ("selection.json", "selection.csv", "selection.png")},
    )
