"""Progress of long computations: library loops say how far they are, silent unless asked.

A long loop of the library opens a :func:`task` and advances it; nothing is shown unless the
caller turned reporting on with :func:`reporting` (the command line does, for a terminal).
Then a line goes to the caller's ``emit`` once the task has run for ``delay`` seconds, at
most every ``every`` seconds after that, and at its end (only if a line was shown)::

    from hexcal.core.progress import reporting, task

    with reporting(print, delay=3.0):          # the caller: lines after 3 s
        ...
        with task("candidate poses", total=n) as step:   # a library loop
            for chunk in chunks:
                ...
                step(len(chunk))               # or step() for one

Tasks nest: an inner task's lines name the outer one (``select: exchange: 40/120``). A task
opened without reporting costs a context-variable lookup. Reporting belongs to the process
that turned it on: a forked worker (a pool's) stays silent. Standard library only.

>>> lines = []
>>> clock = iter(range(0, 100, 2)).__next__   # a clock that advances 2 s per look
>>> with reporting(lines.append, delay=3.0, every=3.0, clock=clock):
...     with task("trials", total=4) as step:
...         for _ in range(4):
...             step()
>>> lines
['hexcal: trials: 2/4 (4 s)', 'hexcal: trials: 4/4 (8 s)', 'hexcal: trials: done, 4/4 (10 s)']
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

#: Seconds a task runs before its first line, by default.
DEFAULT_DELAY = 3.0
#: Seconds between two lines of one task, by default.
DEFAULT_EVERY = 5.0


@dataclass
class _Reporter:
    emit: Callable[[str], None]
    delay: float
    every: float
    clock: Callable[[], float]
    pid: int = field(default_factory=os.getpid)
    stack: list[str] = field(default_factory=list)


_REPORTER: contextvars.ContextVar[_Reporter | None] = contextvars.ContextVar("hexcal_progress", default=None)


@contextlib.contextmanager
def reporting(
    emit: Callable[[str], None],
    delay: float | None = None,
    every: float | None = None,
    clock: Callable[[], float] = time.monotonic,
) -> Iterator[None]:
    """Show the progress of the tasks run inside: ``emit(line)`` for each line (one line of
    text, no newline), after a task's first ``delay`` seconds (default :data:`DEFAULT_DELAY`),
    then every ``every`` seconds (default :data:`DEFAULT_EVERY`) and at its end. ``clock``
    gives seconds (tests pass their own)."""
    delay = DEFAULT_DELAY if delay is None else delay
    every = DEFAULT_EVERY if every is None else every
    token = _REPORTER.set(_Reporter(emit, float(delay), float(every), clock))
    try:
        yield
    finally:
        _REPORTER.reset(token)


def _silent(n: int = 1) -> None:
    del n


@contextlib.contextmanager
def task(label: str, total: int | None = None) -> Iterator[Callable[[int], None]]:
    """A long loop of ``total`` steps (None: unknown): yields ``step(n=1)``, to call as the
    loop advances. Silent unless :func:`reporting` is on in this process."""
    reporter = _REPORTER.get()
    if reporter is None or reporter.pid != os.getpid():
        yield _silent
        return
    name = ": ".join([*reporter.stack, label])
    start = reporter.clock()
    state = {"done": 0, "shown": None}

    def line(now: float, prefix: str = "") -> str:
        count = f"{state['done']}/{total}" if total else f"{state['done']}"
        return f"hexcal: {name}: {prefix}{count} ({now - start:.0f} s)"

    def step(n: int = 1) -> None:
        state["done"] += n
        now = reporter.clock()
        shown = state["shown"]
        if (shown is None and now - start >= reporter.delay) or (
            shown is not None and now - shown >= reporter.every
        ):
            state["shown"] = now
            reporter.emit(line(now))

    reporter.stack.append(label)
    try:
        yield step
    finally:
        reporter.stack.pop()
    if state["shown"] is not None:
        reporter.emit(line(reporter.clock(), "done, "))
