"""Kinematics subcommands of ``hexcal``: ``preset``, ``ik`` and ``fk``.

Imports only the standard library and :mod:`hexcal.cli.common` at its top; each command
imports the library parts it needs when it runs (``hexcal ik`` never loads scipy).
"""

from __future__ import annotations

import argparse
from typing import Any

from hexcal.cli.common import (
    EULER_HELP,
    GEOMETRY_HELP,
    PRESET_NAMES,
    CommandError,
    id_list,
    load_geometry,
    warn,
)


def cmd_preset(args: argparse.Namespace) -> None:
    """Write a built-in geometry to a YAML file."""
    from hexcal.io import save_geometry

    save_geometry(load_geometry(args.name), args.out)
    print(f"wrote preset {args.name} to {args.out}")


def cmd_ik(args: argparse.Namespace) -> None:
    """Leg lengths and readings of the poses of a file; warns of poses beyond the leg limits."""
    import numpy as np

    from hexcal.core import inverse_kinematics, is_feasible, leg_readings
    from hexcal.io import read_poses, write_legs

    geometry = load_geometry(args.geometry, args.euler)
    poses, ids = read_poses(args.poses, geometry.euler)
    lengths = inverse_kinematics(geometry, poses)
    feasible = is_feasible(geometry, poses, margin=1e-6)
    if not feasible.all():
        bad = [ids[k] for k in np.flatnonzero(~feasible)]
        warn(f"hexcal: warning: {len(bad)} pose(s) outside the leg length limits: {id_list(bad)}")
    write_legs(args.out, lengths, leg_readings(geometry, lengths), ids)
    print(f"wrote leg lengths of {len(ids)} pose(s) to {args.out}")


def cmd_fk(args: argparse.Namespace) -> None:
    """Poses of the leg lengths (or readings) of a file, by forward kinematics."""
    import numpy as np

    from hexcal.core import forward_kinematics, leg_lengths, leg_limit_violations
    from hexcal.io import read_legs, read_poses, write_poses

    geometry = load_geometry(args.geometry, args.euler)
    legs = read_legs(args.legs)
    lengths = legs.lengths if legs.lengths is not None else leg_lengths(geometry, legs.readings)
    short, long = leg_limit_violations(geometry, lengths)
    outside = np.flatnonzero(short | long)
    if outside.size:
        lo, hi = geometry.leg_length_limits
        bad = [legs.ids[k] for k in outside]
        raise CommandError(
            f"{args.legs}: {len(bad)} row(s) outside the leg length limits "
            f"[{lo:g}, {hi:g}] mm (ids {id_list(bad)})"
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
            f"(ids {id_list(bad)}): leg lengths "
            "out of reach, or start too far (try --guess)"
        )
    write_poses(args.out, result.poses, legs.ids)
    print(
        f"wrote {len(legs.ids)} pose(s) to {args.out} (max leg residual "
        f"{result.residual.max():.1e} mm, at most {result.iterations.max()} iterations)"
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
    p.add_argument("--out", required=True, help="leg CSV file to write (l1..l6, dl1..dl6)")
    p.add_argument("--euler", help=EULER_HELP)
    p.set_defaults(func=cmd_ik, inputs=("geometry", "poses"), outputs=("out",), folders=())

    p = sub.add_parser("fk", help="forward kinematics: poses of leg lengths or readings")
    p.add_argument("--geometry", required=True, help=GEOMETRY_HELP)
    p.add_argument("--legs", required=True, help="leg CSV file (l1..l6 or dl1..dl6)")
    p.add_argument("--out", required=True, help="pose CSV file to write")
    p.add_argument("--guess", help="pose CSV file of starting poses (default: the home pose)")
    p.add_argument("--euler", help=EULER_HELP)
    p.add_argument("--tol", type=float, default=1e-9, help="leg length tolerance, mm")
    p.set_defaults(func=cmd_fk, inputs=("geometry", "legs", "guess"), outputs=("out",), folders=())
