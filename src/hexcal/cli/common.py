"""Helpers shared by the ``hexcal`` subcommands: geometry loading with ``--euler``, id-list
and table options, the ``--fit`` mask, the ``--candidates`` spec and its feasibility filter, output-path
checks, warnings and progress lines.

This module imports only the standard library and :mod:`hexcal.errors` at its top, so
that building the parser (``hexcal --help``) costs no numpy; the helpers that need the
library import it when they run. Every failure of an option raises :class:`CommandError`,
which ``hexcal.cli.main`` prints as one line.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from hexcal.errors import UsageError

if TYPE_CHECKING:
    from pathlib import Path

    from hexcal.core import Geometry

#: Names of the built-in geometries (``hexcal.core.PRESETS``), spelled here so that the
#: parser is built without importing numpy; ``tests/test_cli.py`` checks they agree.
PRESET_NAMES = ("paper-hmt", "paper-hmt-true")

#: Help of every ``--geometry`` option.
GEOMETRY_HELP = f"geometry YAML file or preset ({', '.join(PRESET_NAMES)})"

#: Help of ``--euler``.
EULER_HELP = "Euler sequence of the angles (default: the geometry's)"


class CommandError(UsageError):
    """A failure of a command's options to report as one line."""


def id_list(ids: Sequence[str], most: int = 20) -> str:
    """``ids`` joined by commas, cut after ``most`` with the total count.

    >>> id_list(["p1", "p2", "p3"], most=2)
    'p1, p2 ... (3 in all)'
    """
    return ", ".join(ids[:most]) + (f" ... ({len(ids)} in all)" if len(ids) > most else "")


def load_geometry(spec: str, euler: str | None = None) -> Geometry:
    """The geometry of a YAML file or preset, with the Euler sequence of ``--euler``."""
    from hexcal.io import load_geometry as load

    geometry = load(spec)
    return geometry.replace(euler=euler) if euler else geometry


#: ``--delimiter`` values and the characters they stand for.
DELIMITER_WORDS = {",": ",", ";": ";", "tab": "\t"}

#: Help of ``--columns``.
COLUMNS_HELP = (
    "column map of the table read, hexcal_name=file_column,... (e.g. dl1=leg_length_1,x=position_x,"
    "qw=orientation_w): read a file with its own column names"
)


def column_map(text: str) -> dict[str, str]:
    """The ``--columns`` spec as a map (an :class:`argparse.ArgumentTypeError` naming the bad item).

    >>> column_map("x=position_x")
    {'x': 'position_x'}
    """
    from hexcal.io.target_files import parse_column_map  # when the option is given: no numpy for --help

    try:
        return parse_column_map(text)
    except UsageError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def table_options(p: argparse.ArgumentParser, what: str, note: str = "", dialect: bool = True) -> None:
    """Add ``--columns`` (and ``--delimiter``, ``--decimal`` with ``dialect``) for the table ``what``
    (``note``: more on the column map)."""
    p.add_argument("--columns", metavar="SPEC", type=column_map, help=f"{COLUMNS_HELP} ({what}{note})")
    if dialect:
        p.add_argument(
            "--delimiter",
            choices=tuple(DELIMITER_WORDS),
            help=f"field separator of {what} (default: detected)",
        )
        p.add_argument("--decimal", choices=(".", ","), help=f"decimal mark of {what} (default: detected)")


def condition_options(p: argparse.ArgumentParser) -> None:
    """Add ``--temperature`` and ``--payload``: one value for every row, for a leg model with
    covariates (docs/leg-models.md)."""
    p.add_argument("--temperature", type=float, metavar="C", help="the legs' temperature, °C, for every row")
    p.add_argument(
        "--payload",
        type=payload_value,
        metavar="KG[,X,Y,Z]",
        help="the payload's mass, kg, and optionally its centre of mass, mm, platform frame, for every row",
    )


