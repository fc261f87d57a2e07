"""Kinematics subcommands of ``hexcal``: ``preset``, ``ik`` and ``fk``.

Imports only the standard library and :mod:`hexcal.cli.common` at its top; each command
imports the library parts it needs when it runs (``hexcal ik`` never loads scipy).
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from typing import Any

from hexcal.cli.common import (
    EULER_HELP,
    GEOMETRY_HELP,
    PRESET_NAMES,
    CommandError,
    id_list,
    load_geometry,
    show_defaults,
    table_options,
    table_reading,
    warn,
)


def cmd_preset(args: argparse.Namespace) -> None:
    """Write a built-in geometry to a YAML file."""
    from hexcal.io import save_geometry

    save_geometry(load_geometry(args.name), args.out)
    print(f"wrote preset {args.name} to {args.out}")


def _first_then(first: list[Any], rest: Iterator[Any]) -> Iterator[Any]:
    """The block of ``first`` (a block read ahead, for its columns; let go once given, so that
    memory holds one block at a time), then the blocks of ``rest``."""
    while first:
        yield first.pop()
    yield from rest


def cmd_ik(args: argparse.Namespace) -> None:
    """Leg lengths and readings of the poses of a file, block by block (bounded memory).

    Warns of poses beyond the leg limits, and beyond a stroke model's calibrated stroke;
    ``--out -`` writes the table to standard output. The covariate columns of the poses (time,
    leg temperatures, payload) are carried along.
    """
    import numpy as np

    from hexcal.core import inverse_kinematics, is_feasible, leg_readings, stroke_excess
    from hexcal.io import LEG_LENGTH_COLUMNS, LEG_READING_COLUMNS, iter_poses, write_table_blocks

    geometry = load_geometry(args.geometry, args.euler)
    bad: list[str] = []
    outside = 0
    beyond = None

    read = iter_poses(args.poses, geometry.euler, **table_reading(args), covariates=True)
    first = [next(read)]  # its covariate columns are the file's
    extra = tuple(first[0][2].to_columns())

    def blocks() -> Any:
        nonlocal outside, beyond
        for poses, ids, covariates in _first_then(first, read):
            lengths = inverse_kinematics(geometry, poses)
            feasible = is_feasible(geometry, poses, margin=1e-6)
            if not feasible.all():
                rows = np.flatnonzero(~feasible)
                outside += rows.size
                bad.extend(ids[k] for k in rows[: max(0, 21 - len(bad))])
            readings = leg_readings(geometry, lengths)
            part = stroke_excess(geometry, readings, ids=ids)
            beyond = part if beyond is None or part is None else beyond.merge(part)
            more = covariates.to_columns().values()
            yield np.column_stack([lengths, readings, *more]), ids

    rows = write_table_blocks(args.out, LEG_LENGTH_COLUMNS + LEG_READING_COLUMNS + extra, blocks())
    if outside:
        more = f" and {outside - len(bad)} more" if outside > len(bad) else ""
        warn(f"hexcal: warning: {outside} pose(s) outside the leg length limits: {', '.join(bad)}{more}")
    _warn_beyond_stroke(beyond, "pose(s)")
    if args.out != "-":
        print(f"wrote leg lengths of {rows} pose(s) to {args.out}")


def _warn_beyond_stroke(beyond: Any, what: str) -> None:
    """The library's warning line of rows beyond the calibrated stroke, if any."""
    line = beyond.warning(what) if beyond is not None else None
    if line:
        warn(f"hexcal: warning: {line}")


