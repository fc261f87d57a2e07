"""The ISO options of ``hexcal validate``: ``--iso230-4`` (the circular test of a ball-bar
circle, before and after calibration, with ``--polar`` for its PNG) and ``--iso9283`` (pose
accuracy and repeatability of repeated visits).

With either option the printed report adds the ISO figures, ``--json`` adds them under
``"iso"``, and ``--html`` writes the ISO page (the tests, the validation's summary beside them,
the inputs) instead of the validation page. The library does the work, refuses options that
cannot act together and decides how each column takes the setup (:func:`hexcal.validate`,
:func:`hexcal.workflow.validation.check_options`); definitions in docs/iso-tests.md. Imports
only the standard library at its top (the defaults, when the parser is built, from
:mod:`hexcal.calibration.limits`).
"""

from __future__ import annotations

import argparse


def iso_options(p: argparse.ArgumentParser) -> None:
    """Add ``--iso230-4``, ``--iso9283``, ``--visit-tolerance`` and ``--polar`` to ``validate``."""
    from hexcal.calibration.limits import VISIT_TOLERANCE, VISIT_TOLERANCE_LIMIT  # constants only: no numpy

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
        metavar="MM",
        help="--iso9283: observations whose six leg readings agree within MM are visits of one "
        f"commanded pose (default {VISIT_TOLERANCE:g}, at most {VISIT_TOLERANCE_LIMIT:g})",
    )
    p.add_argument("--polar", metavar="FILE", help="--iso230-4: save the polar plot as PNG")
