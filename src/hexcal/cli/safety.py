"""What every command gets from :func:`hexcal.cli.main.main`, without a line of its own.

- **Signals**: SIGINT raises :class:`KeyboardInterrupt`, SIGTERM and SIGHUP (a closed
  terminal or SSH session) :class:`Terminated` (a subclass, so that every ``except
  KeyboardInterrupt`` cleans up for all three: the simulation runner terminates its workers,
  the output set removes its staged files); a second signal during the clean-up is ignored.
  The exit status is 128 + the signal's number (:data:`SIGNALS`). A SIGHUP ignored when
  hexcal starts (``nohup``) stays ignored; a forked child (a pool worker) that inherits the
  handlers ends at once on a signal, as by default.
- **Options**: counts positive, ``--jobs`` not negative (0 = all cores), tolerances finite and
  positive, ``--max-rows`` positive, and sizes within the library's memory budget before anything
  is allocated (:func:`check_options`).
- **Outputs**: a command declares ``inputs``, ``outputs`` and ``folders`` (names of its
  options), the files named inside option values (``input_lists``) and the files it writes
  into its folders (``folder_files``) with ``set_defaults`` in its ``register``
  (:func:`declared_files`); :func:`command_outputs` builds one
  :class:`hexcal.io.OutputSet` of them, checked before the work, active while the command
  runs (every writer stages into it), with the command's standard output captured and
  committed with the files: all or nothing.
- **Messages**: :func:`error_line` turns an exception into one line (no temporary names,
  linear-algebra failures named as such).

Standard library only at the top (``hexcal --help`` loads no numpy).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import os
import re
import signal
import sys
from collections.abc import Iterator
from typing import Any

from hexcal.cli.common import CommandError

#: Options that count things: each must be at least 1.
COUNT_OPTIONS = ("trials", "n", "draws", "levels", "grid", "points", "max_rows")

#: Bytes per candidate pose: ``candidates`` (poses, feasibility, distances) and ``select``
#: (a 6 x 42 Jacobian block per candidate, plus the poses).
CANDIDATE_BYTES = {"candidates": 200, "select": 2400}

#: Commands whose reports carry a Cramér-Rao bound (0 when the noise is 0: said so).
BOUND_COMMANDS = ("simulate", "paper")  # identify, observability, select refuse a zero noise

#: Bytes kept per simulated trial and campaign kind (parameter errors, bounds and pose errors
#: of each method: a few hundred numbers).
TRIAL_BYTES = 2048

#: Campaign kinds per cell of a Monte Carlo command that no option counts: ``study
#: selection`` runs three pose strategies (interior, corners, selected) per pose count.
TRIAL_KINDS = {"study": 3}

#: Comma-separated list options of each command, each value given once (a repeated value
#: would only repeat rows of the results).
LIST_OPTIONS = {"simulate": ("poses", "methods", "strategies", "noise_levels"), "study": ("poses",)}

#: Fewest poses of a simulated campaign: 42 kinematic parameters, 6 leg equations per pose.
SIMULATE_MIN_POSES = 7

#: The loosest ``fk --tol`` (mm): a pose solving the legs to worse than a micrometre is not
#: a solution.
FK_MAX_TOL = 1e-3

#: Exit status of a usage error (a malformed command line: unknown option, missing value,
#: a value of the wrong type); every other error exits 1, a signal 128 + its number
#: (:data:`SIGNALS`).
USAGE_STATUS = 2

#: The signals that end a command, and the word of the line each ends it with; the exit
#: status is 128 + the signal's number: 130 (SIGINT), 143 (SIGTERM), 129 (SIGHUP).
SIGNALS = {signal.SIGINT: "interrupted", signal.SIGTERM: "terminated", signal.SIGHUP: "hung up"}

#: The process that installed the handlers (a forked child inherits them, not this).
_owner = {"pid": 0}


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised in the main thread (a KeyboardInterrupt, so clean-ups run
    for all); ``signum`` is the signal's number."""

    def __init__(self, signum: int = signal.SIGTERM) -> None:
        super().__init__(signum)
        self.signum = signum


def _raise_signal(signum: int, _frame: Any) -> None:
    if os.getpid() != _owner["pid"]:  # a forked child (a pool worker): end as by default
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)
        return
    for sig in SIGNALS:  # the clean-up is not interrupted again
        signal.signal(sig, signal.SIG_IGN)
    if signum == signal.SIGINT:
        raise KeyboardInterrupt()
    raise Terminated(signum)


