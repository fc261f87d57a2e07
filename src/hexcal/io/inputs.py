"""Opening input files safely: regular files only, size limits, YAML with limits.

- Only regular files are read. A FIFO, a device, a socket or a folder is refused at once,
  before opening for reading (``os.stat``), and the file is then opened non-blocking and
  checked again on its descriptor, so that no input ever blocks hexcal.
- Tables have a row limit, :data:`DEFAULT_MAX_ROWS`, checked while reading, before the rows
  are converted; the message names the limit and the option that raises it
  (``--max-rows``). Commands that can work in blocks (``ik``, ``fk``) read with
  :func:`hexcal.io.tables.iter_tables` instead, in bounded memory and without a limit.
- YAML is read with :func:`load_yaml`: PyYAML's safe loader (no tags that build Python
  objects), limited to :data:`MAX_YAML_DEPTH` levels of nesting and :data:`MAX_YAML_NODES`
  nodes once aliases are expanded, so that an alias bomb ("billion laughs") or a deeply
  nested document fails at once with one line instead of exhausting memory or the stack;
  a key given twice in one mapping is refused, naming the key and both lines (YAML requires
  unique keys; PyYAML would silently keep the last).
Input files are opened for reading only and never modified.
"""

from __future__ import annotations

import fcntl
import os
import re
import stat
from contextvars import ContextVar
from typing import IO, Any

import yaml
from yaml.events import AliasEvent

from hexcal.errors import InputError
from hexcal.io.output_checks import file_kind

#: Data rows a table may have when it is read whole (``read_table``): a million measured
#: poses, far beyond any calibration campaign (a few hundred poses). Raised with the
#: ``max_rows`` argument (the command line's ``--max-rows``).
DEFAULT_MAX_ROWS = 1_000_000

#: Data rows a measurement file may have (``read_measurements``, used by ``identify`` and
#: ``validate``): an identification holds several arrays per pose (Jacobians of 6 x 48 and
#: more), so a million poses would need many GB; 100,000 poses (a thousand times a campaign)
#: is refused above, up front, naming the limit and ``--max-rows``.
MEASUREMENT_MAX_ROWS = 100_000

#: The command line's ``--max-rows``: when set, it replaces the row limit of every table
#: read whole in this context (:func:`row_limit`).
ROW_LIMIT: ContextVar[int | None] = ContextVar("hexcal_row_limit", default=None)


def row_limit(default: int | None) -> int | None:
    """The row limit in force: ``--max-rows`` if the command line set one, else ``default``."""
    override = ROW_LIMIT.get()
    return default if override is None or default is None else override


#: Levels of nesting allowed in a YAML file (a geometry needs 4).
MAX_YAML_DEPTH = 64

#: Nodes a YAML file may hold once its aliases are expanded (a geometry has about 100,
#: a calibrated one with covariances a few thousand).
MAX_YAML_NODES = 200_000

#: Bytes of a YAML file (a calibrated geometry is a few tens of kB).
MAX_YAML_BYTES = 16 * 1024 * 1024


def _kind(mode: int) -> str:
    """Why a file of this mode is refused as an input (file kinds as :func:`file_kind` names them)."""
    kind = file_kind(mode) or "not a regular file"
    if kind == "a folder":
        return "is a folder, not a file"
    if kind == "not a regular file":
        return "is not a regular file; hexcal reads only regular files"
    return f"is {kind}, not a regular file; hexcal reads only regular files"


def check_input(path: str | os.PathLike[str]) -> os.stat_result:
    """The status of a readable regular file; :class:`InputError` otherwise (never blocks).

    >>> check_input("/dev/null")
    Traceback (most recent call last):
    ...
    hexcal.errors.InputError: /dev/null: is a device, not a regular file; hexcal reads only regular files
    """
    name = os.fspath(path)
    try:
        st = os.stat(name)
    except FileNotFoundError:
        raise InputError(f"{name}: no such file") from None
    except OSError as exc:
        raise InputError(f"{name}: cannot read: {exc.strerror or exc}") from None
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{name}: {_kind(st.st_mode)}")
    return st


