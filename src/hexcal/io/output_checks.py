"""The per-path checks of :class:`hexcal.io.outputs.OutputSet`: one output or folder at a time.

Each check raises :class:`OutputError` with one line naming the path as the user gave it
(never a temporary name). Standard library only.
"""

from __future__ import annotations

import contextlib
import os
import signal
import stat
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from hexcal.errors import InputError


class OutputError(InputError, OSError):
    """An output cannot be written (refused, or the system failed); one line naming the file."""

    def __str__(self) -> str:  # OSError would format (errno, strerror)
        return str(self.args[0]) if self.args else ""


def current_umask() -> int:
    """The process's umask (read without changing it for long)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def reason(exc: OSError) -> str:
    """The system's words for ``exc``, without its file name (which may be temporary)."""
    return exc.strerror or str(exc)


def file_kind(mode: int) -> str | None:
    """A word for a file that is not a regular file, or None."""
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def path_key(path: str) -> Any:
    """``(device, inode)`` of an existing file, else its real path: equal keys, same file."""
    try:
        st = os.stat(path)
    except OSError:
        return os.path.realpath(path)
    return (st.st_dev, st.st_ino)


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
    """Hold SIGINT, SIGTERM and SIGHUP back while the block runs (delivered right after)."""
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    held = {signal.SIGINT, signal.SIGTERM, signal.SIGHUP}
    old = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def make_folder(folder: Path) -> list[Path]:
    """Create an output folder (with parents); returns the folders created, outermost first."""
    if folder.is_dir():
        return []
    if os.path.lexists(folder):
        raise OutputError(f"{folder}: exists and is not a folder")
    missing = []
    probe = folder
    while not os.path.lexists(probe) and probe != probe.parent:
        missing.append(probe)
        probe = probe.parent
    try:
        folder.mkdir(parents=True)
    except OSError as exc:
        raise OutputError(f"{folder}: cannot create the folder: {reason(exc)}") from None
    return list(reversed(missing))


def check_target(name: str) -> tuple[Path, os.stat_result | None]:
    """The real path written for output ``name`` and its current state (None: absent).

    Refuses special files, read-only and hard-linked files and unwritable folders.
    """
    target = Path(os.path.realpath(name))
    existing = None
    try:
        existing = os.stat(target)
    except FileNotFoundError:
        pass
    except OSError as exc:
        raise OutputError(f"{name}: cannot write: {reason(exc)}") from None
    if existing is not None:
        kind = file_kind(existing.st_mode)
        if kind is not None:
            raise OutputError(
                f"{name}: is {kind}; an output must be a regular file (or - for standard output)"
            )
        if not existing.st_mode & 0o222 or not os.access(target, os.W_OK):
            raise OutputError(
                f"{name}: the file is read-only; hexcal does not replace it "
                "(change its mode or choose another name)"
            )
        if existing.st_nlink > 1:
            raise OutputError(
                f"{name}: the file has {existing.st_nlink} hard links and replacing it would break them; "
                "remove the other links or choose another name"
            )
    folder = target.parent
    if not folder.is_dir():
        raise OutputError(f"{name}: the folder {Path(name).parent} does not exist")
    try:  # the real test of a writable folder (read-only mounts, ACLs, root)
        with signals_held():
            fd, probe = tempfile.mkstemp(prefix=".hexcal-probe.", dir=folder)
            os.close(fd)
            os.unlink(probe)
    except OSError as exc:
        raise OutputError(f"{name}: cannot write in the folder {Path(name).parent}: {reason(exc)}") from None
    return target, existing
