"""The ISO options of ``hexcal validate``: ``--iso230-4`` (the circular test of a ball-bar
circle, before and after calibration, with ``--polar`` for its PNG) and ``--iso9283`` (pose
accuracy and repeatability of repeated visits).

With either option the printed report adds the ISO figures, ``--json`` adds them under
``"iso"``, and ``--html`` writes the ISO page (the tests, the validation's summary beside them,
the inputs) instead of the validation page. The library does the work and
decides how each column takes the setup (:func:`hexcal.calibration.iso_validations`,
:func:`hexcal.calibration.circular_tests`, :func:`hexcal.calibration.pose_tests`); definitions
in docs/iso-tests.md. Imports only the standard library and :mod:`hexcal.cli.common` at its top.
"""

from __future__ import annotations

import argparse
from typing import Any

from hexcal.cli.common import CommandError, inputs_record

#: Default ``--visit-tolerance`` (mm): hexcal.calibration.iso_validation.VISIT_TOLERANCE.
VISIT_TOLERANCE = 0.01


def iso_options(p: argparse.ArgumentParser) -> None:
    """Add ``--iso230-4``, ``--iso9283``, ``--visit-tolerance`` and ``--polar`` to ``validate``."""
    p.add_argument(
        "--iso230-4",
        dest="iso230_4",
        action="store_true",
        help="ISO 230-4 circular test of a ball-bar circle (one distance per observation; the bar as "
        "set up): G, F, H before (--nominal) and after calibration; --html writes the ISO page",
    )
    p.add_argument(
        "--iso9283",
        action="store_true",
        help="ISO 9283 pose accuracy AP and repeatability RP of the poses visited more than once "
        "(the instrument gives the pose); --html writes the ISO page",
    )
    p.add_argument(
        "--visit-tolerance",
        type=float,
        default=VISIT_TOLERANCE,
        metavar="MM",
        help="--iso9283: observations whose six leg readings agree within MM are visits of one "
        "commanded pose (default %(default)s, at most 0.1)",
    )
    p.add_argument("--polar", metavar="FILE", help="--iso230-4: save the polar plot as PNG")


def check_iso(args: argparse.Namespace, session: Any) -> None:
    """Refuse, before any work, ISO options that cannot act (in one line)."""
    if args.polar and not args.iso230_4:
        raise CommandError("--polar draws the circular test: give --iso230-4")
    if args.iso230_4 and args.iso9283:
        raise CommandError("--iso230-4 (a ball bar) and --iso9283 (the pose) need different instruments")
    if args.visit_tolerance != VISIT_TOLERANCE and not args.iso9283:
        raise CommandError("--visit-tolerance groups the visits of --iso9283: give --iso9283")
    from hexcal.calibration.iso_poses import check_visit_tolerance

    check_visit_tolerance(args.visit_tolerance)
    if args.iso230_4:
        from hexcal.calibration.iso_validation import check_circle_instrument

        check_circle_instrument(session.instrument)


def iso_validations(args: argparse.Namespace, geometry: Any, session: Any, nominal: Any | None) -> Any:
    """The validations of the ISO test asked for (:func:`hexcal.calibration.iso_validations`),
    None when neither option is given."""
    if not (args.iso230_4 or args.iso9283):
        return None
    from hexcal.calibration import iso_validations as validations

    test = "iso230-4" if args.iso230_4 else "iso9283"
    folds = {} if args.folds is None else {"folds": args.folds}
    return validations(geometry, session, nominal, test=test, seed=args.seed, **folds)


def iso_results(args: argparse.Namespace, session: Any, checked: Any) -> dict[str, Any] | None:
    """The ISO figures of the validations (None when neither option is given), printed; the
    polar plot written with ``--polar``."""
    if checked is None:
        return None
    from hexcal.calibration import circular_tests, pose_tests
    from hexcal.report import iso_dict, iso_text

    results = checked.results
    circles = poses = note = None
    if args.iso230_4:
        circles = circular_tests(session, results)
    else:
        poses = pose_tests(session, results, args.visit_tolerance)
        if poses is None:
            tol = f"{args.visit_tolerance:g}"
            note = f"no commanded pose is visited twice (leg readings within {tol} mm): nothing to report"
    data = iso_dict(
        circles, poses, note=note, tolerance=args.visit_tolerance if args.iso9283 else None,
        instrument=checked.after_result.instrument, names=list(results), after=checked.after,
    )  # fmt: skip
    print(iso_text(data))
    if args.polar:
        from hexcal.report.figures import plot_polar_deviation

        plot_polar_deviation(data["iso230_4"], args.polar, data["labels"])
        print(f"wrote the polar plot to {args.polar}")
    return data


def iso_page(args: argparse.Namespace, data: dict[str, Any], files: dict[str, Any], *results: Any) -> str:
    """The ISO page's HTML, with the summaries of the validations (calibrated, nominal)."""
    from hexcal.report import iso_report, render_html

    names = list(data["labels"])
    ordered = {"calibrated": results[0], "geometry": results[0], "nominal": results[1]}
    validation = {n: {"summary": ordered[n].summary()} for n in names if ordered.get(n) is not None}
    return render_html(iso_report(data, validation, inputs_record(files, args)))
