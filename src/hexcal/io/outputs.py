"""All the outputs of one command, written together or not at all: :class:`OutputSet`.

A command declares its inputs and outputs, checks them before any computation, stages every
output in a temporary file beside its target, and commits them together at the end::

    with OutputSet(outputs=[args.out, args.report], inputs=[args.data, args.geometry]) as out:
        out.check()                      # refused here, before the work: one line each
        result = compute(...)
        save_geometry(result.geometry, args.out, outputs=out)
        with out.open(args.report) as fh:
            fh.write(text)
        with out.staged(figure_path) as tmp:
            fig.savefig(tmp)              # the temporary name keeps the suffix (.png)
        out.print(f"wrote {args.out}")    # standard output, written at the commit
    # committed here, if the block ended normally

Rules (each refused with one :class:`OutputError` line naming the option's path):

- An output naming an input, or another output (after resolving symbolic links: the same
  inode, or the same real path for files that do not exist yet), is refused by :meth:`check`.
- A special file (FIFO, device, socket) or a folder is refused as an output; ``-`` means
  standard output (buffered like a file, see below).
- An existing read-only file is refused (not silently replaced), even for root.
- A file with more than one hard link is refused: replacing it would break the links, and
  writing it in place would not be atomic.
- A symbolic link is written through: the staged file is renamed onto the link's target,
  and the link stays a link.
- A replaced file keeps its permission bits (640 stays 640); a new file gets ``0666 & ~umask``.
- Output folders are checked writable (a probe file is created and removed) by
  :meth:`check`; a folder declared with :meth:`folder` is created there and removed again if
  nothing is committed.

Order of the commit (on a normal exit of the ``with`` block, or :meth:`commit`):

1. every staged file is flushed and ``fsync``-ed (a full disk shows here);
2. the standard-output text (:meth:`print`, and ``-`` outputs) is encoded with the stream's
   encoding and error handler (an ASCII-only terminal fails here), written and flushed (a
   ``> /dev/full`` fails here);
3. with SIGINT and SIGTERM held back, every existing target is kept as a hard-link backup and
   the staged files are renamed onto the targets; if a rename fails, the backups are put back
   and the new files removed; the backups are removed at the end.

On any exception (KeyboardInterrupt and signals turned into exceptions included) before or
during the commit, the staged files and a folder created by the set are removed and no
target changes.
"""

from __future__ import annotations

import contextlib
import io
import os
import stat
import sys
import tempfile
from collections.abc import Iterable, Iterator
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from hexcal.io.output_checks import (
    OutputError,
    check_target,
    current_umask,
    make_folder,
    path_key,
    reason,
    signals_held,
)
from hexcal.report.staging import STAGER

#: The name that means standard output.
STDOUT = "-"

_ACTIVE: ContextVar[OutputSet | None] = ContextVar("hexcal_active_outputs", default=None)


@dataclass
class _Output:
    name: str  # as given: used in messages
    target: Path  # the real path written (symbolic links resolved)
    existing: os.stat_result | None
    staged: Path | None = None


