"""Planning subcommands of ``hexcal``: error maps, observability, candidates, pose selection.

- ``hexcal errormap``: the seed paper's Figs. 4-9 (PNG) and the numbers behind them (CSV),
  with the numbers that test its boundary and height claims;
- ``hexcal observability``: indices O1-O5, rank, lost parameter combinations, predicted
  parameter and pose errors of a pose file;
- ``hexcal candidates``: feasible candidate poses (corners, grids, random, files);
- ``hexcal select``: optimal measurement poses (greedy + exchange), beside the seed
  paper's strategy and random interior poses.

Imports only the standard library and :mod:`hexcal.cli.common` at its top. Known failures
raise :class:`hexcal.cli.common.CommandError` or another :class:`hexcal.errors.HexcalError`,
which ``hexcal.cli.main`` prints as one line.
"""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING, Any

from hexcal.cli.common import (
    EULER_HELP,
    GEOMETRY_HELP,
    CommandError,
    candidate_files,
    candidate_spec,
    check_outputs,
    choice,
    feasible_candidates,
    fit_mask,
    fitted_groups,
    id_list,
    load_geometry,
    show_defaults,
    table_options,
    table_reading,
    warn,
)
from hexcal.cli.noise import NOISE_HELP, parse_noise, refuse_zero_noise

if TYPE_CHECKING:
    from pathlib import Path

#: Figure names of the error maps, after the seed paper's figure numbers.
ERRORMAP_FIGURES = {
    "x": "fig4_x.png",
    "y": "fig5_y.png",
    "z": "fig6_z.png",
    "a-b": "fig7_a-b.png",
    "a-c": "fig8_a-c.png",
    "b-c": "fig9_b-c.png",
}

#: Every file ``hexcal errormap`` writes into ``--out``: figures, tables (``errormap_tables``), claims.
ERRORMAP_FILES = (*ERRORMAP_FIGURES.values(), "claims.json")
ERRORMAP_FILES += tuple(f"errormap_{name}.csv" for name in (*ERRORMAP_FIGURES, "corners", "interior"))

CANDIDATES_HELP = "corners, grid[:L], edges[:L], random:N, FILE; join with +"
FIT_HELP = "parameter groups: joints, base, platform, l0, gains"


# -- helpers ---------------------------------------------------------------------------------


def _noise(args: argparse.Namespace) -> Any:
    noise = parse_noise(args.noise, choice(args.noise_dist, ("uniform", "normal"), "--noise-dist"))
    return refuse_zero_noise(noise, "every predicted accuracy")


# -- errormap -----------------------------------------------------------------------------------


def _errormap_options(args: argparse.Namespace) -> tuple[str, Any, Path]:
    """The checked ``--method``, parameter mask and ``--out`` folder of ``hexcal errormap``."""
    from pathlib import Path

    method = choice(args.method, ("linear", "exact"), "--method")
    mask = fit_mask(args.fit)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise CommandError(f"--out {out}: exists and is not a folder")
    if not out.parent.is_dir():
        raise CommandError(f"--out {out}: the folder {out.parent} does not exist")
    for name, value, low in (
        ("--levels", args.levels, 1),
        ("--points", args.points, 2),
        ("--grid", args.grid, 2),
    ):
        if value < low:
            raise CommandError(f"{name} must be at least {low}, got {value}")
    if args.draws < 1:
        raise CommandError(f"--draws must be at least 1, got {args.draws}")
    if not (math.isfinite(args.amplitude) and args.amplitude > 0):
        raise CommandError(f"--amplitude must be a finite value > 0, got {args.amplitude}")
    return method, mask, out