def payload_value(text: str) -> tuple[float, ...]:
    """``--payload KG[,X,Y,Z]`` as numbers (their checks are the library's)."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected KG or KG,X,Y,Z (numbers), got {text!r}") from None
    if len(values) not in (1, 4):
        raise argparse.ArgumentTypeError(f"expected KG or KG,X,Y,Z, got {len(values)} numbers")
    return values


def table_reading(args: argparse.Namespace) -> dict[str, Any]:
    """The reader options of ``--columns``, ``--delimiter`` and ``--decimal`` (keywords of the
    readers of :mod:`hexcal.io`)."""
    word = getattr(args, "delimiter", None)
    return {
        "delimiter": None if word is None else DELIMITER_WORDS[word],
        "decimal": getattr(args, "decimal", None),
        "columns": getattr(args, "columns", None),
    }


def choice(value: str, allowed: Sequence[str], option: str) -> str:
    """``value`` if it is one of ``allowed``, else a :class:`CommandError` naming ``option``.

    >>> choice("A", ("D", "A"), "--criterion")
    'A'
    """
    if value not in allowed:
        raise CommandError(f"{option}: unknown {value!r}; choose from {', '.join(allowed)}")
    return value


def fit_mask(fit: str, fix: Sequence[str] = (), option: str | None = "--fit", geometry: Any = None) -> Any:
    """The parameter mask of ``--fit`` groups and ``--fix`` names: over the 48 linear-leg
    parameters, or over ``geometry``'s machine parameters when its leg model has terms of its
    own (their group, e.g. ``stroke``, added to the fit as ``identify`` adds it)."""
    from hexcal.core import select_parameters

    try:
        if geometry is not None and geometry.leg_model.terms:
            import numpy as np

            from hexcal.calibration.leg_model_choice import fit_for

            return np.asarray(geometry.machine_parameters(fit_for(fit, geometry.leg_model), fix).vary)
        return select_parameters(fit, fix)
    except ValueError as exc:
        raise CommandError(f"{option}: {exc}" if option else str(exc)) from None


def fitted_groups(fit: str, geometry: Any) -> str:
    """``--fit`` with the group of the geometry's leg model added when it has terms (as
    :func:`fit_mask` and ``identify`` add it), for headings."""
    if not geometry.leg_model.terms:
        return fit
    from hexcal.calibration.leg_model_choice import fit_for

    return str(fit_for(fit, geometry.leg_model))


def int_list(text: str, option: str) -> list[int]:
    """Positive integers of a comma-separated option.

    >>> int_list("7,15", "--poses")
    [7, 15]
    """
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise CommandError(f"{option}: {text!r} is not a comma-separated list of integers") from None
    if not values or min(values) < 1:
        raise CommandError(f"{option}: give positive integers, got {text!r}")
    return values


def check_outputs(*paths: str | None) -> None:
    """Fail before any work when an output's folder does not exist."""
    from pathlib import Path

    for path in paths:
        if path is None:
            continue
        folder = Path(path).parent
        if not folder.is_dir():
            raise CommandError(f"{path}: the folder {folder} does not exist")
        if Path(path).is_dir():
            raise CommandError(f"{path}: is a folder, not a file")


def output_folder(path: str | None) -> Path | None:
    """The ``--out`` folder of a study (None without ``--out``); fails if it is a file."""
    from pathlib import Path

    out = Path(path) if path else None
    if out is not None and out.exists() and not out.is_dir():
        raise CommandError(f"--out {out}: exists and is not a folder")
    return out


def check_trials(trials: int) -> None:
    """Fail unless ``--trials`` is at least 1."""
    if trials < 1:
        raise CommandError(f"--trials must be at least 1, got {trials}")


def warn(message: str) -> None:
    """Print ``message`` on stderr (the caller writes the ``hexcal: warning:`` prefix)."""
    print(message, file=sys.stderr)


#: ``--candidates`` kinds and the prefixes of their pose ids.
CANDIDATE_PREFIXES = {"corners": "c", "grid": "g", "edges": "e", "random": "r"}


