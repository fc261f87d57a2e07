"""Where a figure is written: through the command's output set when one is active.

The report layer draws figures but does not own files: :func:`staged_path` asks the
output set of the running command (installed by :mod:`hexcal.io.outputs` through
:data:`STAGER`) for a temporary name that is committed with the command's other outputs.
Without one, the figure is written to a temporary name beside the target and renamed.
Standard library only.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager
from contextvars import ContextVar
from pathlib import Path

#: The active stager: a function of a path giving a context manager that yields the
#: staged file name to write (set by :class:`hexcal.io.outputs.OutputSet`).
STAGER: ContextVar[Callable[[str | os.PathLike[str]], AbstractContextManager[str]] | None] = ContextVar(
    "hexcal_stager", default=None
)


@contextlib.contextmanager
def staged_path(path: str | os.PathLike[str]) -> Iterator[str]:
    """A file name to write ``path``'s content to; put in place when the output set commits.

    >>> import tempfile, pathlib
    >>> target = pathlib.Path(tempfile.mkdtemp()) / "f.txt"
    >>> with staged_path(target) as tmp:
    ...     _ = pathlib.Path(tmp).write_text("x")
    >>> target.read_text()
    'x'
    """
    stager = STAGER.get()
    if stager is not None:
        with stager(path) as tmp:
            yield tmp
        return
    target = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.stem}.", suffix=f".tmp{target.suffix}", dir=target.parent)
    os.close(fd)
    try:
        yield tmp
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
