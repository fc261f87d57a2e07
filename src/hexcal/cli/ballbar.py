"""Ballbar planning on the command line: ``hexcal candidates --ballbar`` and ``hexcal select
--ballbar`` (docs/ballbar.md).

``candidates --ballbar SETUP`` writes the feasible circles of the bar (its ball and length)
at the pivots given by ``--pivots`` (default: seven around the workspace's centre), in the
planes of ``--planes``, the platform level and, with ``--tilt``, tilted about x and y, both
feed directions, ``--points`` per circle; ids ``p{pivot}.c{circle}.{ccw|cw}.{point}``, or
``NAME.c...`` for a pivot given as ``NAME=x,y,z`` (a name no other session of the campaign has).
``select --ballbar SETUP --circles N`` chooses N of those circles (and so the pivots) for
the machine, with the predicted accuracy. The pose file then holds every chosen circle; the
rows of one pivot (ids ``p{k}.``) are one session, measured with the setup of that pivot.

Its options are declared in :mod:`hexcal.cli.plan` (``circle_options``). Imports only the
standard library and :mod:`hexcal.cli.common` at its top.
"""

from __future__ import annotations

import argparse
import math
from typing import Any

from hexcal.cli.common import CommandError, check_outputs, choice, load_geometry
from hexcal.cli.noise import parse_noise


def _pivots(text: str | None) -> tuple[Any, Any]:
    """The pivots of ``--pivots 'x,y,z;NAME=x,y,z'`` and their names (None: the default)."""
    if text is None:
        return None, None
    rows, names = [], []
    for item in text.split(";"):
        name, sep, point = item.strip().rpartition("=")
        names.append(name.strip() if sep else None)
        parts = point.replace(" ", "").split(",")
        try:
            values = [float(v) for v in parts]
        except ValueError:
            raise CommandError(f"--pivots: {item!r} is not x,y,z (mm)") from None
        if len(values) != 3 or not all(math.isfinite(v) for v in values):
            raise CommandError(f"--pivots: {item!r} is not three finite numbers x,y,z (mm)")
        rows.append(values)
    return rows, names


def circles_of(args: argparse.Namespace) -> tuple[Any, Any, int]:
    """The geometry, the feasible candidate circles and how many were infeasible."""
    import numpy as np

    from hexcal.design.ballbar_plan import PLANES, ballbar_circles
    from hexcal.io import load_setup

    geometry = load_geometry(args.geometry, args.euler)
    setup = load_setup(args.ballbar)
    if setup.kind != "ballbar":
        raise CommandError(f"--ballbar {args.ballbar}: not a ballbar setup (it has no 'ballbar:' mapping)")
    given: dict[str, Any] = {}  # the options given; the library's defaults for the others
    if args.planes is not None:
        planes = tuple(p.strip() for p in args.planes.split(",") if p.strip())
        unknown = [p for p in planes if p not in PLANES]
        if unknown or not planes:
            raise CommandError(f"--planes: {', '.join(unknown) or 'none'}; give some of xy, xz, yz")
        given["planes"] = planes
    if args.tilt is not None:
        if not (math.isfinite(args.tilt) and 0 <= args.tilt < 45):
            raise CommandError(f"--tilt {args.tilt}: a tilt from 0 to 45 degrees")
        given["tilt"] = float(np.deg2rad(args.tilt))
    if args.d0 is not None:
        if not math.isfinite(args.d0):
            raise CommandError(f"--d0 {args.d0}: not a finite number")
        given["d0"] = args.d0
    if args.points is not None:
        given["points"] = args.points
    pivots, names = _pivots(args.pivots)
    circles, dropped = ballbar_circles(
        geometry, setup, pivots, min_distance=args.min_distance, names=names, **given
    )
    if circles.n_circles == 0:
        raise CommandError(f"--ballbar: none of the {dropped} circle(s) is feasible for this machine")
    return geometry, circles, dropped


def _pivot_lines(circles: Any) -> list[str]:
    return [
        f"  {circles.pivot_title(k)}: [{', '.join(f'{v:g}' for v in p)}] mm (ids {circles.names[k]}.*)"
        for k, p in enumerate(circles.pivots)
    ]


def cmd_candidates(args: argparse.Namespace) -> None:
    """The feasible circles of a ballbar, as a pose file."""
    from hexcal.io import write_poses

    check_outputs(args.out)
    _, circles, dropped = circles_of(args)
    write_poses(args.out, circles.poses, list(circles.ids), comment=f"ballbar circles of {args.ballbar}")
    print(f"{circles.n_circles} feasible ballbar circle(s) of {circles.n_circles + dropped}, at the pivots:")
    print("\n".join(_pivot_lines(circles)))
    print(f"wrote {len(circles.ids)} pose(s) to {args.out}")


def cmd_select(args: argparse.Namespace) -> None:
    """Circles and pivots for the machine, with the predicted accuracy."""
    from hexcal.core.text import printable
    from hexcal.design.ballbar_selection import circle_accuracy, select_circles
    from hexcal.io import atomic_write, write_poses
    from hexcal.report.jsonout import json_text

    check_outputs(args.out, args.json)
    if args.html:
        raise CommandError("--html: select --ballbar writes the pose file and --json only")
    geometry, circles, dropped = circles_of(args)
    noise = parse_noise(args.noise, choice(args.noise_dist, ("uniform", "normal"), "--noise-dist"))
    chosen = select_circles(geometry, circles, *([] if args.circles is None else [args.circles]), noise=noise,
                            fit=args.fit)  # fmt: skip
    acc = circle_accuracy(geometry, chosen.circles, noise, args.fit)
    used = [int(p) + 1 for p in chosen.pivots_used]
    lines = [
        f"{len(chosen.chosen)} ballbar circle(s) chosen of {circles.n_circles} feasible "
        f"({dropped} infeasible left out), at {len(used)} pivot(s): "
        f"{', '.join(circles.pivot_title(p - 1) for p in used)}",
        *(f"  {label}" for label in chosen.circles.labels),
        *(line for k, line in enumerate(_pivot_lines(circles)) if k + 1 in used),
        f"predicted after calibration ({acc['circle_poses']} poses, {acc['parameters']} parameters, "
        f"{acc['gauges']} gauges, rank {acc['rank']}, "
        f"{'identifiable' if acc['identifiable'] else 'NOT identifiable: choose more circles'}): "
        f"position RMS {acc['position_rms_mm']:.3g} mm (worst {acc['position_max_mm']:.3g}), orientation RMS "
        f"{acc['orientation_rms_rad']:.3g} rad; joints and l0 σ mean {acc['joint_sigma_mean_mm']:.3g} mm",
    ]
    print("\n".join(printable(line) for line in lines))
    write_poses(args.out, chosen.circles.poses, list(chosen.circles.ids), comment="hexcal select --ballbar")
    if args.json:
        data = {
            "circles": [
                {
                    "label": label,
                    "pivot": int(chosen.circles.pivot[k]) + 1,
                    "pivot_name": circles.names[int(chosen.circles.pivot[k])],
                }
                for k, label in enumerate(chosen.circles.labels)
            ],
            "pivots": {str(p): [float(v) for v in circles.pivots[p - 1]] for p in used},
            "accuracy": acc,
            "criterion_trace_mm2": list(chosen.history),
        }
        with atomic_write(args.json) as fh:
            fh.write(json_text(data))
    print(f"wrote {len(chosen.circles.ids)} pose(s) to {args.out}")