def cmd_fk(args: argparse.Namespace) -> None:
    """Poses of the leg lengths (or readings) of a file, by forward kinematics, block by block
    (the covariate columns of the legs carried along); warns of readings beyond a stroke model's
    calibrated stroke."""
    import numpy as np

    from hexcal.core import (
        forward_kinematics,
        leg_lengths,
        leg_limit_violations,
        pose_jacobian_from_arrays,
        stroke_excess,
    )
    from hexcal.io import iter_legs, iter_poses, write_table_blocks

    geometry = load_geometry(args.geometry, args.euler)
    if not args.guess and geometry.home_pose is None:
        raise CommandError("the geometry has no home_pose: give starting poses with --guess")
    guesses = iter_poses(args.guess, geometry.euler) if args.guess else None
    if guesses is None:
        home_lengths, home_jacobian = pose_jacobian_from_arrays(
            geometry.base_joints, geometry.platform_joints, geometry.home_pose, geometry.euler
        )
        home_step = np.linalg.inv(home_jacobian)
    stats = {"rows": 0, "residual": 0.0, "iterations": 0}
    read = iter_legs(args.legs, **table_reading(args))
    first = [next(read)]  # its covariate columns are the file's
    extra = tuple(first[0].covariates.to_columns())
    beyond = None

    def blocks() -> Any:
        nonlocal beyond
        pending = np.empty((0, 6))
        warned = False
        for legs in _first_then(first, read):
            if legs.readings is not None:  # the controller's readings, through l0 and the gains
                if legs.has_lengths and not warned:  # the lengths stay unconverted
                    warn(
                        f"hexcal: {args.legs} has both l and dl columns: using dl (the controller's readings)"
                    )
                    warned = True
                lengths = leg_lengths(geometry, legs.readings)
                part = stroke_excess(geometry, legs.readings, ids=legs.ids)
                beyond = part if beyond is None or part is None else beyond.merge(part)
            else:
                lengths = legs.lengths
            short, long = leg_limit_violations(geometry, lengths)
            outside = np.flatnonzero(short | long)
            if outside.size:
                lo, hi = geometry.leg_length_limits
                hint = ""
                if legs.readings is not None:
                    as_lengths = legs.readings[outside]
                    if np.all((as_lengths >= lo) & (as_lengths <= hi)):
                        hint = (
                            "; these dl are themselves within the limits: absolute strut lengths (a "
                            "controller's joint positions)? give them as l1..l6, or dl = joint position "
                            "- HOME_OFFSET"
                        )
                raise CommandError(
                    f"{args.legs}: row(s) outside the leg length limits [{lo:g}, {hi:g}] mm "
                    f"(ids {id_list([legs.ids[k] for k in outside])}){hint}"
                )
            if guesses is None:
                # the first Newton step from the home pose, for all rows at once: one 6x6
                # Jacobian instead of one per row (the iteration then starts one step closer)
                guess = geometry.home_pose + (lengths - home_lengths) @ home_step.T
            else:
                while len(pending) < len(lengths):
                    more = next(guesses, None)
                    if more is None:
                        raise CommandError(f"{args.guess}: fewer guess poses than rows of {args.legs}")
                    pending = np.concatenate([pending, more[0]])
                guess, pending = pending[: len(lengths)], pending[len(lengths) :]
            result = forward_kinematics(geometry, lengths, guess=guess, tol=args.tol)
            if not result.all_converged:
                bad = [legs.ids[k] for k in np.flatnonzero(~result.converged)]
                raise CommandError(
                    f"forward kinematics did not converge within --tol {args.tol:g} mm for "
                    f"row(s) of {args.legs} (ids {id_list(bad)}): leg lengths out of reach, "
                    "or start too far (try --guess)"
                )
            stats["rows"] += len(lengths)
            stats["residual"] = max(stats["residual"], float(result.residual.max()))
            stats["iterations"] = max(stats["iterations"], int(result.iterations.max()))
            yield np.column_stack([result.poses, *legs.covariates.to_columns().values()]), legs.ids
        if guesses is not None and (len(pending) or next(guesses, None) is not None):
            raise CommandError(f"{args.guess}: more guess poses than rows of {args.legs}")

    write_table_blocks(args.out, ("x", "y", "z", "a", "b", "c", *extra), blocks())
    _warn_beyond_stroke(beyond, "row(s) of readings")
    if args.out != "-":
        print(
            f"wrote {stats['rows']} pose(s) to {args.out} (max leg residual "
            f"{stats['residual']:.1e} mm, at most {stats['iterations']} iterations)"
        )


def register(sub: Any) -> None:
    """Add ``preset``, ``ik`` and ``fk`` to the ``hexcal`` parser's subparsers."""
    p = sub.add_parser("preset", help="write a built-in geometry to a YAML file")
    p.add_argument("name", choices=sorted(PRESET_NAMES))
    p.add_argument("--out", required=True, help="YAML file to write")
    p.set_defaults(func=cmd_preset, inputs=(), outputs=("out",), folders=())

    p = sub.add_parser("ik", help="inverse kinematics: leg lengths of poses")
    p.add_argument("--geometry", required=True, help=GEOMETRY_HELP)
    p.add_argument("--poses", required=True, help="pose CSV file")
    p.add_argument("--out", required=True, help="leg CSV file to write (l1..l6, dl1..dl6; - for stdout)")
    p.add_argument("--euler", help=EULER_HELP)
    table_options(p, "--poses")
    p.set_defaults(func=cmd_ik, inputs=("geometry", "poses"), outputs=("out",), folders=())

    p = sub.add_parser("fk", help="forward kinematics: poses of leg lengths or readings")
    p.add_argument("--geometry", required=True, help=GEOMETRY_HELP)
    p.add_argument(
        "--legs",
        required=True,
        help="leg CSV file (lengths l1..l6 in mm, or readings dl1..dl6 in the unit of the geometry's "
        "gains: mm, or revolutions with gains in mm per revolution; dl is used when both are given)",
    )
    p.add_argument("--out", required=True, help="pose CSV file to write; - for standard output")
    p.add_argument("--guess", help="pose CSV file of starting poses (default: the home pose)")
    p.add_argument("--euler", help=EULER_HELP)
    p.add_argument("--tol", type=float, default=1e-9, help="leg length tolerance, mm")
    table_options(p, "--legs", "; --guess is read with hexcal's names")
    p.set_defaults(func=cmd_fk, inputs=("geometry", "legs", "guess"), outputs=("out",), folders=())
    for name in ("preset", "ik", "fk"):
        show_defaults(sub.choices[name])
