"""Compensation subcommand of ``hexcal``: ``compensate`` (leg commands for targets on the
calibrated machine, and corrected targets for a controller that keeps the nominal geometry).

Imports only the standard library and :mod:`hexcal.cli.common` at its top; the command
imports the library parts it needs when it runs.
"""

from __future__ import annotations

import argparse
from typing import Any

from hexcal.cli.common import (
    EULER_HELP,
    GEOMETRY_HELP,
    CommandError,
    check_outputs,
    id_list,
    load_geometry,
    show_defaults,
    warn,
)


def cmd_compensate(args: argparse.Namespace) -> None:
    """Leg commands that bring the calibrated machine to target poses."""
    from hexcal.core import compensate
    from hexcal.io import read_poses, write_legs, write_poses

    check_outputs(args.out, args.corrected_poses)
    if args.corrected_poses and not args.nominal:
        raise CommandError("--corrected-poses needs --nominal (the controller's geometry)")
    geometry = load_geometry(args.geometry, args.euler)
    targets, ids = read_poses(args.poses, geometry.euler)
    nominal = load_geometry(args.nominal, geometry.euler) if args.nominal else None
    comp = compensate(geometry, targets, ids, nominal)
    bad = comp.infeasible_ids
    if bad and not args.skip_infeasible:
        raise CommandError(
            f"{len(bad)} target(s) outside the leg length limits: {id_list(list(bad))} "
            "(nothing written; --skip-infeasible writes the others)"
        )
    _warn_outside_box(geometry, targets, ids, "target(s)")
    keep = comp.feasible
    kept_ids = [i for i, k in zip(ids, keep, strict=True) if k]
    if args.corrected_poses and comp.corrected_poses is not None:
        _warn_outside_box(geometry, comp.corrected_poses[keep], kept_ids, "corrected pose(s)")
    write_legs(args.out, comp.lengths[keep], comp.readings[keep], kept_ids)
    if args.corrected_poses and comp.corrected_poses is not None:
        write_poses(args.corrected_poses, comp.corrected_poses[keep], kept_ids)
        print(f"wrote corrected target poses for the nominal controller to {args.corrected_poses}")
    if bad:
        warn(f"hexcal: warning: skipped {len(bad)} infeasible target(s): {id_list(list(bad))}")
    print(f"wrote leg commands for {len(kept_ids)} target(s) to {args.out}")


def _warn_outside_box(geometry: Any, poses: Any, ids: list[str], what: str) -> None:
    """One warning line naming the poses outside the geometry's workspace box."""
    import numpy as np

    if geometry.workspace is None or len(poses) == 0:
        return
    box = np.asarray(geometry.workspace)
    tol = 1e-9 * np.maximum(1.0, np.abs(box))
    outside = np.any((poses < box[:, 0] - tol[:, 0]) | (poses > box[:, 1] + tol[:, 1]), axis=1)
    if outside.any():
        bad = [ids[k] for k in np.flatnonzero(outside)]
        warn(f"hexcal: warning: {len(bad)} {what} outside the workspace box: {id_list(bad)}")


def register(sub: Any) -> None:
    """Add ``compensate`` to the subparsers."""
    p = sub.add_parser("compensate", help="leg commands that bring the real machine to targets")
    p.add_argument("--geometry", required=True, help=f"calibrated {GEOMETRY_HELP}")
    p.add_argument("--poses", required=True, help="target pose CSV file")
    p.add_argument("--out", required=True, help="leg CSV file to write (l1..l6, dl1..dl6)")
    p.add_argument("--nominal", help="the controller's (nominal) geometry")
    p.add_argument("--corrected-poses", help="pose CSV file of corrected targets for the nominal controller")
    p.add_argument("--skip-infeasible", action="store_true", help="write the feasible targets only")
    p.add_argument("--euler", help=EULER_HELP)
    p.set_defaults(
        func=cmd_compensate,
        inputs=("geometry", "poses", "nominal"),
        outputs=("out", "corrected_poses"),
        folders=(),
    )
    show_defaults(sub.choices["compensate"])