def _number(text: str, token: str, low: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise CommandError(f"--candidates: {token!r}: {text!r} is not a whole number") from None
    if value < low:
        raise CommandError(f"--candidates: {token!r}: the number must be at least {low}")
    return value


def _candidate_kind(token: str, geometry: Any, rng: Any) -> tuple[Any, list[str]]:
    """Poses and ids of one built-in kind of ``--candidates`` (``grid:3``, ``random:100``...)."""
    from hexcal.design import candidate_poses

    kind, _, arg = token.partition(":")
    if kind == "corners" and arg:
        raise CommandError(f"--candidates: {token!r}: corners take no number")
    if kind == "random" and not arg:
        raise CommandError("--candidates: random needs a number, e.g. random:1000")
    count = _number(arg, token, 1 if kind == "random" else 2) if arg else None
    if kind in ("grid", "edges") and count is not None and count > 12:
        raise CommandError(f"--candidates: {token!r}: at most 12 grid levels (12⁶ poses)")
    try:
        poses = candidate_poses(geometry, kind, count, rng)
    except ValueError as exc:
        raise CommandError(f"--candidates: {token}: {exc}") from None
    width = len(str(len(poses)))
    return poses, [f"{CANDIDATE_PREFIXES[kind]}{k:0{width}d}" for k in range(len(poses))]


def candidate_files(spec: str | None) -> list[str]:
    """The files a ``--candidates`` spec names (every token that is not a built-in kind).

    Declared as inputs of the command's output set, so that no output may replace one.

    >>> candidate_files("corners+grid:3+poses.csv+random:10+more.csv")
    ['poses.csv', 'more.csv']
    """
    tokens = [t.strip() for t in (spec or "").split("+") if t.strip()]
    return [t for t in tokens if t.partition(":")[0] not in CANDIDATE_PREFIXES]


def candidate_spec(spec: str, geometry: Any, seed: int, covariates: bool = False) -> Any:
    """Candidate poses and ids of a spec like ``corners+grid:3+random:1000+file.csv``; with
    ``covariates``, also their conditions (:class:`hexcal.instruments.Covariates`, or None
    unless every part is a file with the same covariate columns)."""
    from pathlib import Path

    import numpy as np

    from hexcal.io import read_poses

    tokens = [t.strip() for t in spec.split("+") if t.strip()]
    if not tokens:
        raise CommandError("--candidates: empty; give corners, grid[:L], edges[:L], random:N or a file")
    rng = np.random.default_rng(seed)
    parts = []
    conditions = []
    ids: list[str] = []
    for token in tokens:
        if token.partition(":")[0] in CANDIDATE_PREFIXES:
            poses, new_ids = _candidate_kind(token, geometry, rng)
            ids += new_ids
            conditions.append(None)
        else:
            if not Path(token).exists():
                raise CommandError(
                    f"--candidates: {token!r} is neither corners, grid[:L], edges[:L], random:N nor a file"
                )
            poses, file_ids, found = read_poses(token, geometry.euler, covariates=True)
            ids += list(file_ids)
            conditions.append(found.to_columns() if found else None)
        parts.append(poses)
    seen: set[str] = set()
    for i in ids:
        if i in seen:
            raise CommandError(f"--candidates: pose id {i!r} appears twice; give the files distinct ids")
        seen.add(i)
    if not covariates:
        return np.concatenate(parts), ids
    joined = None
    if all(c is not None for c in conditions) and len({tuple(c) for c in conditions}) == 1:
        from hexcal.instruments import Covariates

        joined = Covariates.from_columns(
            {k: np.concatenate([c[k] for c in conditions]) for k in conditions[0]}
        )
    return np.concatenate(parts), ids, joined


def feasible_candidates(
    geometry: Any, poses: Any, ids: list[str], min_distance: float | None
) -> tuple[Any, list[str], str | None]:
    """Feasible candidates, their ids, and a warning naming the infeasible ones (or None).

    The warning is printed once the command has succeeded, so that a failure stays one line.
    """
    import numpy as np

    from hexcal.design import MIN_SINGULARITY_DISTANCE, check_feasibility

    threshold = MIN_SINGULARITY_DISTANCE if min_distance is None else min_distance
    if not (math.isfinite(threshold) and threshold >= 0):
        raise CommandError(f"--min-distance must be a finite value >= 0, got {threshold}")
    report = check_feasibility(geometry, poses, threshold)
    keep = np.flatnonzero(report.feasible)
    if keep.size == 0:
        raise CommandError(f"no feasible candidate pose: {report.summary()}")
    warning = None
    if report.n_infeasible:
        bad = np.flatnonzero(~report.feasible)
        detail = "; ".join(f"{ids[k]}: {report.reasons(k)}" for k in bad[:5])
        more = f" ... ids {id_list([ids[k] for k in bad])}" if bad.size > 5 else ""
        warning = f"hexcal: warning: candidates: {report.summary()}; never proposed ({detail}{more})"
    return poses[keep], [ids[k] for k in keep], warning


class Progress:
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


def inputs_record(files: dict[str, str | None], args: argparse.Namespace) -> dict[str, Any]:
    """What makes a report traceable: the input files with their SHA-256 (presets by name),
    the command's options, hexcal's version and the date."""
    import datetime
    import hashlib
    from importlib.metadata import version

    records = []
    for role, path in files.items():
        if path is None:
            continue
        if path in PRESET_NAMES:
            records.append({"role": role, "path": f"preset {path}", "sha256": "-"})
            continue
        digest = hashlib.sha256()
        with open(path, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                digest.update(block)
        records.append({"role": role, "path": str(path), "sha256": digest.hexdigest()})
    options = {
        k: v for k, v in sorted(vars(args).items()) if k not in ("func", "command") and v not in (None, False)
    }
    return {
        "files": records,
        "command": f"hexcal {args.command}",
        "options": options,
        "hexcal version": version("hexcal"),
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
    }


def show_defaults(parser: argparse.ArgumentParser) -> None:
    """Append ``(default ...)`` to the help of every option whose help does not state it.

    >>> p = argparse.ArgumentParser()
    >>> _ = p.add_argument("--seed", type=int, default=0, help="random seed")
    >>> show_defaults(p)
    >>> p._actions[-1].help
    'random seed (default %(default)s)'
    """
    for action in parser._actions:
        if not action.option_strings or action.help == argparse.SUPPRESS or action.dest == "help":
            continue
        text = action.help or ""
        if "default" in text:
            continue
        if action.required:
            continue
        if isinstance(action, argparse._StoreTrueAction):
            suffix = "(default: off)"
        elif action.default is None:
            suffix = "(default: none)"
        else:
            suffix = "(default %(default)s)"
        action.help = f"{text} {suffix}".strip()
