"""Calibration subcommands of ``hexcal``: ``identify``, ``validate`` and ``synthesize``.

Imports only the standard library and :mod:`hexcal.cli.common` at its top; each command
imports the library parts it needs when it runs, calls the library and renders the result
through :mod:`hexcal.report`.
"""

from __future__ import annotations

import argparse
from typing import Any

from hexcal.cli.common import (
    EULER_HELP,
    GEOMETRY_HELP,
    CommandError,
    check_outputs,
    fit_mask,
    inputs_record,
    load_geometry,
    noise_from_args,
    noise_options,
    parse_noise,
    show_defaults,
    warn,
)

#: Default ``--sigma-limit``: a parameter combination whose predicted σ exceeds this
#: fraction of the platform radius is poorly determined (``warn``), beyond three times it
#: not determined by the data (``fail``); gains: 1e-3 per mm of the length limit.
SIGMA_LIMIT = 0.2

#: Default ``--max-change``: a change beyond this fraction of the machine's size (base radius
#: for ``u``, platform radius for ``s``, the larger for ``l0``; of 1 for gains) is implausible.
MAX_CHANGE = 0.25


def identify_noise(args: argparse.Namespace) -> Any:
    """``"auto"`` (the noise learned from the data) unless ``--noise``/``--pose-covariance``
    give a noise model."""
    if (args.noise is None and not args.pose_covariance) or (args.noise or "").strip() == "auto":
        if args.pose_covariance:
            raise CommandError("--pose-covariance gives the noise: do not combine it with --noise auto")
        return "auto"
    return noise_from_args(args)


def cmd_identify(args: argparse.Namespace) -> None:
    """Identify the parameters from a measurement file; write the calibrated geometry."""
    if args.setup:  # an instrument setup: cli/instrument.py
        from hexcal.cli.instrument import identify_with_setup

        return identify_with_setup(args)
    import numpy as np

    from hexcal.calibration import estimate
    from hexcal.io import atomic_write, read_measurements, save_geometry
    from hexcal.report import identification_dict, identification_report_dict, render

    check_outputs(args.out, args.report, args.json, args.html)
    if not args.sigma_limit > 0:
        raise CommandError(f"--sigma-limit must be > 0, got {args.sigma_limit}")
    if not args.max_change > 0:
        raise CommandError(f"--max-change must be > 0, got {args.max_change}")
    nominal = load_geometry(args.geometry, args.euler)
    data = read_measurements(args.data, nominal.euler)
    noise = identify_noise(args)
    mask = fit_mask(args.fit, args.fix or (), option=None)
    if args.robust:  # refuse too few poses by the file's count, before any pose is set aside
        from hexcal.estimation import Problem

        Problem(nominal, data, mask=mask).check_size()
    # limits relative to the machine: the library's are 1 mm (1e-3 for gains) per unit of scale
    radius = float(np.max(np.linalg.norm(nominal.platform_joints[:, :2], axis=1)))
    scale = args.sigma_limit * radius
    # the pose check runs on the generalised least-squares fit (its whitened deletion statistic
    # follows a known F distribution); --robust wraps the chosen estimator itself
    result = estimate(
        nominal,
        data,
        args.method,
        mask,
        noise,
        robust=args.robust,
        sigma_limit=scale,
        max_change=args.max_change,
    )
    outliers, flagged = result.outliers, result.flagged
    text = render("identification", identification_report_dict(result, outliers, flagged))
    if result.failed and not args.force:
        print(text)
        reasons = result.verdict.reasons
        serious = [r.message for r in reasons if r.severity == "fail"]
        serious += [r.message for r in reasons if r.severity == "warn"]
        raise CommandError(
            f"verdict fail: {'; '.join(serious)}; nothing written (--force writes the geometry anyway)"
        )
    calibration = result.calibration_metadata()
    calibration["data"] = str(args.data)
    calibration["outliers"] = list(outliers)
    if result.verdict is not None:
        calibration["verdict"] = result.verdict_status
    name = f"{nominal.name}-calibrated" if nominal.name else "calibrated"
    save_geometry(result.geometry.replace(name=name, calibration=calibration), args.out)
    if args.report:
        with atomic_write(args.report) as fh:
            fh.write(text + "\n")
    if args.json:
        with atomic_write(args.json) as fh:
            fh.write(render("identification", identification_dict(result, outliers, flagged), "json"))
    if args.html:
        from hexcal.report import identification_report, render_html

        inputs = inputs_record({"geometry": args.geometry, "data": args.data}, args)
        with atomic_write(args.html) as fh:
            fh.write(render_html(identification_report(result, data, inputs)))
    print(text)
    if result.failed:
        warn(f"hexcal: warning: verdict fail, written anyway (--force) to {args.out}")
    print(f"wrote the calibrated geometry to {args.out}")


