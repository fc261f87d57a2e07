"""The ``hexcal`` command: the parser assembled from each command group's ``register``, and
:func:`main`, which runs a subcommand safely and turns every known failure into one line.

Every failure ends with one line ``hexcal: error: ...`` on stderr and no output file: exit
status 2 for a usage error (a malformed command line), 1 for every other error; a signal
ends it with one line and 128 + the signal's number: SIGINT ``hexcal: interrupted`` (130),
SIGTERM ``hexcal: terminated`` (143), SIGHUP (a closed terminal) ``hexcal: hung up`` (129);
warnings print as ``hexcal: warning: ...``. The outputs a command declares are checked
before it runs and committed together with its standard output after it succeeds
(:mod:`hexcal.cli.safety`). Imports only the standard library, :mod:`hexcal.errors` and
the command modules, whose tops are as light: ``hexcal --help`` imports no numpy.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import warnings
from collections.abc import Sequence
from typing import Any, NoReturn

from hexcal.cli import calibrate, compensation, kinematics, linuxcnc, plan, safety, simulate, study
from hexcal.errors import HexcalError

#: Commands that read a whole table take ``--max-rows`` (default limits in the help).
MAX_ROWS_COMMANDS = ("identify", "ik", "fk", "validate", "compensate")

EPILOG = (
    "Exit status: 0 success; 1 error (one line 'hexcal: error: ...', no output written); "
    f"{safety.USAGE_STATUS} usage error (a malformed command line); 128 + the signal's number after "
    "a signal: 130 interrupted (SIGINT), 143 terminated (SIGTERM), 129 hung up (SIGHUP, a closed "
    "terminal)."
)


class Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line ``hexcal: error: ...``."""

    def error(self, message: str) -> NoReturn:
        print(
            f"hexcal: error: {self.prog.removeprefix('hexcal ')}: {message}"
            if self.prog != "hexcal"
            else f"hexcal: error: {message}",
            file=sys.stderr,
        )
        sys.exit(safety.USAGE_STATUS)


def package_version() -> str:
    """hexcal's version, from the installed package's metadata (pyproject.toml's ``version``)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("hexcal")
    except PackageNotFoundError:  # a source tree that was never installed
        return "0+unknown"


def build_parser() -> argparse.ArgumentParser:
    """The ``hexcal`` parser with every subcommand, in the order of ``hexcal --help``."""
    parser = Parser(
        prog="hexcal",
        description="Kinematic calibration of hexapods (Stewart-Gough platforms).",
        epilog=EPILOG,
    )
    parser.add_argument(
        "--version", action="version", version=f"hexcal {package_version()}", help="print hexcal's version"
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=Parser)
    for group in (kinematics, calibrate, compensation, plan, simulate, study, linuxcnc):
        group.register(sub)
    for name in MAX_ROWS_COMMANDS:
        sub.choices[name].add_argument(
            "--max-rows",
            type=int,
            default=None,
            help="rows a table read whole may have (default 1,000,000; 100,000 for measurement files)",
        )
        sub.choices[name].epilog = EPILOG
    return parser


def _show_warning(message: Any, category: Any, *_args: Any, **_kw: Any) -> None:
    print(f"hexcal: warning: {message}", file=sys.stderr)


def _run(args: argparse.Namespace) -> None:
    """Check the options, then run the command inside its output set (all or nothing)."""
    safety.check_options(args)
    token = None
    if getattr(args, "max_rows", None) is not None:
        from hexcal.io.inputs import ROW_LIMIT

        token = ROW_LIMIT.set(args.max_rows)
    try:
        with safety.command_outputs(args), safety.progress_lines(args):
            args.func(args)
    finally:
        if token is not None:
            ROW_LIMIT.reset(token)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``hexcal`` command; returns the exit status.

    >>> main(["ik", "--geometry", "paper-hmt", "--poses", "missing.csv", "--out", "legs.csv"])
    1
    """
    old_signals: dict[int, Any] = {}
    console = argv is None
    old = warnings.showwarning
    try:  # a signal from here on ends in one line (the handlers are installed inside the try)
        safety.install_signals(old_signals)
        warnings.showwarning = _show_warning
        # floating-point warnings of numpy ("overflow encountered in ..."): the results are
        # checked for finite values where they matter; the warning would only confuse
        if not any(f[0] == "ignore" and f[2] is RuntimeWarning for f in warnings.filters):
            # (added once: changing the filters would show every warning again)
            warnings.filterwarnings("ignore", message=r".*encountered in", category=RuntimeWarning)
        args = build_parser().parse_args(argv)
        _run(args)
    except BrokenPipeError:  # output piped into `head`: not an error of hexcal's
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except KeyboardInterrupt as exc:  # SIGINT, or SIGTERM and SIGHUP (Terminated)
        status, line = safety.signal_exit(exc)
        with contextlib.suppress(Exception):
            print(line, file=sys.stderr, flush=True)
        if console:  # skip the interpreter's exit (pool threads): the clean-up is done
            with contextlib.suppress(Exception):
                sys.stdout.flush()
            os._exit(status)
        return status
    # ValueError: the library's remaining plain ValueErrors (numpy's LinAlgError is one);
    # OSError: files; MemoryError: a size the limits did not foresee
    except (HexcalError, ValueError, OSError, MemoryError, RecursionError) as exc:
        print(safety.error_line(exc), file=sys.stderr)
        return 1
    finally:
        warnings.showwarning = old
        safety.restore_signals(old_signals)
    return 0
