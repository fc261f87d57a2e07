"""The ``hexcal`` command: the parser assembled from each command group's ``register``, and
:func:`main`, which runs a subcommand and turns every known failure into one line.

Every known failure (bad file, bad option, unreachable pose, no convergence) ends with one
line ``hexcal: error: ...`` on stderr and exit status 1, and no output file; an interrupt
ends with ``hexcal: interrupted`` and status 130; warnings print as
``hexcal: warning: ...``. Imports only the standard library, :mod:`hexcal.errors` and the
command modules, whose tops are as light: ``hexcal --help`` imports no numpy.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import warnings
from collections.abc import Sequence
from typing import Any

from hexcal.cli import calibrate, kinematics, linuxcnc, plan, simulate, study
from hexcal.errors import HexcalError


def build_parser() -> argparse.ArgumentParser:
    """The ``hexcal`` parser with every subcommand, in the order of ``hexcal --help``."""
    parser = argparse.ArgumentParser(
        prog="hexcal", description="Kinematic calibration of hexapods (Stewart-Gough platforms)."
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for group in (kinematics, calibrate, plan, simulate, study, linuxcnc):
        group.register(sub)
    return parser


def _show_warning(message: Any, category: Any, *_args: Any, **_kw: Any) -> None:
    print(f"hexcal: warning: {message}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``hexcal`` command; returns the exit status.

    >>> main(["ik", "--geometry", "paper-hmt", "--poses", "missing.csv", "--out", "legs.csv"])
    1
    """
    args = build_parser().parse_args(argv)
    old = warnings.showwarning
    warnings.showwarning = _show_warning
    try:
        args.func(args)
    except BrokenPipeError:  # output piped into `head`: not an error of hexcal's
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    # ValueError: the library's remaining plain ValueErrors (e.g. numpy's) until every
    # layer raises HexcalError; OSError: files (the message names the file) until io
    # converts them
    except (HexcalError, ValueError, OSError) as exc:
        print(f"hexcal: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("hexcal: interrupted", file=sys.stderr)
        return 130
    finally:
        warnings.showwarning = old
    return 0