def open_input(path: str | os.PathLike[str], encoding: str = "utf-8") -> IO[str]:
    """Open a regular file for reading as text (``newline=""``), never blocking.

    The file is checked with ``os.stat`` first, then opened with ``O_NONBLOCK`` and checked
    again on its descriptor (a file swapped for a FIFO in between is refused too).
    """
    name = os.fspath(path)
    check_input(name)
    try:
        fd = os.open(name, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise InputError(f"{name}: cannot read: {exc.strerror or exc}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise InputError(f"{name}: {_kind(st.st_mode)}")
        flags = fcntl.fcntl(fd, fcntl.F_GETFL)
        fcntl.fcntl(fd, fcntl.F_SETFL, flags & ~os.O_NONBLOCK)
        return open(fd, encoding=encoding, newline="")
    except BaseException:
        os.close(fd)
        raise


def read_text(path: str | os.PathLike[str], encoding: str = "utf-8", max_bytes: int | None = None) -> str:
    """The whole text of a regular file; over ``max_bytes`` bytes is refused before reading."""
    name = os.fspath(path)
    st = check_input(name)
    if max_bytes is not None and st.st_size > max_bytes:
        raise InputError(f"{name}: {st.st_size:,} bytes, over the limit of {max_bytes:,} bytes for this file")
    try:
        with open_input(name, encoding) as fh:
            return fh.read()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{name}: cannot read: {exc}") from None


def too_many_rows(path: str, max_rows: int) -> InputError:
    """The error for a table over the row limit (names the limit and how to raise it)."""
    return InputError(
        f"{path}: more than {max_rows:,} data rows, the limit; raise it with --max-rows "
        "(memory grows with the rows)"
    )


# -- YAML -------------------------------------------------------------------------------


class YamlLimitError(yaml.YAMLError):
    """A YAML document beyond :data:`MAX_YAML_DEPTH` or :data:`MAX_YAML_NODES`, or with a
    key given twice in one mapping."""

    def __init__(self, problem: str, mark: Any) -> None:
        super().__init__(problem)
        self.problem = problem
        self.problem_mark = mark


class LimitedSafeLoader(yaml.SafeLoader):
    """PyYAML's ``SafeLoader`` that counts nodes (aliases expanded) and nesting depth.

    An alias costs the size of the node it repeats, so that ``MAX_YAML_NODES`` bounds the
    size of the data that the document stands for, whatever the aliases.
    """

    max_depth = MAX_YAML_DEPTH
    max_nodes = MAX_YAML_NODES

    def __init__(self, stream: Any) -> None:
        super().__init__(stream)
        self._depth = 0
        self._nodes = 0
        self._sizes: dict[int, int] = {}

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(AliasEvent):
            mark = self.peek_event().start_mark
            node = super().compose_node(parent, index)
            self._count(self._sizes.get(id(node), 1), mark)
            return node
        mark = self.peek_event().start_mark
        self._depth += 1
        if self._depth > self.max_depth:
            raise YamlLimitError(f"nested more than {self.max_depth} levels deep", mark)
        start = self._nodes
        try:
            self._count(1, mark)
            node = super().compose_node(parent, index)
        finally:
            self._depth -= 1
        self._sizes[id(node)] = self._nodes - start
        return node

    def construct_mapping(self, node: Any, deep: bool = False) -> Any:
        """A mapping, refusing a key given twice (merge keys ``<<`` may be overridden)."""
        if isinstance(node, yaml.MappingNode):
            seen: dict[Any, int] = {}
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=True)
                line = key_node.start_mark.line + 1
                try:
                    first = seen.get(key)
                    seen.setdefault(key, line)
                except TypeError:  # an unhashable key: PyYAML's own error follows
                    continue
                if first is not None:
                    shown = repr(key) if len(repr(key)) <= 60 else repr(key)[:57] + "..."
                    where = f"lines {first} and {line}" if first != line else f"line {line}"
                    raise YamlLimitError(
                        f"the key {shown} is given twice in one mapping, on {where}", key_node.start_mark
                    )
        return super().construct_mapping(node, deep)

    def _count(self, size: int, mark: Any) -> None:
        self._nodes += size
        if self._nodes > self.max_nodes:
            raise YamlLimitError(
                f"more than {self.max_nodes:,} values once aliases are expanded (an alias bomb?)", mark
            )


# YAML 1.1 (PyYAML) reads ``1e-3``, ``2E5`` and ``1.5e3`` as text: its floats need a dot and a
# signed exponent. Users write them (a noise ``{position: 1e-3}``); YAML 1.2 reads them as
# numbers, and so does hexcal.
LimitedSafeLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+.0123456789"),
)


def load_yaml(path: str | os.PathLike[str], what: str = "YAML") -> Any:
    """Parse a YAML file safely with limits; one-line :class:`InputError` on any problem.

    Parameters
    ----------
    path : str or path-like
        A regular file (UTF-8).
    what : str
        What the file is, for messages ("geometry file").
    """
    name = os.fspath(path)
    return parse_yaml(read_text(name, max_bytes=MAX_YAML_BYTES), name, what)


def parse_yaml(text: str, name: str, what: str = "YAML") -> Any:
    """Parse YAML text as :func:`load_yaml` parses a file (``name`` for messages).

    >>> parse_yaml("a: 1\\nb: 2\\na: 3\\n", "g.yaml")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    hexcal.errors.InputError: g.yaml: line 3: not valid YAML (the key 'a' is given twice ... lines 1 and 3)
    """
    loader: LimitedSafeLoader | None = None
    try:
        loader = LimitedSafeLoader(text)
        return loader.get_single_data()
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}: " if mark is not None else ""
        problem = getattr(exc, "problem", None) or (str(exc).splitlines() or ["?"])[0]
        raise InputError(f"{name}: {where}not valid {what} ({problem})") from None
    except (ValueError, OverflowError, RecursionError, MemoryError, TypeError) as exc:
        # e.g. an integer over Python's digit limit, or a key that cannot be hashed
        first = (str(exc).splitlines() or [type(exc).__name__])[0]
        raise InputError(f"{name}: not valid {what} ({first})") from None
    finally:
        if loader is not None:
            loader.dispose()
