"""The ``hexcal`` command line: thin subcommands over the library.

Every known failure (bad file, bad option, unreachable pose, no convergence) ends
with one line ``hexcal: error: ...`` on stderr and exit status 1, and no output file.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hexcal.geometry import Geometry, GeometryError
from hexcal.identification import IdentificationError
from hexcal.io import (
    InputError,
    atomic_write,
    load_geometry,
    read_legs,
    read_poses,
    save_geometry,
    write_legs,
    write_poses,
)
from hexcal.kinematics import (
    forward_kinematics,
    inverse_kinematics,
    is_feasible,
    leg_lengths,
    leg_readings,
)
from hexcal.measurement import NoiseModel
from hexcal.presets import PRESETS
from hexcal.simulation import SimulationError


class CommandError(Exception):
    """A failure to report as one line."""


def _geometry(spec: str, euler: str | None = None) -> Geometry:
    geometry = load_geometry(spec)
    return geometry.replace(euler=euler) if euler else geometry


def parse_noise(text: str | None, distribution: str = "uniform") -> NoiseModel:
    """Parse ``leg=0.01,pos=0.025,ang=0.001`` (any subset; others keep the paper's values)."""
    keys = {"leg": "leg", "pos": "position", "ang": "orientation"}
    values: dict[str, float] = {}
    for item in (text or "").split(","):
        item = item.strip()
        if not item:
            continue
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or key not in keys:
            raise CommandError(f"--noise: cannot read {item!r}; write e.g. leg=0.01,pos=0.025,ang=0.001")
        try:
            number = float(value)
        except ValueError:
            raise CommandError(f"--noise: {key}={value!r} is not a number") from None
        if not np.isfinite(number) or number < 0:
            raise CommandError(f"--noise: {key} must be a finite value >= 0, got {value}")
        values[keys[key]] = number
    try:
        return NoiseModel(distribution=distribution, **values)
    except ValueError as exc:
        raise CommandError(f"--noise: {exc}") from None


# -- subcommands ------------------------------------------------------------------


def cmd_preset(args: argparse.Namespace) -> None:
    save_geometry(_geometry(args.name), args.out)
    print(f"wrote preset {args.name} to {args.out}")


def cmd_ik(args: argparse.Namespace) -> None:
    geometry = _geometry(args.geometry, args.euler)
    poses, ids = read_poses(args.poses, geometry.euler)
    lengths = inverse_kinematics(geometry, poses)
    feasible = is_feasible(geometry, poses, margin=1e-6)
    if not feasible.all():
        bad = [ids[k] for k in np.flatnonzero(~feasible)]
        print(
            f"hexcal: warning: {len(bad)} pose(s) outside the leg length limits: "
            f"{', '.join(bad[:20])}{' ...' if len(bad) > 20 else ''}",
            file=sys.stderr,
        )
    write_legs(args.out, lengths, leg_readings(geometry, lengths), ids)
    print(f"wrote leg lengths of {len(ids)} pose(s) to {args.out}")


def cmd_fk(args: argparse.Namespace) -> None:
    geometry = _geometry(args.geometry, args.euler)
    legs = read_legs(args.legs)
    lengths = legs.lengths if legs.lengths is not None else leg_lengths(geometry, legs.readings)
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
            f"(ids {', '.join(bad[:20])}{' ...' if len(bad) > 20 else ''}): leg lengths "
            "out of reach, or start too far (try --guess)"
        )
    write_poses(args.out, result.poses, legs.ids)
    print(
        f"wrote {len(legs.ids)} pose(s) to {args.out} (max leg residual "
        f"{result.residual.max():.1e} mm, at most {result.iterations.max()} iterations)"
    )


class _Progress:
    """Progress lines on stderr, about every 10 % (and at the end)."""

    def __init__(self, label: str, quiet: bool = False) -> None:
        self.label, self.quiet, self.last, self.start = label, quiet, -1, time.perf_counter()

    def __call__(self, done: int, total: int) -> None:
        step = int(10 * done / total)
        if self.quiet or (step == self.last and done < total):
            return
        self.last = step
        elapsed = time.perf_counter() - self.start
        print(f"  {self.label}: {done}/{total} ({elapsed:.1f} s)", file=sys.stderr, flush=True)