def install_signals(old: dict[int, Any] | None = None) -> dict[int, Any]:
    """SIGINT, SIGTERM and SIGHUP raise in the main thread; returns (and fills ``old`` with)
    the handlers replaced. An ignored SIGHUP (``nohup``) stays ignored."""
    old = {} if old is None else old
    _owner["pid"] = os.getpid()
    for sig in SIGNALS:
        with contextlib.suppress(ValueError):  # not the main thread: leave them
            if sig == signal.SIGHUP and signal.getsignal(sig) == signal.SIG_IGN:
                continue
            old[sig] = signal.signal(sig, _raise_signal)
    return old


def restore_signals(old: dict[int, Any]) -> None:
    """Put back the handlers :func:`install_signals` replaced."""
    for sig, handler in old.items():
        with contextlib.suppress(ValueError, TypeError):
            signal.signal(sig, handler)


def signal_exit(exc: BaseException) -> tuple[int, str]:
    """The exit status and the line of an interrupt: 128 + the signal's number.

    >>> signal_exit(Terminated(signal.SIGHUP))
    (129, 'hexcal: hung up')
    """
    signum = exc.signum if isinstance(exc, Terminated) else signal.SIGINT
    return 128 + signum, f"hexcal: {SIGNALS.get(signum, 'terminated')}"


# -- options ---------------------------------------------------------------------------------
def _option(dest: str) -> str:
    return "--" + dest.replace("_", "-")


def _candidate_count(spec: str) -> int:
    """An upper bound of the poses of a ``--candidates`` spec (files count as 0 here)."""
    total = 0
    for token in (t.strip() for t in spec.split("+")):
        kind, _, arg = token.partition(":")
        if not arg.isdigit():
            total += 64 if kind in ("corners", "grid", "edges") else 0
        elif kind == "random":
            total += int(arg)
        elif kind in ("grid", "edges"):
            total += int(arg) ** 6
    return total


def _budget(option: str, size: int, what: str) -> None:
    """The library's one budget (:data:`hexcal.core.resources.MEMORY_BUDGET`), checked from the
    options before anything is read: ``errormap --grid/--levels/--points/--draws``,
    ``candidates``/``select --candidates``, ``--trials``; the library checks the sizes that
    only it can count (ballbar pivots and circles) itself, before allocating."""
    from hexcal.core.resources import check_memory  # standard library only: no numpy

    check_memory(option, size, what)


def _same_value(text: str) -> Any:
    """The value a list item stands for (``8`` and ``08`` are one pose count)."""
    try:
        return float(text)
    except ValueError:
        return text


def _check_lists(values: dict[str, Any]) -> None:
    """Refuse a value given twice in a comma-separated list option (``--poses 8,8``)."""
    for dest in LIST_OPTIONS.get(values.get("command") or "", ()):
        text = values.get(dest)
        if not isinstance(text, str):
            continue
        seen: dict[Any, str] = {}
        for item in (t.strip() for t in text.split(",") if t.strip()):
            key = _same_value(item)
            if key in seen:
                same = "" if seen[key] == item else f" (as {seen[key]})"
                raise CommandError(f"{_option(dest)}: {item} is given twice{same}; give each value once")
            seen[key] = item


def _check_needs(values: dict[str, Any]) -> None:
    """Refuse an option that cannot act without another (``set_defaults(needs={dest: other})``
    in a command's ``register``: ``candidates --points`` draws the circles of ``--ballbar``).
    Such options default to None, the library deciding their defaults; ``needs`` is consumed."""
    for dest, other in (values.pop("needs", None) or {}).items():
        if values.get(dest) is not None and not values.get(other):
            raise CommandError(
                f"{_option(dest)} acts only with {_option(other)}; give {_option(other)}, or leave "
                f"{_option(dest)} out"
            )