def cmd_errormap(args: argparse.Namespace) -> None:
    """Pose error maps of random parameter errors, their tables and the claims they test."""
    from hexcal.design import claims, error_maps
    from hexcal.io import atomic_write, write_table
    from hexcal.report import errormap_tables, plot_error_angles, plot_error_lines, render

    geometry = load_geometry(args.geometry, args.euler)
    method, mask, out = _errormap_options(args)
    if geometry.workspace is None:
        raise CommandError("the geometry has no workspace box: add a 'workspace:' mapping")
    maps = error_maps(
        geometry,
        levels=args.levels,
        points=args.points,
        grid=args.grid,
        draws=args.draws,
        amplitude=args.amplitude,
        mask=mask,
        rng=args.seed,
        method=method,
    )
    summary = claims(maps)
    out.mkdir(exist_ok=True)
    for name, (columns, rows, ids, comment) in errormap_tables(maps).items():
        write_table(out / f"errormap_{name}.csv", columns, rows, ids, comment=comment)
    note = f"parameter errors uniform in ±{args.amplitude:g} mm · {args.draws} draws ({method})"
    note += f" · seed {args.seed}"
    for axis, line in maps.lines.items():
        plot_error_lines(line, out / ERRORMAP_FIGURES[axis], note=note)
    for name, grid in maps.angles.items():
        plot_error_angles(grid, out / ERRORMAP_FIGURES[name], note=note)
    settings = {
        "geometry": geometry.name or str(args.geometry),
        "levels": args.levels,
        "points": args.points,
        "grid": args.grid,
        "draws": args.draws,
        "amplitude_mm": args.amplitude,
        "method": method,
        "seed": args.seed,
        "parameters": list(maps.parameters),
    }
    with atomic_write(out / "claims.json") as fh:
        fh.write(render("claims", {"settings": settings, "claims": summary}, "json"))
    print(
        f"Error maps of {geometry.name or args.geometry}: parameter errors uniform in "
        f"±{args.amplitude:g} mm, {args.draws} draws, {args.levels} levels ({method})"
    )
    print(render("claims", summary))
    print(
        f"wrote {len(ERRORMAP_FIGURES)} figures, {len(ERRORMAP_FIGURES) + 2} CSV tables and "
        f"claims.json to {out}"
    )


# -- observability ------------------------------------------------------------------------------


def cmd_observability(args: argparse.Namespace) -> None:
    """Observability indices and predicted accuracy of a pose file, for any instrument."""
    import numpy as np

    from hexcal.core import workspace_corners
    from hexcal.design import SCALINGS, analyse_poses, check_feasibility
    from hexcal.io import atomic_write, load_instrument, read_poses
    from hexcal.report import render

    check_outputs(args.json, args.html)
    geometry = load_geometry(args.geometry, args.euler)
    instrument = load_instrument(args.setup, geometry.euler)
    scaling = choice(args.scaling, SCALINGS, "--scaling")
    method = choice(args.method, ("ml", "length", "paper"), "--method")
    mask = fit_mask(args.fit, geometry=geometry)
    noise = _noise(args)
    poses, ids = read_poses(args.poses, geometry.euler, **table_reading(args))
    if args.test_poses:
        test, _ = read_poses(args.test_poses, geometry.euler)
    elif geometry.workspace is not None:
        test = workspace_corners(geometry)
    else:
        test = None
    try:
        analysis = analyse_poses(
            geometry, poses, noise, mask, test, scaling, method, args.weighted, instrument, args.fix or ()
        )
    except np.linalg.LinAlgError as exc:
        raise CommandError(f"{args.poses}: cannot analyse these poses ({exc})") from None
    report = check_feasibility(geometry, poses)
    if report.n_infeasible:
        bad = [ids[k] for k in np.flatnonzero(~report.feasible)]
        warn(f"hexcal: warning: {args.poses}: {report.summary()} (ids {id_list(bad)})")
    data = analysis.to_dict()
    print(render("observability", data, fit=fitted_groups(args.fit, geometry)))
    if args.json:
        with atomic_write(args.json) as fh:
            fh.write(render("observability", data, "json"))
        print(f"wrote {args.json}")
    if args.html:
        from hexcal.cli.common import inputs_record
        from hexcal.report import observability_report, render_html

        files = {
            "geometry": args.geometry,
            "poses": args.poses,
            "test poses": args.test_poses,
            "setup": args.setup,
        }
        page = observability_report(data, poses, geometry.workspace, inputs_record(files, args))
        with atomic_write(args.html) as fh:
            fh.write(render_html(page))
        print(f"wrote the HTML report to {args.html}")


# -- candidates and select ---------------------------------------------------------------------


def cmd_candidates(args: argparse.Namespace) -> None:
    """The feasible candidate poses of a ``--candidates`` spec."""
    from hexcal.io import write_poses

    if args.ballbar:  # circles of a ballbar (cli/ballbar.py)
        from hexcal.cli.ballbar import cmd_candidates as circles

        return circles(args)
    check_outputs(args.out)
    geometry = load_geometry(args.geometry, args.euler)
    poses, ids = candidate_spec(args.candidates, geometry, args.seed)
    feasible, kept, warning = feasible_candidates(geometry, poses, ids, args.min_distance)
    if warning:
        warn(warning)
    write_poses(args.out, feasible, kept, comment=f"feasible candidates {args.candidates} (seed {args.seed})")
    print(f"wrote {len(kept)} feasible of {len(ids)} candidate pose(s) to {args.out}")


