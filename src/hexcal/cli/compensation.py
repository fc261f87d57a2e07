"""Compensation subcommand of ``hexcal``: ``compensate`` (leg commands for targets on the
calibrated machine, corrected targets for a controller that keeps the nominal geometry, and
G-code programs filtered for such a controller).

Imports only the standard library and :mod:`hexcal.cli.common` at its top; the command
imports the library parts it needs when it runs.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Any

from hexcal.cli.common import (
    EULER_HELP,
    GEOMETRY_HELP,
    PRESET_NAMES,
    CommandError,
    check_outputs,
    id_list,
    load_geometry,
    show_defaults,
    table_options,
    table_reading,
    warn,
)

#: Default ``--tolerance`` (mm) and ``--angle-tolerance`` (rad): a micrometre, and the angle
#: that moves a point 100 mm from the platform's origin by a micrometre.
TOLERANCE = 1e-3
ANGLE_TOLERANCE = 1e-5

#: The tightest tolerances accepted: the corrected poses are solved to 1e-9 mm of leg length.
MIN_TOLERANCE = 1e-6
MIN_ANGLE_TOLERANCE = 1e-9


def cmd_compensate(args: argparse.Namespace) -> None:
    """Leg commands that bring the calibrated machine to target poses, or a filtered program."""
    if args.gcode:
        _compensate_program(args)
        return
    from hexcal.core import compensate, stroke_excess
    from hexcal.io import read_table, table_covariates, table_poses, write_legs

    check_outputs(args.out, args.corrected_poses)
    if args.corrected_poses and not args.nominal:
        raise CommandError("--corrected-poses needs --nominal (the controller's geometry)")
    geometry = load_geometry(args.geometry, args.euler)
    table = read_table(args.poses, **table_reading(args))
    targets, ids, covariates = table_poses(table, geometry.euler), table.ids(), table_covariates(table)
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
    kept_ids = list(ids) if keep.all() else [i for i, k in zip(ids, keep, strict=True) if k]
    if args.corrected_poses and comp.corrected_poses is not None:
        _warn_outside_box(geometry, comp.corrected_poses[keep], kept_ids, "corrected pose(s)")
    lengths, readings = comp.lengths, comp.readings
    if not keep.all():  # (every target feasible: no copies of the whole arrays)
        lengths, readings = lengths[keep], readings[keep]
    covariates = covariates.subset(keep)  # carried from the targets to the commands
    write_legs(args.out, lengths, readings, kept_ids, covariates=covariates)
    beyond = stroke_excess(geometry, readings, ids=kept_ids)
    if beyond is not None and (line := beyond.warning("target(s)")):
        warn(f"hexcal: warning: {line}")
    if args.corrected_poses and comp.corrected_poses is not None:
        corrected = comp.corrected_poses[keep]
        _write_poses_like(table, args.corrected_poses, corrected, kept_ids, geometry.euler, covariates)
        print(f"wrote corrected target poses for the nominal controller to {args.corrected_poses}")
    if bad:
        warn(f"hexcal: warning: skipped {len(bad)} infeasible target(s): {id_list(list(bad))}")
    print(f"wrote leg commands for {len(kept_ids)} target(s) to {args.out}")


def _write_poses_like(table: Any, path: str, poses: Any, ids: list[str], euler: str, covariates: Any) -> None:
    """Write poses with the orientation columns of the input table: radians ``a, b, c``,
    degrees ``a_deg, b_deg, c_deg`` or quaternions ``qx, qy, qz, qw``; then the covariates."""
    import numpy as np

    from hexcal.io import ORIENTATION_GROUPS, write_table

    group = next((g for g, cols in ORIENTATION_GROUPS.items() if any(table.has(c) for c in cols)), "rad")
    if group == "deg":
        angles = np.rad2deg(poses[:, 3:])
    elif group == "quat":
        from scipy.spatial.transform import Rotation

        angles = Rotation.from_euler(euler, poses[:, 3:]).as_quat() if len(poses) else np.empty((0, 4))
    else:
        angles = poses[:, 3:]
    extra = covariates.to_columns()
    columns = ("x", "y", "z", *ORIENTATION_GROUPS[group], *extra)
    write_table(path, columns, np.column_stack([poses[:, :3], angles, *extra.values()]), ids)


def _warn_outside_box(geometry: Any, poses: Any, ids: list[str], what: str) -> None:
    """One warning line naming the poses outside the geometry's workspace box."""
    bad = _outside_box(geometry, poses)
    if len(bad):
        names = [ids[k] for k in bad]
        warn(f"hexcal: warning: {len(names)} {what} outside the workspace box: {id_list(names)}")