def cmd_paper(args: argparse.Namespace) -> None:
    from hexcal.report import format_paper_summary, paper_summary
    from hexcal.simulation import run_paper_experiment

    nominal = _geometry(args.geometry)
    true = None if args.true == "random" else _geometry(args.true)
    if args.trials < 1:
        raise CommandError(f"--trials must be at least 1, got {args.trials}")
    noise = parse_noise(args.noise, args.noise_dist)
    out = Path(args.out) if args.out else None
    if out is not None and out.exists() and not out.is_dir():
        raise CommandError(f"--out {out}: exists and is not a folder")
    print(
        f"Simulating the seed paper's experiment: {args.trials} trials, "
        f"nominal {nominal.name or args.geometry}, "
        f"true machine {true.name if true else 'nominal + U(±5 mm)'}, seed {args.seed}",
        file=sys.stderr,
    )
    start = time.perf_counter()
    experiment = run_paper_experiment(
        nominal,
        true,
        trials=args.trials,
        rng=args.seed,
        noise=noise,
        method=args.method,
        jobs=args.jobs,
        progress=_Progress("identifications", args.quiet),
    )
    summary = paper_summary(
        experiment,
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
    print(format_paper_summary(summary))
    print(f"({elapsed:.1f} s)")
    if out is not None:
        from hexcal.plotting import plot_parameter_errors, plot_validation_errors

        out.mkdir(parents=True, exist_ok=True)
        plot_parameter_errors(experiment, out / "fig10_parameter_errors.png")
        plot_validation_errors(experiment, out / "fig11_validation_errors.png")
        with atomic_write(out / "table1.json") as fh:
            json.dump(summary, fh, indent=2)
            fh.write("\n")
        print(
            f"wrote {out / 'table1.json'} and the figures fig10_parameter_errors.png, "
            "fig11_validation_errors.png"
        )


# -- parser -------------------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hexcal", description="Kinematic calibration of hexapods (Stewart-Gough platforms)."
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    geometry_help = f"geometry YAML file or preset ({', '.join(PRESETS)})"

    p = sub.add_parser("preset", help="write a built-in geometry to a YAML file")
    p.add_argument("name", choices=sorted(PRESETS))
    p.add_argument("--out", required=True, help="YAML file to write")
    p.set_defaults(func=cmd_preset)

    p = sub.add_parser("ik", help="inverse kinematics: leg lengths of poses")
    p.add_argument("--geometry", required=True, help=geometry_help)
    p.add_argument("--poses", required=True, help="pose CSV file")
    p.add_argument("--out", required=True, help="leg CSV file to write (l1..l6, dl1..dl6)")
    p.add_argument("--euler", help="Euler sequence of the angles (default: the geometry's)")
    p.set_defaults(func=cmd_ik)

    p = sub.add_parser("fk", help="forward kinematics: poses of leg lengths or readings")
    p.add_argument("--geometry", required=True, help=geometry_help)
    p.add_argument("--legs", required=True, help="leg CSV file (l1..l6 or dl1..dl6)")
    p.add_argument("--out", required=True, help="pose CSV file to write")
    p.add_argument("--guess", help="pose CSV file of starting poses (default: the home pose)")
    p.add_argument("--euler", help="Euler sequence of the angles (default: the geometry's)")
    p.add_argument("--tol", type=float, default=1e-9, help="leg length tolerance, mm")
    p.set_defaults(func=cmd_fk)

    p = sub.add_parser("paper", help="reproduce the seed paper's Table I by Monte Carlo")
    p.add_argument("--geometry", default="paper-hmt", help=f"nominal {geometry_help}")
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
    p.add_argument("--jobs", type=int, default=1, help="processes for the identifications")
    p.add_argument("--out", help="folder for table1.json and the figures")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=cmd_paper)
    return parser


def _show_warning(message: Any, category: Any, *_args: Any, **_kw: Any) -> None:
    print(f"hexcal: warning: {message}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``hexcal`` command; returns the exit status."""
    args = build_parser().parse_args(argv)
    old = warnings.showwarning
    warnings.showwarning = _show_warning
    try:
        args.func(args)
    except (
        CommandError,
        InputError,
        GeometryError,
        IdentificationError,
        SimulationError,
        ValueError,
        OSError,
    ) as exc:
        print(f"hexcal: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("hexcal: interrupted", file=sys.stderr)
        return 130
    finally:
        warnings.showwarning = old
    return 0


if __name__ == "__main__":
    sys.exit(main())