def cmd_validate(args: argparse.Namespace) -> None:
    """Pose errors of a geometry (and optionally the nominal one) on held-out measurements."""
    if args.setup:  # an instrument setup: cli/instrument.py
        from hexcal.cli.instrument import validate_with_setup

        return validate_with_setup(args)
    from hexcal.calibration import validate
    from hexcal.io import read_measurements, write_table
    from hexcal.report import render, validation_dict, validation_table

    check_outputs(args.out, args.html)
    geometry = load_geometry(args.geometry, args.euler)
    data = read_measurements(args.data, geometry.euler)
    calibrated = validate(geometry, data)
    nominal = validate(load_geometry(args.nominal, geometry.euler), data) if args.nominal else None
    print(render("validation", validation_dict(calibrated, nominal)))
    if args.out:
        columns, rows, ids, comment = validation_table(calibrated, nominal, data.ids)
        write_table(args.out, columns, rows, ids, comment=comment)
        print(f"wrote the per-pose table to {args.out}")
    if args.html:
        from hexcal.io import atomic_write
        from hexcal.report import render_html, validation_report

        results = {"calibrated": calibrated} | ({"nominal": nominal} if nominal else {})
        files = {"geometry": args.geometry, "data": args.data} | (
            {"nominal": args.nominal} if args.nominal else {}
        )
        with atomic_write(args.html) as fh:
            fh.write(render_html(validation_report(results, inputs_record(files, args))))
        print(f"wrote the HTML report to {args.html}")


def cmd_synthesize(args: argparse.Namespace) -> None:
    """A simulated measurement file of a known machine."""
    if args.setup:  # an instrument setup: cli/instrument.py
        from hexcal.cli.instrument import synthesize_with_setup

        return synthesize_with_setup(args)
    from hexcal.io import read_poses, write_measurements
    from hexcal.simulation import simulate_measurements

    check_outputs(args.out)
    nominal = load_geometry(args.nominal, args.euler)
    true = load_geometry(args.true, nominal.euler)
    poses, ids = read_poses(args.poses, nominal.euler)
    noise = parse_noise(args.noise, args.noise_dist)
    data = simulate_measurements(nominal, true, poses, noise, args.seed, ids)
    write_measurements(
        args.out,
        data,
        nominal.euler,
        args.orientation,
        comment=f"simulated: nominal {args.nominal}, true {args.true}, seed {args.seed}, noise {noise}",
    )
    print(f"wrote {len(data)} simulated measurement(s) to {args.out}")