def _outside_box(geometry: Any, poses: Any) -> Any:
    """Indices of the poses ``(m, 6)`` outside the geometry's workspace box (none without one)."""
    import numpy as np

    if geometry.workspace is None or len(poses) == 0:
        return np.empty(0, dtype=int)
    box = np.asarray(geometry.workspace)
    tol = 1e-9 * np.maximum(1.0, np.abs(box))
    return np.flatnonzero(np.any((poses < box[:, 0] - tol[:, 0]) | (poses > box[:, 1] + tol[:, 1]), axis=1))


# -- G-code programs ---------------------------------------------------------------------------
def _decimals(step: float) -> int:
    """Decimals that write a number to a hundredth of ``step`` (3 to 12).

    >>> _decimals(1e-3), _decimals(1e-3 / 25.4)
    (5, 7)
    """
    return min(12, max(3, math.ceil(-math.log10(step / 100) - 1e-9)))


def _sha256(spec: str, geometry: Any) -> tuple[str, str]:
    """How the header names a geometry, and its SHA-256: of the file, or for a preset of the
    YAML ``hexcal preset NAME --out FILE`` writes."""
    import hashlib

    if spec in PRESET_NAMES:
        import yaml

        from hexcal.core import preset
        from hexcal.io import plain

        text = yaml.safe_dump(plain(preset(spec).to_dict()), sort_keys=False, default_flow_style=None)
        return f"preset {spec}", hashlib.sha256(text.encode()).hexdigest()
    digest = hashlib.sha256()
    with open(spec, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            digest.update(chunk)
    return f"file {spec}", digest.hexdigest()


def _sequence(euler: str) -> str:
    """The rotation of an Euler sequence in words (brackets: a G-code comment has no parentheses).

    >>> _sequence("XYZ")
    'intrinsic XYZ: R = Rx[A] Ry[B] Rz[C]'
    """
    factors = [f"R{axis.lower()}[{name}]" for axis, name in zip(euler, "ABC", strict=True)]
    if euler.islower():
        linuxcnc = ", LinuxCNC's" if euler == "xyz" else ""
        return f"extrinsic {euler}: R = {' '.join(reversed(factors))}{linuxcnc}"
    return f"intrinsic {euler}: R = {' '.join(factors)}"


def _pose_words(pose: Any) -> str:
    """``X.. Y.. Z.. A.. B.. C..`` of a pose (mm, rad) in mm and degrees."""
    values = [*pose[:3], *(math.degrees(v) for v in pose[3:])]
    return " ".join(f"{a}{v:.6f}".rstrip("0").rstrip(".") for a, v in zip("XYZABC", values, strict=True))


def _start(args: argparse.Namespace, geometry: Any) -> Any:
    """The ``--start`` pose (mm and degrees on the command line) in mm and rad."""
    import numpy as np

    if args.start is None:
        if geometry.home_pose is None:
            raise CommandError("--start: the geometry has no home pose; give the pose before the program")
        return np.array(geometry.home_pose, dtype=float)
    try:
        values = [float(v) for v in args.start.split(",")]
    except ValueError:
        raise CommandError(f"--start: {args.start!r} is not six numbers X,Y,Z,A,B,C (mm, degrees)") from None
    if len(values) != 6 or not all(math.isfinite(v) for v in values):
        raise CommandError(f"--start: give six finite numbers X,Y,Z,A,B,C (mm, degrees), got {args.start!r}")
    return np.array([*values[:3], *np.radians(values[3:])])


def _check_program_options(args: argparse.Namespace) -> None:
    for option, dest in (("--corrected-poses", "corrected_poses"), ("--skip-infeasible", "skip_infeasible")):
        if getattr(args, dest):
            raise CommandError(
                f"{option} does not apply to --gcode (a program with a move left out would not follow "
                "its path; every move must be reachable)"
            )
    if not args.nominal:
        raise CommandError("--gcode needs --nominal (the geometry the controller keeps)")
    for option, value, least in (
        ("--tolerance", args.tolerance, MIN_TOLERANCE),
        ("--angle-tolerance", args.angle_tolerance, MIN_ANGLE_TOLERANCE),
    ):
        if not (math.isfinite(value) and value >= least):
            raise CommandError(f"{option}: must be a finite number >= {least:g}, got {value:g}")
    check_outputs(args.out)


class _Lines:
    """Program line numbers of a kind (first few kept, all counted) for one warning line."""

    def __init__(self) -> None:
        self.first: list[str] = []
        self.count = 0

    def add(self, numbers: list[int]) -> None:
        self.count += len(numbers)
        self.first += [f"line {n}" for n in numbers[: max(0, 20 - len(self.first))]]

    def warn(self, what: str) -> None:
        if self.count:
            more = f" ... ({self.count} in all)" if self.count > len(self.first) else ""
            named = ", ".join(self.first) + more
            warn(f"hexcal: warning: {self.count} {what} outside the workspace box: {named}")


def _compensate_program(args: argparse.Namespace) -> None:
    """Filter a G-code program for a controller that keeps the nominal geometry."""
    import os
    from importlib.metadata import version

    from hexcal.calibration import poses_stroke_excess
    from hexcal.core import PathError, correct_path, correct_poses
    from hexcal.errors import InputError
    from hexcal.io import atomic_write, gcode

    _check_program_options(args)
    geometry = load_geometry(args.geometry, args.euler)
    nominal = load_geometry(args.nominal, geometry.euler)
    start = _start(args, geometry)
    try:
        start_corrected = correct_poses(geometry, nominal, start[None], [0])[0]
    except PathError as exc:
        raise CommandError(f"--start: {exc}") from None
    tol, angle_tol = args.tolerance, args.angle_tolerance
    decimals = (_decimals(tol), _decimals(tol / 25.4), _decimals(math.degrees(angle_tol)))
    (cal, cal_sha), (nom, nom_sha) = _sha256(args.geometry, geometry), _sha256(args.nominal, nominal)
    header = [gcode.gcode_comment(text) for text in (
        f"hexcal {version('hexcal')} compensate: corrected for a controller that keeps the nominal geometry",
        f"calibrated geometry: sha256 {cal_sha}, {cal}",
        f'calibrated geometry name: "{geometry.name}"',
        f"nominal geometry: sha256 {nom_sha}, {nom}",
        f'nominal geometry name: "{nominal.name}"',
        f"A B C: degrees, Euler sequence {_sequence(geometry.euler)}",
        f"tolerance along the whole path: {tol:g} mm in position, {angle_tol:g} rad in orientation",
        f"units: the program's, G21 mm unless it selects G20 inch, converted, X Y Z written with "
        f"{decimals[0]} decimals in mm, {decimals[1]} in inch, A B C with {decimals[2]}",
        f"start pose assumed, mm and deg: {_pose_words(start)}",
        f"the controller's pose there: {_pose_words(start_corrected)}",
    )]  # fmt: skip
    size = max(1, os.stat(args.gcode).st_size)
    began, shown, moves, points, lines = time.perf_counter(), 0, 0, 0, 0
    worst = [0.0, 0.0]
    targets_out, corrected_out = _Lines(), _Lines()
    beyond = None
    last = start_corrected
    with atomic_write(args.out) as fh:
        writer = gcode.ProgramWriter(fh, header, decimals, start_corrected)
        for block in gcode.read_program(args.gcode, start, gcode.BLOCK_LINES):
            try:
                path = correct_path(geometry, nominal, block.moves, last, tol, angle_tol)
            except PathError as exc:
                line = block.first_line + int(block.move_lines[exc.move])
                raise InputError(f"{args.gcode}: line {line}: {exc}") from None
            writer.write(block, path)
            if len(path.corrected):
                last = path.corrected[-1]
            numbers = (block.first_line + block.move_lines).tolist()
            targets_out.add([numbers[k] for k in _outside_box(geometry, block.moves.end)])
            corrected_out.add(sorted({numbers[path.move[k]] for k in _outside_box(geometry, path.corrected)}))
            part = poses_stroke_excess(geometry, block.moves.end, ids=[f"line {n}" for n in numbers])
            beyond = part if beyond is None or part is None else beyond.merge(part)
            moves, points, lines = moves + len(block.moves), points + len(path.move), lines + len(block.lines)
            worst = [max(worst[0], path.position), max(worst[1], path.orientation)]
            if not args.quiet and (block.chars * 10 // size > shown or block.chars >= size):
                shown = block.chars * 10 // size
                elapsed = time.perf_counter() - began
                note = f"  compensate: {min(100, 10 * shown)}% ({lines:,} lines, {elapsed:.1f} s)"
                print(note, file=sys.stderr, flush=True)
    targets_out.warn("target(s) of the program")
    corrected_out.warn("corrected move(s)")
    if beyond is not None and (line := beyond.warning("target(s) of the program")):
        warn(f"hexcal: warning: {line}")
    print(
        f"wrote {args.out}: {lines:,} lines read, {moves:,} moves corrected as {points:,} "
        f"({points - moves:,} added to follow the path); largest deviation at the checked midpoints "
        f"{worst[0]:.3g} mm, {worst[1]:.3g} rad (tolerance {tol:g} mm, {angle_tol:g} rad)"
    )


def register(sub: Any) -> None:
    """Add ``compensate`` to the subparsers."""
    p = sub.add_parser("compensate", help="leg commands that bring the real machine to targets")
    p.add_argument("--geometry", required=True, help=f"calibrated {GEOMETRY_HELP}")
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--poses", help="target pose CSV file")
    source.add_argument("--gcode", help="G-code program to filter for a nominal controller (needs --nominal)")
    p.add_argument(
        "--out", required=True, help="leg CSV file to write (l1..l6, dl1..dl6); with --gcode, the program"
    )
    p.add_argument("--nominal", help="the controller's (nominal) geometry")
    p.add_argument(
        "--corrected-poses",
        help="pose CSV file of corrected targets for the nominal controller (angles as in --poses)",
    )
    p.add_argument("--skip-infeasible", action="store_true", help="write the feasible targets only")
    p.add_argument("--euler", help=EULER_HELP + "; with --gcode, of the program's A B C (degrees)")
    p.add_argument("--tolerance", type=float, default=TOLERANCE, help="with --gcode: mm along the path")
    p.add_argument(
        "--angle-tolerance", type=float, default=ANGLE_TOLERANCE, help="with --gcode: rad along the path"
    )
    p.add_argument(
        "--start",
        help="with --gcode: pose X,Y,Z,A,B,C (mm, degrees) before the program (default: the home pose)",
    )
    p.add_argument("--quiet", action="store_true", help="with --gcode: no progress lines")
    table_options(p, "--poses")
    p.set_defaults(
        func=cmd_compensate,
        inputs=("geometry", "poses", "nominal", "gcode"),
        outputs=("out", "corrected_poses"),
        folders=(),
    )
    show_defaults(sub.choices["compensate"])