class OutputSet:
    """The outputs of one command: checked up front, staged, committed all together.

    Parameters
    ----------
    outputs : iterable of str or path-like
        Output files (``None`` entries are ignored); ``"-"`` is standard output.
    inputs : iterable of str or path-like
        Input files (``None`` and preset names that are not files are ignored): no output may
        name one of them.
    stdout : text stream, optional
        Where :meth:`print` and ``-`` outputs go at the commit; default ``sys.stdout`` at
        commit time.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> with OutputSet([folder / "a.txt"]) as out:
    ...     with out.open(folder / "a.txt") as fh:
    ...         _ = fh.write("hello\\n")
    >>> (folder / "a.txt").read_text()
    'hello\\n'
    >>> OutputSet([folder / "a.txt"], inputs=[folder / "a.txt"]).check()  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    hexcal.io.output_checks.OutputError: .../a.txt: this output is also an input; choose another name
    """

    def __init__(
        self,
        outputs: Iterable[str | os.PathLike[str] | None] = (),
        inputs: Iterable[str | os.PathLike[str] | None] = (),
        *,
        stdout: IO[str] | None = None,
    ) -> None:
        self._outputs: dict[str, _Output] = {}
        self._declared: list[str] = [os.fspath(p) for p in outputs if p is not None]
        self._inputs: list[str] = [os.fspath(p) for p in inputs if p is not None]
        self._input_keys: dict[Any, str] = {}
        self._folders: list[Path] = []
        self._created: list[Path] = []
        self._stdout_target = stdout
        self._text = io.StringIO()
        self._checked = False
        self._done = False
        self._token: Any = None
        self._stager_token: Any = None

    # -- declaring and checking -------------------------------------------------------
    def add_input(self, path: str | os.PathLike[str] | None) -> None:
        """Declare one more input (checked at once if the set is already checked)."""
        if path is None:
            return
        self._inputs.append(os.fspath(path))
        if self._checked:
            self._check_input(self._inputs[-1])

    def add(self, path: str | os.PathLike[str]) -> str:
        """Declare one more output (checked at once if the set is already checked)."""
        name = os.fspath(path)
        if name == STDOUT:
            return name
        known = self._find(name)
        if known is not None:
            return known
        self._declared.append(name)
        if self._checked:
            self._check_output(name)
        return name

    def _find(self, name: str) -> str | None:
        """The name under which an output of this real path was declared, if any."""
        if name in self._declared:
            return name
        real = os.path.realpath(name)
        for other in self._declared:
            if other != STDOUT and os.path.realpath(other) == real:
                return other
        return None

    def folder(self, path: str | os.PathLike[str]) -> Path:
        """Declare an output folder: created (with parents) by :meth:`check` if absent."""
        self._folders.append(Path(path))
        if self._checked:
            self._make_folder(Path(path))
        return Path(path)

    def check(self) -> None:
        """Refuse clashing, special, read-only or unwritable outputs (call before the work)."""
        if self._checked:
            return
        self._checked = True
        for name in self._inputs:
            self._check_input(name)
        for folder in self._folders:
            self._make_folder(folder)
        if self._declared.count(STDOUT) > 1:
            raise OutputError("two outputs name standard output (-); give one of them a file name")
        for name in self._declared:
            if name == STDOUT:
                continue
            if name in self._outputs:
                raise OutputError(
                    f"{name}: is also another output of this command (two outputs name the same file); "
                    "choose another name"
                )
            self._check_output(name)

    def _check_input(self, name: str) -> None:
        if name == STDOUT or not os.path.lexists(name):
            return  # a preset name, or a missing file the reader will report
        self._input_keys.setdefault(path_key(name), name)

    def _make_folder(self, folder: Path) -> None:
        self._created.extend(make_folder(folder))

    def _check_output(self, name: str) -> None:
        key = path_key(name)
        if key in self._input_keys:
            other = self._input_keys[key]
            same = "" if other == name else f" ({other})"
            raise OutputError(f"{name}: this output is also an input{same}; choose another name")
        for other, out in self._outputs.items():
            if path_key(str(out.target)) == key or os.path.realpath(name) == str(out.target):
                raise OutputError(
                    f"{name}: is also another output of this command, {other} (two outputs name the same "
                    "file); choose another name"
                )
        target, existing = check_target(name)
        self._outputs[name] = _Output(name, target, existing)

    def _output(self, path: str | os.PathLike[str]) -> _Output:
        name = self.add(path)
        if not self._checked:
            self.check()
        return self._outputs[name]

    # -- staging ----------------------------------------------------------------------
    def _stage(self, out: _Output) -> Path:
        if self._done:
            raise RuntimeError("the output set is already committed or discarded")
        if out.staged is None:
            suffix = out.target.suffix
            try:
                with signals_held():  # no interrupt between creating and recording it
                    fd, tmp = tempfile.mkstemp(
                        prefix=f".{out.target.stem}.", suffix=f".tmp{suffix}", dir=out.target.parent
                    )
                    os.close(fd)
                    out.staged = Path(tmp)
            except OSError as exc:
                raise OutputError(f"{out.name}: cannot write: {reason(exc)}") from None
        return out.staged

    @contextlib.contextmanager
    def open(self, path: str | os.PathLike[str], mode: str = "w") -> Iterator[IO[Any]]:
        """A file handle on the staged copy of ``path`` (text: UTF-8, ``\\n`` line ends).

        ``"-"`` gives a text buffer that is written to standard output at the commit.
        Opening the same output again starts it afresh.
        """
        if os.fspath(path) == STDOUT:
            if "b" in mode:
                raise ValueError("standard output is text")
            yield self._text
            return
        out = self._output(path)
        tmp = self._stage(out)
        try:
            if "b" in mode:
                fh: IO[Any] = open(tmp, "wb")
            else:
                fh = open(tmp, "w", encoding="utf-8", newline="")
            with fh:
                yield fh
                fh.flush()
                os.fsync(fh.fileno())
        except OutputError:
            raise
        except OSError as exc:
            raise OutputError(f"{out.name}: cannot write: {reason(exc)}") from None

    @contextlib.contextmanager
    def staged(self, path: str | os.PathLike[str]) -> Iterator[str]:
        """The staged file name of ``path``, for writers that want a name (``savefig``).

        The name keeps the target's suffix, so that matplotlib picks the same format.
        """
        out = self._output(path)
        tmp = self._stage(out)
        try:
            yield str(tmp)
        except OutputError:
            raise
        except OSError as exc:
            raise OutputError(f"{out.name}: cannot write: {reason(exc)}") from None

    def write_text(self, path: str | os.PathLike[str], text: str) -> None:
        """Stage ``text`` as the whole content of ``path`` (``-``: standard output)."""
        with self.open(path) as fh:
            fh.write(text)

    def print(self, *values: Any, sep: str = " ", end: str = "\n") -> None:
        """Like :func:`print` to standard output, but written only at the commit."""
        self._text.write(sep.join(map(str, values)) + end)

    @property
    def text(self) -> str:
        """The standard-output text staged so far."""
        return self._text.getvalue()

    def show_text(self) -> None:
        """Write the staged standard output now, the files staying staged (a refusal's report)."""
        self._write_stdout()
        self._text = io.StringIO()

    # -- commit / discard ---------------------------------------------------------------
    def _stdout_bytes(self, stream: IO[str]) -> bytes:
        text = self._text.getvalue()
        encoding = getattr(stream, "encoding", None) or "utf-8"
        errors = getattr(stream, "errors", None) or "strict"
        try:
            return text.encode(encoding, errors)
        except UnicodeEncodeError as exc:
            char = exc.object[exc.start : exc.end]
            raise OutputError(
                f"standard output: cannot print {char!r} in the encoding {encoding}; "
                "set PYTHONIOENCODING=utf-8 (no output file was written)"
            ) from None
        except LookupError:
            return text.encode("utf-8")

    def _write_stdout(self) -> None:
        if not self._text.getvalue():
            return
        stream = self._stdout_target or sys.stdout
        data = self._stdout_bytes(stream)
        try:
            buffer = getattr(stream, "buffer", None)
            if buffer is not None:
                stream.flush()
                buffer.write(data)
                buffer.flush()
            else:
                stream.write(self._text.getvalue())
                stream.flush()
        except OSError as exc:
            raise OutputError(
                f"standard output: cannot write: {reason(exc)} (no output file was written)"
            ) from None

    def commit(self) -> None:
        """Write standard output, then put every staged file in place (all or nothing)."""
        if self._done:
            return
        staged = [o for o in self._outputs.values() if o.staged is not None]
        try:
            self._write_stdout()
            with signals_held():
                self._replace_all(staged)
        except BaseException:
            self.discard()
            raise
        self._done = True

    def _replace_all(self, staged: list[_Output]) -> None:
        mask = current_umask()
        backups: list[tuple[_Output, Path | None]] = []
        try:
            for out in staged:
                assert out.staged is not None
                mode = stat.S_IMODE(out.existing.st_mode) if out.existing is not None else 0o666 & ~mask
                os.chmod(out.staged, mode)
                backup = None
                if out.target.exists():
                    backup = Path(f"{out.staged}.old")
                    with contextlib.suppress(OSError):
                        os.link(out.target, backup)
                    if not backup.exists():
                        backup = None
                backups.append((out, backup))
                os.replace(out.staged, out.target)
                out.staged = None
        except OSError as exc:
            self._roll_back(backups)
            name = backups[-1][0].name if backups else "output"
            raise OutputError(f"{name}: cannot write: {reason(exc)} (no output file was changed)") from None
        except BaseException:
            self._roll_back(backups)
            raise
        for _, backup in backups:
            if backup is not None:
                with contextlib.suppress(OSError):
                    os.unlink(backup)

    @staticmethod
    def _roll_back(backups: list[tuple[_Output, Path | None]]) -> None:
        for out, backup in reversed(backups):
            with contextlib.suppress(OSError):
                if out.staged is None:  # already renamed onto the target
                    if backup is not None:
                        os.replace(backup, out.target)
                    else:
                        os.unlink(out.target)
                elif backup is not None:
                    os.unlink(backup)

    def discard(self) -> None:
        """Remove every staged file (and folders this set created); change no target."""
        self._done = True
        for out in self._outputs.values():
            if out.staged is not None:
                with contextlib.suppress(OSError):
                    os.unlink(out.staged)
                with contextlib.suppress(OSError):
                    os.unlink(f"{out.staged}.old")
                out.staged = None
        for folder in reversed(self._created):
            with contextlib.suppress(OSError):
                folder.rmdir()  # only if empty: never remove a user's file
        self._created.clear()

    def __enter__(self) -> OutputSet:
        self._token = _ACTIVE.set(self)
        self._stager_token = STAGER.set(self.staged)
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        try:
            if exc_type is None:
                self.commit()
            else:
                self.discard()
        finally:
            if self._token is not None:
                _ACTIVE.reset(self._token)
                STAGER.reset(self._stager_token)
                self._token = None


def active_outputs() -> OutputSet | None:
    """The output set of the innermost ``with OutputSet(...)`` block, if any."""
    return _ACTIVE.get()


@contextlib.contextmanager
def output_file(
    path: str | os.PathLike[str], mode: str = "w", outputs: OutputSet | None = None
) -> Iterator[IO[Any]]:
    """A staged handle on ``path`` in ``outputs``, the active set, or a set of its own.

    Every hexcal writer goes through here: inside a command's ``with OutputSet(...)``
    block, files are committed with the others; alone, the file is written atomically.
    """
    target = outputs if outputs is not None else active_outputs()
    if target is not None:
        with target.open(path, mode) as fh:
            yield fh
        return
    with OutputSet([path]) as own:
        own.check()
        with own.open(path, mode) as fh:
            yield fh