def register(sub: Any) -> None:
    """Add ``identify``, ``validate`` and ``synthesize`` to the subparsers."""
    p = sub.add_parser("identify", help="identify the kinematic parameters from a measurement file")
    p.add_argument("--geometry", required=True, help=f"nominal {GEOMETRY_HELP}")
    p.add_argument("--data", required=True, help="measurement CSV file (dl1..dl6 and the measured pose)")
    p.add_argument("--out", required=True, help="calibrated geometry YAML file to write")
    from hexcal.estimation.registry import DEFAULT_ESTIMATOR, ESTIMATORS  # names only: no numpy

    p.add_argument(
        "--method",
        choices=tuple(ESTIMATORS),
        default=DEFAULT_ESTIMATOR,
        help="estimator: maximum likelihood (default), generalised least squares, least squares "
        "on leg lengths, or the seed paper's squared lengths (eq. 3)",
    )
    noise_options(p)
    for action in p._actions:  # identify's own default: the noise learned from the data
        if action.dest == "noise":
            action.help = (
                "measurement noise: auto (learned from the data: the default when neither --noise nor "
                "--pose-covariance is given) or leg=MM,pos=MM,ang=RAD"
            )
        elif action.dest == "noise_dist":
            action.help += " (default %(default)s)"
    p.add_argument(
        "--fit",
        default="joints,l0",
        help="parameter groups: joints, base, platform, l0, gains (default %(default)s)",
    )
    p.add_argument(
        "--fix", nargs="+", metavar="NAME", help="parameters to hold, e.g. u1.z l0_1 (default: none)"
    )
    p.add_argument(
        "--robust", action="store_true", help="find and leave out outlying poses (default: keep every pose)"
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="write the calibrated geometry even when the verdict is fail (default: a fail writes nothing)",
    )
    p.add_argument(
        "--sigma-limit",
        type=float,
        default=SIGMA_LIMIT,
        metavar="FRACTION",
        help="identifiability limit: a parameter combination whose predicted σ exceeds this fraction of "
        "the platform radius is poorly determined (warn), beyond 3 times it undetermined (fail); gains: "
        "1e-3 per mm of that limit (default %(default)s)",
    )
    p.add_argument(
        "--max-change",
        type=float,
        default=MAX_CHANGE,
        metavar="FRACTION",
        help="a parameter change beyond this fraction of the machine's size (base radius for u, platform "
        "radius for s, the larger for l0, 1 for gains) is implausible: fail (default %(default)s)",
    )
    p.add_argument("--euler", help=EULER_HELP)
    p.add_argument("--report", help="save the report as text (default: not saved)")
    p.add_argument("--json", help="save the result as JSON (default: not saved; keys in the README)")
    p.add_argument(
        "--html", metavar="FILE", help="save a self-contained HTML report (verdict, tables, figures)"
    )
    p.add_argument("--setup", metavar="FILE", help="instrument setup YAML (targets or tool; frame or auto)")
    p.add_argument("--setup-out", metavar="FILE", help="with --setup: calibrated setup YAML to write")
    p.add_argument("--delimiter", choices=(",", ";", "tab"), help="export field separator (default: sniffed)")
    p.add_argument("--decimal", choices=(".", ","), help="export decimal mark (default: detected)")
    p.set_defaults(
        func=cmd_identify,
        inputs=("geometry", "data", "pose_covariance", "setup"),
        outputs=("out", "report", "json", "html", "setup_out"),
        folders=(),
    )

    p = sub.add_parser("validate", help="pose errors of a geometry on held-out measurements")
    p.add_argument("--geometry", required=True, help=f"calibrated {GEOMETRY_HELP}")
    p.add_argument("--data", required=True, help="held-out measurement CSV file")
    p.add_argument("--nominal", help="also validate this geometry, side by side")
    p.add_argument("--out", help="per-pose table CSV file")
    p.add_argument("--html", metavar="FILE", help="save a self-contained HTML report with figures")
    p.add_argument("--euler", help=EULER_HELP)
    p.add_argument("--setup", metavar="FILE", help="calibrated setup YAML: --data is an instrument export")
    p.add_argument("--delimiter", choices=(",", ";", "tab"), help="export field separator (default: sniffed)")
    p.add_argument("--decimal", choices=(".", ","), help="export decimal mark (default: detected)")
    p.set_defaults(
        func=cmd_validate,
        inputs=("geometry", "data", "nominal", "setup"),
        outputs=("out", "html"),
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
    p.add_argument("--setup", metavar="FILE", help="true instrument setup YAML: write an instrument export")
    p.add_argument("--missing-rate", type=float, default=0.0, help="with --setup: share of lost targets")
    p.set_defaults(
        func=cmd_synthesize, inputs=("nominal", "true", "poses", "setup"), outputs=("out",), folders=()
    )
    for name in ("identify", "validate", "synthesize"):
        show_defaults(sub.choices[name])