def check_options(args: argparse.Namespace) -> None:
    """Refuse nonsense values of the common options, options that cannot act, and sizes over
    the memory budget."""
    values = vars(args)
    _check_needs(values)
    for dest in COUNT_OPTIONS:
        value = values.get(dest)
        if isinstance(value, int) and value < 1:
            raise CommandError(f"{_option(dest)}: must be at least 1, got {value}")
    jobs = values.get("jobs")
    if isinstance(jobs, int) and jobs < 0:
        raise CommandError(f"--jobs: must be at least 1 (or 0 for all cores), got {jobs}")
    for dest in ("tol", "amplitude", "min_distance"):
        value = values.get(dest)
        if isinstance(value, float) and not (math.isfinite(value) and value > 0):
            raise CommandError(f"{_option(dest)}: must be a finite positive number, got {value:g}")
    seed = values.get("seed")
    if isinstance(seed, int) and seed < 0:
        raise CommandError(f"--seed: must be a non-negative integer, got {seed}")
    noise = values.get("noise")
    if isinstance(noise, str) and "=" in noise and values.get("command") in BOUND_COMMANDS:
        numbers = [v.partition("=")[2].strip() for v in noise.split(",")]
        with contextlib.suppress(ValueError):
            if all(float(v) == 0 for v in numbers):
                print(
                    "hexcal: warning: --noise is zero: every predicted bound and standard deviation "
                    "below is 0 by construction, not a measured accuracy",
                    file=sys.stderr,
                )
    tol = values.get("tol")
    if values.get("command") == "fk" and isinstance(tol, float) and tol > FK_MAX_TOL:
        raise CommandError(
            f"--tol: at most {FK_MAX_TOL:g} mm, got {tol:g} (a looser tolerance accepts poses "
            "that do not match the legs)"
        )
    poses = values.get("poses")
    if values.get("command") == "simulate" and isinstance(poses, str):
        counts = [int(t) for t in poses.replace(" ", "").split(",") if t.lstrip("-").isdigit()]
        if counts and min(counts) < SIMULATE_MIN_POSES:
            raise CommandError(
                f"--poses: at least {SIMULATE_MIN_POSES} poses per campaign (42 parameters, 6 "
                f"equations per pose), got {min(counts)}"
            )
    missing = values.get("missing_rate")
    if isinstance(missing, float) and not 0 <= missing < 1:
        raise CommandError(f"--missing-rate: must be in [0, 1), got {missing:g}")
    if values.get("command") == "errormap":
        draws = values.get("draws") or 1
        points = max(
            (values.get("levels") or 1) * (values.get("points") or 1), (values.get("grid") or 1) ** 2
        )
        option = "--grid" if (values.get("grid") or 1) ** 2 >= points else "--levels/--points"
        option = "--draws" if draws >= points else option  # the larger factor is the one to lower
        _budget(f"{option} (with the others)", 48 * 4 * draws * points, "the error maps")
    _check_lists(values)
    trials = values.get("trials")
    if isinstance(trials, int):  # every Monte Carlo command: paper, simulate, study
        command = values.get("command") or ""
        cells = TRIAL_KINDS.get(command, 1)
        for dest in LIST_OPTIONS.get(command, ("methods", "strategies", "noise_levels")):
            if isinstance(values.get(dest), str):
                cells *= len([t for t in values[dest].split(",") if t.strip()]) or 1
        _budget("--trials", TRIAL_BYTES * trials * cells, f"{trials:,} trials of {cells} campaign kind(s)")
    spec = values.get("candidates")
    if isinstance(spec, str) and values.get("command") in CANDIDATE_BYTES:
        count = _candidate_count(spec)
        _budget("--candidates", count * CANDIDATE_BYTES[values["command"]], f"{count:,} candidate poses")


# -- outputs ---------------------------------------------------------------------------------
class _Captured(io.TextIOBase):
    """``sys.stdout`` while a command runs: text kept by the output set until the commit."""

    def __init__(self, outputs: Any, real: Any) -> None:
        self._outputs = outputs
        self._real = real

    def writable(self) -> bool:
        return True

    def write(self, text: str) -> int:
        self._outputs.print(text, end="")
        return len(text)

    @property
    def encoding(self) -> str:  # type: ignore[override]
        return getattr(self._real, "encoding", "utf-8") or "utf-8"

    def isatty(self) -> bool:
        return False


def _names(args: argparse.Namespace, attr: str) -> list[str]:
    out = []
    for dest in getattr(args, attr, ()) or ():
        value = getattr(args, dest, None)
        if isinstance(value, (list, tuple)):
            out += [os.fspath(v) for v in value if v is not None]
        elif value is not None:
            out.append(os.fspath(value))
    return out