def cmd_select(args: argparse.Namespace) -> None:
    """Optimal measurement poses for any instrument, beside the seed paper's strategy and
    random poses."""
    from hexcal.design import CRITERIA
    from hexcal.design.planning import plan_selection
    from hexcal.io import atomic_write, load_instrument, write_poses
    from hexcal.report import render

    if args.ballbar:  # circles and pivots of a ballbar (cli/ballbar.py)
        from hexcal.cli.ballbar import cmd_select as choose

        return choose(args)
    check_outputs(args.out, args.json, args.html)
    geometry = load_geometry(args.geometry, args.euler)
    instrument = load_instrument(args.setup, geometry.euler)
    criterion = choice(args.criterion, CRITERIA, "--criterion")
    strategy = choice(args.strategy, ("optimal", "paper"), "--strategy")
    mask = fit_mask(args.fit, geometry=geometry)
    noise = _noise(args)
    n = args.n
    candidates = kept = warning = None
    if strategy == "optimal":
        poses, cand_ids = candidate_spec(args.candidates, geometry, args.seed)
        candidates, kept, warning = feasible_candidates(geometry, poses, cand_ids, args.min_distance)
        if n > len(kept):
            dropped = f" ({len(cand_ids) - len(kept)} infeasible left out)" if warning else ""
            raise CommandError(f"--n {n}: only {len(kept)} feasible candidate pose(s){dropped}")
    selection = plan_selection(
        geometry,
        n,
        noise,
        mask,
        args.seed,
        strategy=strategy,
        candidates=candidates,
        candidate_ids=kept,
        criterion=criterion,
        exchange=not args.no_exchange,
        min_distance=args.min_distance,
        spec=args.candidates,
        seed=args.seed,
        instrument=instrument,
        fix=args.fix or (),
    )
    data = selection.to_dict()
    print(render("select", data))
    if warning:
        warn(warning)
    write_poses(args.out, selection.poses, selection.ids, comment=f"hexcal select: {selection.label}")
    if args.json:
        with atomic_write(args.json) as fh:
            fh.write(render("select", data, "json"))
    print(f"wrote {n} pose(s) to {args.out}")
    if args.html:
        from hexcal.cli.common import inputs_record
        from hexcal.report import render_html, selection_report

        files = {"geometry": args.geometry, "setup": args.setup}
        files |= {f"candidates {k + 1}": f for k, f in enumerate(candidate_files(args.candidates))}
        page = selection_report(data, selection.poses, geometry.workspace, inputs_record(files, args))
        with atomic_write(args.html) as fh:
            fh.write(render_html(page))
        print(f"wrote the HTML report to {args.html}")


# -- parser -------------------------------------------------------------------------------------
def circle_options(p: argparse.ArgumentParser, select: bool = False) -> None:
    """The ballbar options of ``candidates`` and ``select`` (the work: hexcal.cli.ballbar)."""
    p.add_argument("--ballbar", metavar="FILE", help="ballbar setup YAML: its circles instead of poses")
    p.add_argument(
        "--pivots",
        help="ballbar pivots 'x,y,z;NAME=x,y,z', mm; NAME prefixes the ids (default p1, p2, ...; pivots: "
        "seven about the centre)",
    )
    p.add_argument("--planes", help="ballbar circle planes (of xy, xz, yz; default all three)")
    p.add_argument("--tilt", type=float, help="ballbar: circles also tilted ± this about x, y (default 8°)")
    p.add_argument("--points", type=int, help="ballbar: points per circle (default 12)")
    p.add_argument("--d0", type=float, help="ballbar: bar reading along the circles, mm (default 0)")
    needs = {dest: "ballbar" for dest in ("pivots", "planes", "tilt", "points", "d0")}
    if select:
        p.add_argument("--circles", type=int, help="ballbar: circles to choose (default 12)")
        needs["circles"] = "ballbar"
    p.set_defaults(needs=needs)  # each refused without --ballbar (cli.safety)


