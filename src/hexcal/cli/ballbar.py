"""The options of an instrument's own planner on the command line (``hexcal candidates`` and
``hexcal select`` with ``--setup`` of an instrument whose record has a planner, and no
``--candidates``): the ballbar's circles (docs/ballbar.md).

``--pivots`` (``x,y,z;NAME=x,y,z``, mm; NAME prefixes the ids), ``--planes``, ``--tilt``
(degrees), ``--points``, ``--d0`` and, to select, ``--circles``: parsed here into the
planner's options (:func:`planner_options`); the planner (the library's
:class:`hexcal.design.ballbar_selection.BallbarPlanner`) decides their defaults and what is
feasible. Imports only the standard library and :mod:`hexcal.cli.common` at its top.
"""

from __future__ import annotations

import argparse
import math
from typing import Any

from hexcal.cli.common import CommandError

#: The planner options of the command line (dests), besides ``min_distance``.
PLANNER_OPTIONS = ("pivots", "planes", "tilt", "points", "d0", "circles")


def _pivots(text: str) -> tuple[Any, Any]:
    """The pivots of ``--pivots 'x,y,z;NAME=x,y,z'`` and their names."""
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


def given_planner_options(args: argparse.Namespace) -> list[str]:
    """The planner options given on the command line (their option names)."""
    return [f"--{d.replace('_', '-')}" for d in PLANNER_OPTIONS if getattr(args, d, None) is not None]


def planner_options(args: argparse.Namespace) -> dict[str, Any]:
    """The planner's options of the command line: only those given (the planner's defaults for
    the others), ``--tilt`` in rad, ``--min-distance`` as ``min_distance``; ``--circles`` is the
    selection's count, not among them."""
    from hexcal.design.ballbar_plan import PLANES

    given: dict[str, Any] = {"min_distance": args.min_distance}
    if args.planes is not None:
        planes = tuple(p.strip() for p in args.planes.split(",") if p.strip())
        unknown = [p for p in planes if p not in PLANES]
        if unknown or not planes:
            raise CommandError(f"--planes: {', '.join(unknown) or 'none'}; give some of xy, xz, yz")
        given["planes"] = planes
    if args.tilt is not None:
        if not (math.isfinite(args.tilt) and 0 <= args.tilt < 45):
            raise CommandError(f"--tilt {args.tilt}: a tilt from 0 to 45 degrees")
        given["tilt"] = math.radians(args.tilt)
    if args.d0 is not None:
        if not math.isfinite(args.d0):
            raise CommandError(f"--d0 {args.d0}: not a finite number")
        given["d0"] = args.d0
    if args.points is not None:
        given["points"] = args.points
    if args.pivots is not None:
        given["pivots"], given["names"] = _pivots(args.pivots)
    return given
