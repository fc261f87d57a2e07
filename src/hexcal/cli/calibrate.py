"""Calibration subcommands of ``hexcal``: ``identify``, ``validate`` and ``synthesize``.

Every instrument takes the same path: a data file is read with its setup (``--setup``; none
for the full pose in the base frame) into a session, and the library does the rest
(:func:`hexcal.calibrate`, :func:`hexcal.validate`, :func:`hexcal.simulation.simulate_session`).
``--data`` and ``--setup`` may be repeated: pairs in order, one setup for every data file, or
none.

Imports only the standard library and :mod:`hexcal.cli.common` at its top; each command
imports the library parts it needs when it runs, calls the library and renders the result
through :mod:`hexcal.report`.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import Any

from hexcal.cli.common import (
    EULER_HELP,
    GEOMETRY_HELP,
    CommandError,
    check_outputs,
    inputs_record,
    load_geometry,
    show_defaults,
    table_options,
    table_reading,
    warn,
)
from hexcal.cli.noise import noise_from_args, noise_options, parse_noise, refuse_zero_noise


def identify_noise(args: argparse.Namespace, sessions: Sequence[Any] = ()) -> Any:
    """``"auto"`` (the noise learned from the data) unless ``--noise``/``--pose-covariance``
    give a noise model (a pose covariance only for sessions whose instruments measure a pose)."""
    if (args.noise is None and not args.pose_covariance) or (args.noise or "").strip() == "auto":
        if args.pose_covariance:
            raise CommandError("--pose-covariance gives the noise: do not combine it with --noise auto")
        return "auto"
    noise = noise_from_args(args, [s.instrument for s in sessions])
    return refuse_zero_noise(noise, "every weight, bound and verdict")


def read_sessions(args: argparse.Namespace, geometry: Any) -> list[Any]:
    """The sessions of ``--data`` and ``--setup`` (pairs in order, one setup for all, or none),
    read with ``--columns`` (merged with a setup's ``columns``), ``--delimiter``, ``--decimal``."""
    from hexcal.io import read_sessions as read

    return read(args.data, args.setup or [], geometry.euler, **table_reading(args))


def _given(**files: Any) -> dict[str, Any]:
    """The input files given, by label: one path as a string, several as a list; none left out."""
    out: dict[str, Any] = {}
    for label, value in files.items():
        paths = [str(v) for v in ([] if value is None else value if isinstance(value, list) else [value])]
        if paths:
            out[label] = paths[0] if len(paths) == 1 else paths
    return out


def _setup_outputs(args: argparse.Namespace) -> list[str]:
    """The calibrated setups ``--setup-out`` names: a file for one data file, else one file per
    session in the folder ``--setup-out`` (declared now, before any work; with ``--split`` the
    sessions are known only after it, so ``--setup-out`` is a folder whose files are declared
    then: :func:`_split_setup_paths`)."""
    from pathlib import Path

    from hexcal.io import active_outputs

    if not args.setup_out:
        return []
    outputs = active_outputs()
    if len(args.data) == 1 and not args.split:
        paths = [args.setup_out]
    else:
        folder = Path(args.setup_out)
        if folder.exists() and not folder.is_dir():
            raise CommandError(
                f"--setup-out {folder}: with {'--split' if args.split else f'{len(args.data)} data files'} "
                "this is a folder"
            )
        if outputs is not None:
            outputs.folder(folder)
        if args.split:
            return [str(folder)]
        paths = [str(folder / f"{Path(d).stem}-setup.yaml") for d in args.data]
        if len(set(paths)) < len(paths):
            raise CommandError("--setup-out: two data files have the same name; give them distinct names")
    for path in paths:
        if outputs is not None:
            outputs.add(path)
    return paths


def _split_setup_paths(folder: str, labels: Sequence[str]) -> list[str]:
    """One calibrated setup file per session of a split calibration, in ``folder``, named by
    the session's label (``run.csv#2`` -> ``run-2-setup.yaml``), declared in the output set."""
    import re
    from pathlib import Path

    from hexcal.io import active_outputs

    outputs = active_outputs()
    paths = []
    for label in labels:
        stem, _, part = label.partition("#")
        name = re.sub(r"[^A-Za-z0-9._-]+", "_", Path(stem).stem + (f"-{part}" if part else ""))
        paths.append(str(Path(folder) / f"{name}-setup.yaml"))
        if outputs is not None:
            outputs.add(paths[-1])
    return paths


def cmd_identify(args: argparse.Namespace) -> None:
    """Identify the machine from measurement sessions; write the calibrated geometry."""
    import numpy as np

    from hexcal.io import active_outputs, atomic_write
    from hexcal.workflow import calibrate

    check_outputs(args.out, args.report, args.json, args.html)
    setup_paths = _setup_outputs(args)
    nominal = load_geometry(args.geometry, args.euler)
    sessions = read_sessions(args, nominal)
    if setup_paths and not any(np.any(s.instrument.parameters().vary) for s in sessions):
        raise CommandError("--setup-out: the data have no setup (give --setup) to calibrate")
    files = {"geometry": args.geometry} | {f"data {k + 1}": d for k, d in enumerate(args.data)}
    files |= {f"setup {k + 1}": s for k, s in enumerate(args.setup or [])}
    calibration = calibrate(
        nominal,
        sessions,
        method=args.method,
        noise=identify_noise(args, sessions),
        fit=args.fit,
        fix=args.fix or (),
        leg_model=args.leg_model,
        robust=args.robust,
        split=_split_option(args.split),
        sigma_limit=args.sigma_limit,
        max_change=args.max_change,
        inputs=_given(data=args.data, setup=args.setup) | inputs_record(files, args),
    )
    text = calibration.report()
    if calibration.failed and not args.force:
        print(text)
        outputs = active_outputs()
        if outputs is not None:  # the report is shown though nothing is written
            outputs.show_text()
        raise CommandError(
            f"verdict fail: {calibration.failure()}; nothing written (--force writes the geometry anyway)"
        )
    calibration.save(args.out, force=args.force)
    if args.split and setup_paths:
        setup_paths = _split_setup_paths(setup_paths[0], [s.label for s in calibration.sessions])
    calibration.save_setups(setup_paths, force=args.force)
    written = [("the report", args.report, text + "\n"), ("the JSON result", args.json, None)]
    written.append(("the HTML report", args.html, None))
    for _, path, body in written:
        if not path:
            continue
        if body is None:
            body = calibration.report("json") if path == args.json else calibration.html()
        with atomic_write(path) as fh:
            fh.write(body)
    print(text)
    if calibration.failed:
        warn(f"hexcal: warning: verdict fail, written anyway (--force) to {args.out}")
    print(f"wrote the calibrated geometry to {args.out}")
    for path in setup_paths:
        print(f"wrote the calibrated setup to {path}")
    for what, path, _ in written:
        if path:
            print(f"wrote {what} to {path}")
    unsaved = [s.label for s in calibration.sessions if s.instrument.unregistered]
    if unsaved and not setup_paths:
        warn(
            "hexcal: warning: the registered frame is not saved: give --setup-out FILE to validate later"
            + (f" ({', '.join(unsaved)})" if len(calibration.sessions) > 1 else "")
        )


def _split_option(values: list[str] | None) -> Any:
    """``--split`` as the library takes it: ``auto``, or the ``LABEL:ID`` splits."""
    if not values:
        return None
    if "auto" in values:
        if len(values) > 1:
            raise CommandError("--split auto splits where the verdict finds steps: give it alone")
        return "auto"
    return values


def cmd_validate(args: argparse.Namespace) -> None:
    """Prediction errors of a calibration (and optionally the nominal geometry) on held-out data;
    the library's warnings (legs beyond a stroke model's calibrated stroke) printed."""
    from hexcal.io import atomic_write
    from hexcal.workflow import validate
    from hexcal.workflow.validation import check_options

    check_outputs(args.out, args.html, args.json, args.polar)
    options = {"iso230_4": args.iso230_4, "iso9283": args.iso9283, "visit_tolerance": args.visit_tolerance}
    check_options(**options, folds=args.folds, polar=bool(args.polar))
    geometry = load_geometry(args.geometry, args.euler)
    sessions = read_sessions(args, geometry)
    nominal = load_geometry(args.nominal, geometry.euler) if args.nominal else None
    files = {"geometry": args.geometry, "nominal": args.nominal}
    files |= _numbered("data", args.data) | _numbered("setup", args.setup)
    validation = validate(
        geometry, sessions, nominal=nominal, folds=args.folds, seed=args.seed,
        inputs=inputs_record(files, args), **options,
    )  # fmt: skip
    print(validation.report())
    for line in validation.warnings:
        warn(f"hexcal: warning: {line}")
    if args.polar:
        validation.save_polar(args.polar)
        print(f"wrote the polar plot to {args.polar}")
    if args.out:
        validation.save_table(args.out)
        print(f"wrote the per-pose table to {args.out}")
    if args.json:
        with atomic_write(args.json) as fh:
            fh.write(validation.report("json"))
        print(f"wrote the JSON summary to {args.json}")
    if args.html:
        with atomic_write(args.html) as fh:
            fh.write(validation.html())
        print(f"wrote the HTML report to {args.html}")


def _numbered(label: str, paths: list[str] | None) -> dict[str, str]:
    """Input files by role: ``data`` for one file, ``data 1``, ``data 2``, ... for several."""
    paths = paths or []
    if len(paths) == 1:
        return {label: paths[0]}
    return {f"{label} {k + 1}": path for k, path in enumerate(paths)}


def cmd_synthesize(args: argparse.Namespace) -> None:
    """A simulated data file of a known machine (and instrument setup)."""
    from hexcal.io import load_instrument, read_poses, write_session_data
    from hexcal.simulation import simulate_session

    check_outputs(args.out)
    nominal = load_geometry(args.nominal, args.euler)
    true = load_geometry(args.true, nominal.euler)
    instrument = load_instrument(args.setup, nominal.euler)
    if instrument.unregistered:
        raise CommandError(f"{args.setup}: simulation needs the true instrument frame, not auto")
    poses, ids, covariates = read_poses(args.poses, nominal.euler, **table_reading(args), covariates=True)
    noise = parse_noise(args.noise, args.noise_dist)
    options = {"missing_rate": args.missing_rate} if args.missing_rate else {}
    session = simulate_session(
        nominal, true, instrument, poses, noise, args.seed, tuple(ids), covariates, **options
    )
    comment = f"simulated: nominal {args.nominal}, true {args.true}, seed {args.seed}, noise {noise}"
    comment += "".join(f", {label} {value}" for label, value in _given(setup=args.setup).items())
    comment += f", missing rate {args.missing_rate:g}" if args.missing_rate else ""
    write_session_data(args.out, session, nominal.euler, args.orientation, comment)
    print(f"wrote {len(session)} simulated observation(s) of {instrument.describe()} to {args.out}")


def register(sub: Any) -> None:
    """Add ``identify``, ``validate`` and ``synthesize`` to the subparsers."""
    p = sub.add_parser("identify", help="identify the kinematic parameters from measurement sessions")
    p.add_argument("--geometry", required=True, help=f"nominal {GEOMETRY_HELP}")
    p.add_argument(
        "--data",
        required=True,
        action="append",
        help="measurement CSV file (dl1..dl6 and what the instrument measured); repeat for several sessions",
    )
    p.add_argument("--out", required=True, help="calibrated geometry YAML file to write")
    from hexcal.estimation.registry import DEFAULT_ESTIMATOR, ESTIMATORS  # names only: no numpy

    p.add_argument(
        "--method",
        choices=tuple(ESTIMATORS),
        default=DEFAULT_ESTIMATOR,
        help="estimator: maximum likelihood (default), generalised least squares, least squares "
        "on leg lengths, or the seed paper's squared lengths (eq. 3); the last three need the "
        "platform pose measured (no free instrument frame or tool)",
    )
    noise_options(p)
    for action in p._actions:  # identify's own default: the noise learned from the data
        if action.dest == "noise":
            action.help = (
                "measurement noise: auto (learned from the data, per session and group: the default when "
                "neither --noise nor --pose-covariance is given) or leg=MM,pos=MM,ang=RAD"
            )
        elif action.dest == "noise_dist":
            action.help += " (default %(default)s)"
    p.add_argument(
        "--fit",
        help="machine parameter groups: joints, base, platform, l0, gains (default joints,l0); the "
        "instrument quantities a setup does not fix vary too",
    )
    p.add_argument(
        "--fix",
        nargs="+",
        metavar="NAME",
        help="parameters or groups to hold, e.g. u1.z l0_1 frame (default: none)",
    )
    p.add_argument(
        "--leg-model",
        metavar="NAME[:DEGREE]",
        help="how readings become leg lengths: linear (l0 + g dl), stroke[:DEGREE] (plus a Legendre "
        "curve of each leg's reading over its stroke, degree 2-8, default 3; its terms fitted), or auto "
        "(chosen by cross-validation; default: the geometry's own model)",
    )
    p.add_argument(
        "--robust", action="store_true", help="find and leave out outliers (default: keep every observation)"
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="write the calibrated geometry even when the verdict is fail (default: a fail writes nothing)",
    )
    from hexcal.calibration.limits import MAX_CHANGE, SIGMA_LIMIT  # constants only: no numpy

    p.add_argument(
        "--sigma-limit",
        type=float,
        metavar="FRACTION",
        help="identifiability limit: a parameter combination whose predicted σ exceeds this fraction of "
        "the platform radius is poorly determined (warn), beyond 3 times it undetermined (fail); gains: "
        f"1e-3 (relative) per mm of that limit (default {SIGMA_LIMIT})",
    )
    p.add_argument(
        "--max-change",
        type=float,
        metavar="FRACTION",
        help="a parameter change beyond this fraction of the machine's size (base radius for u, platform "
        f"radius for s, the larger for l0, the gain for gains) is implausible: fail (default {MAX_CHANGE})",
    )
    p.add_argument(
        "--split",
        action="append",
        metavar="LABEL:ID",
        help="split a session before pose ID (its instrument moved there: each part gets its own frame); "
        "repeat for several, or auto: where the verdict finds a step (default: no split)",
    )
    p.add_argument("--euler", help=EULER_HELP)
    p.add_argument("--report", help="save the report as text (default: not saved)")
    p.add_argument("--json", help="save the result as JSON (default: not saved; keys in the README)")
    p.add_argument(
        "--html", metavar="FILE", help="save a self-contained HTML report (verdict, tables, figures)"
    )
    p.add_argument(
        "--setup",
        metavar="FILE",
        action="append",
        help="instrument setup YAML (targets or tool; frame or auto): once for every --data, or once "
        "per --data",
    )
    p.add_argument(
        "--setup-out",
        metavar="PATH",
        help="calibrated setup YAML to write (one --data), or a folder for one per session (several)",
    )
    table_options(p, "--data", "; merged with a setup's columns, this option winning")
    p.set_defaults(
        func=cmd_identify,
        inputs=("geometry", "data", "pose_covariance", "setup"),
        outputs=("out", "report", "json", "html"),
        folders=(),
    )

    p = sub.add_parser("validate", help="prediction errors of a calibration on held-out measurements")
    p.add_argument("--geometry", required=True, help=f"calibrated {GEOMETRY_HELP}")
    p.add_argument("--data", required=True, action="append", help="held-out measurement CSV file")
    p.add_argument(
        "--nominal",
        help="also validate this geometry, side by side (a free frame or tool re-registered for it too)",
    )
    p.add_argument("--out", help="per-pose table CSV file")
    p.add_argument(
        "--json",
        metavar="FILE",
        help="save the summary as JSON (position_rms_mm, orientation_rms_rad, leg_rms_mm, maxima, the "
        "registration, what the calibration expected)",
    )
    from hexcal.calibration.limits import VALIDATION_FOLDS  # constants only: no numpy

    p.add_argument(
        "--folds",
        type=int,
        default=None,
        help=f"folds of the cross-validated re-registration of a free frame or tool (default "
        f"{VALIDATION_FOLDS}; refused when nothing is re-registered)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the poses' folds (default 0)")
    p.add_argument("--html", metavar="FILE", help="save a self-contained HTML report with figures")
    p.add_argument("--euler", help=EULER_HELP)
    p.add_argument(
        "--setup",
        metavar="FILE",
        action="append",
        help="calibrated setup YAML: --data is an instrument export",
    )
    table_options(p, "--data", "; merged with a setup's columns, this option winning")
    from hexcal.cli.iso import iso_options

    iso_options(p)
    p.set_defaults(
        func=cmd_validate,
        inputs=("geometry", "data", "nominal", "setup"),
        outputs=("out", "html", "json", "polar"),
        folders=(),
    )

    p = sub.add_parser("synthesize", help="simulate a measurement file of a known machine (for rehearsal)")
    p.add_argument("--nominal", required=True, help=f"the controller's {GEOMETRY_HELP}")
    p.add_argument("--true", required=True, help=f"the simulated real machine: {GEOMETRY_HELP}")
    p.add_argument("--poses", required=True, help="commanded pose CSV file")
    p.add_argument("--out", required=True, help="measurement CSV file to write")
    p.add_argument("--noise", help="noise half-widths, e.g. leg=0.01,pos=0.025,ang=0.001 (the paper's)")
    p.add_argument("--noise-dist", choices=("uniform", "normal"), default="uniform")
    p.add_argument("--orientation", choices=("rad", "deg", "quat"), default="rad")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--euler", help="Euler sequence of the angles (default: the nominal geometry's)")
    p.add_argument("--setup", metavar="FILE", help="true instrument setup YAML: write what it records")
    p.add_argument("--missing-rate", type=float, default=0.0, help="with --setup: share of lost targets")
    table_options(p, "--poses")
    p.set_defaults(
        func=cmd_synthesize, inputs=("nominal", "true", "poses", "setup"), outputs=("out",), folders=()
    )
    for name in ("identify", "validate", "synthesize"):
        show_defaults(sub.choices[name])