def register(sub: Any) -> None:
    """Add the planning subcommands to the ``hexcal`` parser's subparsers."""
    p = sub.add_parser("errormap", help="pose error maps of random parameter errors (paper Figs. 4-9)")
    p.add_argument("--geometry", required=True, help=f"nominal {GEOMETRY_HELP} (with a workspace box)")
    p.add_argument("--out", required=True, help="folder for the figures, CSV tables and claims.json")
    p.add_argument("--levels", type=int, default=100, help="curves per sweep / z levels (paper: 100)")
    p.add_argument("--points", type=int, default=41, help="points along each line sweep")
    p.add_argument("--grid", type=int, default=21, help="points per angle of the angle grids")
    p.add_argument("--draws", type=int, default=200, help="random parameter error draws")
    p.add_argument("--amplitude", type=float, default=0.1, help="parameter errors uniform in ±this, mm")
    p.add_argument(
        "--fit", default="joints,l0", help="parameters with errors: joints, base, platform, l0, gains"
    )
    p.add_argument(
        "--method", default="linear", help="linear (first-order map) or exact (forward kinematics)"
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--euler", help=EULER_HELP)
    files = {"folder_files": {"out": ERRORMAP_FILES}}  # declared: each checked before the work
    p.set_defaults(func=cmd_errormap, inputs=("geometry",), outputs=(), folders=("out",), **files)

    p = sub.add_parser("observability", help="observability indices and predicted accuracy of a pose set")
    p.add_argument("--geometry", required=True, help=f"nominal {GEOMETRY_HELP}")
    p.add_argument("--poses", required=True, help="pose CSV file of the planned measurement poses")
    p.add_argument("--json", help="save the results as JSON")
    p.add_argument("--html", metavar="FILE", help="save a self-contained HTML report (indices, figures)")
    p.add_argument("--noise", help=NOISE_HELP)
    p.add_argument("--noise-dist", default="uniform", help="uniform (default) or normal")
    p.add_argument("--fit", default="joints,l0", help=FIT_HELP)
    p.add_argument("--test-poses", help="pose CSV file where to predict the pose error (default: corners)")
    p.add_argument("--scaling", default="norm", help="column scaling of the indices: norm, parameter, none")
    p.add_argument("--weighted", action="store_true", help="indices of the noise-whitened Jacobian")
    p.add_argument(
        "--method",
        default="ml",
        help="estimator predicted: ml (identify's default; its covariance is the Cramér–Rao bound), "
        "length or paper (default %(default)s)",
    )
    p.add_argument("--euler", help=EULER_HELP)
    p.add_argument("--setup", metavar="FILE", help="instrument setup YAML: plan for targets or a tool")
    p.add_argument("--fix", nargs="+", metavar="NAME", help="parameters or groups to hold, e.g. frame")
    table_options(p, "--poses", "; --test-poses is read with hexcal's names")
    p.set_defaults(
        func=cmd_observability,
        inputs=("geometry", "poses", "test_poses", "setup"),
        outputs=("json", "html"),
        folders=(),
    )

    p = sub.add_parser("candidates", help="feasible candidate measurement poses")
    p.add_argument("--geometry", required=True, help=f"nominal {GEOMETRY_HELP}")
    p.add_argument("--candidates", default="grid", help=CANDIDATES_HELP)
    p.add_argument("--out", required=True, help="pose CSV file of the feasible candidates")
    p.add_argument("--min-distance", type=float, help="minimum singularity distance (default 0.05)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--euler", help=EULER_HELP)
    circle_options(p)
    spec = {"input_lists": {"candidates": candidate_files}}  # the files of a spec are inputs
    p.set_defaults(func=cmd_candidates, inputs=("geometry", "ballbar"), outputs=("out",), folders=(), **spec)

    p = sub.add_parser("select", help="select optimal measurement poses (greedy + exchange)")
    p.add_argument("--geometry", required=True, help=f"nominal {GEOMETRY_HELP}")
    p.add_argument("--n", type=int, default=15, help="number of poses (default 15, as the paper)")
    p.add_argument(
        "--criterion",
        default="A",
        help="D, A, E or O4 (default %(default)s: A-optimal, the closest to the mean absolute error, "
        "as simulate --strategies selected; the default was D before)",
    )
    p.add_argument("--candidates", default="grid", help=CANDIDATES_HELP)
    p.add_argument("--strategy", default="optimal", help="optimal (default) or paper (n random corners)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", required=True, help="pose CSV file of the selected poses")
    p.add_argument("--json", help="save the selection and predictions as JSON")
    p.add_argument("--html", metavar="FILE", help="save a self-contained HTML report (poses, predictions)")
    p.add_argument("--noise", help=NOISE_HELP)
    p.add_argument("--noise-dist", default="uniform", help="uniform (default) or normal")
    p.add_argument("--fit", default="joints,l0", help=FIT_HELP)
    p.add_argument("--min-distance", type=float, help="minimum singularity distance (default 0.05)")
    p.add_argument("--no-exchange", action="store_true", help="greedy selection only")
    p.add_argument("--euler", help=EULER_HELP)
    p.add_argument("--setup", metavar="FILE", help="instrument setup YAML: poses optimal for it")
    p.add_argument("--fix", nargs="+", metavar="NAME", help="parameters or groups to hold, e.g. frame")
    circle_options(p, select=True)
    p.set_defaults(
        func=cmd_select, inputs=("geometry", "setup", "ballbar"), outputs=("out", "json", "html"), **spec
    )
    p.set_defaults(folders=())
    for name in ("errormap", "observability", "candidates", "select"):
        show_defaults(sub.choices[name])