def declared_files(args: argparse.Namespace) -> tuple[list[str], list[str], list[str]]:
    """The inputs, outputs and folders a command declares (``set_defaults`` in ``register``).

    - ``inputs``, ``outputs``, ``folders``: names of options holding a path (or a list);
    - ``input_lists``: option name -> a function listing the files named inside its value
      (``--candidates corners+poses.csv`` names ``poses.csv``): inputs too;
    - ``folder_files``: folder option name -> the fixed file names the command writes into
      that folder (``--out DIR`` of ``simulate``: ``DIR/study.json``...): outputs too, so
      that each is checked (a FIFO, a read-only file, an input) before any work.

    ``input_lists`` and ``folder_files`` are consumed (removed from ``args``): they are not
    options, and the reports that list a command's options must not show them.
    """
    values = vars(args)
    lists, folder_files = values.pop("input_lists", None), values.pop("folder_files", None)
    inputs = _names(args, "inputs")
    for dest, files in (lists or {}).items():
        if isinstance(values.get(dest), str):
            inputs += [os.fspath(f) for f in files(values[dest])]
    outputs = _names(args, "outputs")
    for dest, names in (folder_files or {}).items():
        if values.get(dest) is not None:
            outputs += [os.path.join(os.fspath(values[dest]), name) for name in names]
    return inputs, outputs, _names(args, "folders")


@contextlib.contextmanager
def command_outputs(args: argparse.Namespace) -> Iterator[Any]:
    """The command's output set: checked now, active and capturing stdout while it runs."""
    from hexcal.io import OutputSet, check_input

    real = sys.stdout
    inputs, declared, folders = declared_files(args)
    for name in inputs:  # FIFOs and devices refused at once, whichever reader comes later
        if os.path.lexists(name):
            check_input(name)
    outputs = OutputSet(declared, inputs=inputs, stdout=real)
    for folder in folders:
        outputs.folder(folder)
    with outputs:
        outputs.check()
        sys.stdout = _Captured(outputs, real)  # type: ignore[assignment]
        try:
            yield outputs
        finally:
            sys.stdout = real


# -- progress --------------------------------------------------------------------------------
#: Environment variable that turns progress lines on (``1``) or off (``0``) whatever stderr is.
PROGRESS_VARIABLE = "HEXCAL_PROGRESS"


def progress_lines(args: argparse.Namespace) -> contextlib.AbstractContextManager[Any]:
    """The library's progress lines (:mod:`hexcal.core.progress`) on stderr while the command
    runs: for a terminal (or ``HEXCAL_PROGRESS=1``), unless ``--quiet``; each long loop says
    how far it is after its first seconds."""
    wanted = os.environ.get(PROGRESS_VARIABLE)
    on = sys.stderr.isatty() if wanted is None else wanted.strip() == "1"
    if not on or getattr(args, "quiet", False):
        return contextlib.nullcontext()
    from hexcal.core.progress import reporting

    return reporting(lambda line: print(line, file=sys.stderr, flush=True))


# -- messages --------------------------------------------------------------------------------
_TEMPORARY = re.compile(
    r"(?P<dir>[^\s'\"]*/)?\.(?P<stem>[^/\s'\"]+?)\.[A-Za-z0-9_]{6,}\.tmp(?P<suffix>\.\w+)?(\.old)?"
)


def _untemp(text: str) -> str:
    """Temporary names (``.name.XXXXXX.tmp.png``) replaced by the file they stand for."""
    return _TEMPORARY.sub(lambda m: f"{m['dir'] or ''}{m['stem']}{m['suffix'] or ''}", text)


def error_line(exc: BaseException) -> str:
    """One line for an error: the message, without temporary names or repeated paths."""
    name = type(exc).__name__
    if name == "LinAlgError":
        text = f"the computation failed numerically ({exc}): the data do not determine the problem"
    elif isinstance(exc, OSError) and exc.strerror:
        text = f"{exc.filename}: {exc.strerror}" if exc.filename else exc.strerror
    elif isinstance(exc, MemoryError):
        text = "out of memory; reduce the size of the problem (fewer rows, trials or points)"
    else:
        text = str(exc) or name
    text = _untemp(" ".join(_clipped(word) for word in text.split()))
    return f"hexcal: error: {text}"


#: A word of an error line longer than this is shown by its ends and its length.
LONGEST_WORD = 200


def _clipped(word: str) -> str:
    """``word``, or its ends and length when it is longer than :data:`LONGEST_WORD` (a field of
    100,000 digits is not repeated in full, nor searched for temporary names)."""
    if len(word) <= LONGEST_WORD:
        return word
    return f"{word[:60]}...{word[-20:]} ({len(word):,} characters)"
