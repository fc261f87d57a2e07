"""The one runner: maps chunks of trial indices over an executor and reassembles by index.

A simulation is a *definition* (a small picklable object) and a *chunk function*
``fn(definition, indices) -> {name: array}`` that simulates the trials ``indices``
(generating their data from the trial seeds, :class:`~hexcal.simulation.protocol.TrialSeeds`)
and returns arrays whose first axis runs over those trials. :func:`map_trials` submits
the chunks to an executor (anything with ``submit(fn, *args)`` returning a future with
``.result()``: :class:`SerialExecutor` in this process,
:class:`concurrent.futures.ProcessPoolExecutor` for ``jobs > 1``, or a distributed
client), reports progress as chunks complete and concatenates the results in trial
order, so they do not depend on how trials are grouped or where they run.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from hexcal.core.progress import task

#: Progress callback ``(done, total)``.
Progress = Callable[[int, int], None]
#: A chunk function ``(definition, trial indices) -> {name: array over those trials}``.
ChunkFunction = Callable[[Any, NDArray[np.intp]], Mapping[str, NDArray[Any]]]

#: Most trials per chunk: the trials of a chunk are identified together, and the batched
#: solvers gain from larger stacks (measured: 100 trials per chunk take 30 % less CPU than
#: 32 for ``hexcal paper``); small enough for frequent progress.
MAX_CHUNK = 100
#: Chunks of a run by default (fewer trials per chunk when there are few trials): enough for
#: load balance on a few cores and for progress lines; large runs get more chunks of
#: :data:`MAX_CHUNK` trials, to spread over a cluster.
CHUNKS = 16
#: ``prctl`` option of Linux: the signal a process gets when the thread that forked it ends.
PR_SET_PDEATHSIG = 1
#: Seconds between two looks at the parent by a worker's watchdog (where ``prctl`` is missing).
WATCHDOG_PERIOD = 0.5


class Executor(Protocol):
    """Anything that runs ``fn(*args)`` and returns a future (``concurrent.futures`` style)."""

    def submit(self, fn: Callable[..., Any], /, *args: Any) -> Future[Any]: ...


class SerialExecutor:
    """An executor that runs each submitted call at once, in this process.

    Examples
    --------
    >>> SerialExecutor().submit(pow, 2, 10).result()
    1024
    """

    def submit(self, fn: Callable[..., Any], /, *args: Any) -> Future[Any]:
        future: Future[Any] = Future()
        try:
            future.set_result(fn(*args))
        except Exception as exc:  # delivered through the future, as a pool would
            future.set_exception(exc)
        return future


def worker_signals(parent: int | None = None) -> None:
    """In a pool worker: SIGINT and SIGHUP ignored (the parent stops the pool: a closed
    terminal sends SIGHUP to every process of its group, and only the parent decides, so that
    it never sees a broken pool instead of the signal), SIGTERM kills at once (the parent
    terminates its workers with it); with ``parent`` (its pid), the worker also ends when that
    process is gone (:func:`end_with_parent`)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if parent is not None:
        end_with_parent(parent)


def end_with_parent(parent: int) -> None:
    """End this process when its parent ``parent`` is gone, however it died.

    A parent killed by a signal it cannot handle (SIGKILL, an out-of-memory kill, ``timeout
    -s KILL``) or by one it does not handle (SIGQUIT, SIGUSR1) cannot stop its pool; its
    workers would be re-parented and compute on. On Linux the kernel sends this process
    SIGKILL when the parent ends (``prctl(PR_SET_PDEATHSIG)``); elsewhere a daemon thread looks
    at the parent's pid every :data:`WATCHDOG_PERIOD` seconds. A parent already gone when this
    is called ends the process at once.
    """
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0:
            if os.getppid() != parent:  # it died before the request: nobody will signal
                os._exit(1)
            return
    thread = threading.Thread(target=_watch_parent, args=(parent,), name="hexcal-parent-watch", daemon=True)
    thread.start()


def _watch_parent(parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(WATCHDOG_PERIOD)
    os._exit(1)


def resolve_jobs(jobs: int | None) -> int:
    """Number of processes: ``None`` means all cores, at least 1."""
    return (os.cpu_count() or 1) if not jobs else max(1, int(jobs))


def chunk_indices(trials: int, jobs: int = 1, chunk_size: int | None = None) -> list[NDArray[np.intp]]:
    """Trial indices ``0 .. trials-1`` in chunks (default :func:`default_chunk_size`).

    ``jobs`` is accepted for compatibility and does not change the chunks: the trials of a
    chunk are identified together, and the batched solver's last digits (about 1e-11 mm)
    depend on which trials share a stack, so the chunks must not depend on where they run.

    Examples
    --------
    >>> [c.tolist() for c in chunk_indices(5, chunk_size=2)]
    [[0, 1], [2, 3], [4]]
    """
    del jobs
    chunk_size = default_chunk_size(trials) if chunk_size is None else max(1, int(chunk_size))
    return [np.arange(i, min(i + chunk_size, trials)) for i in range(0, trials, chunk_size)]


def default_chunk_size(trials: int) -> int:
    """Trials per chunk: about :data:`CHUNKS` chunks, at most :data:`MAX_CHUNK` trials each.

    A function of the number of trials only, never of the processes or the cluster: the
    same chunks everywhere give bit-identical numbers locally, with any ``--jobs`` and on
    any cluster.

    Examples
    --------
    >>> default_chunk_size(5), default_chunk_size(1000), default_chunk_size(10**6)
    (1, 63, 100)
    """
    return max(1, min(MAX_CHUNK, -(-int(trials) // CHUNKS)))


def map_trials(
    fn: ChunkFunction,
    definition: Any,
    trials: int,
    *,
    jobs: int | None = 1,
    executor: Executor | None = None,
    chunk_size: int | None = None,
    progress: Progress | None = None,
    weight: int = 1,
) -> dict[str, NDArray[Any]]:
    """Run ``fn(definition, indices)`` over all trials, chunk by chunk.

    Parameters
    ----------
    fn : callable
        The chunk function; a module-level function if it runs in other processes.
    definition : object
        Passed to every chunk (picklable for other processes).
    trials : int
    jobs : int or None
        Processes when no ``executor`` is given: 1 runs in this process, more use a
        :class:`~concurrent.futures.ProcessPoolExecutor` (``None``: all cores).
    executor : Executor, optional
        Where to run the chunks (it is not shut down here).
    chunk_size : int, optional
        Trials per chunk (default :func:`default_chunk_size`, independent of ``jobs`` and
        ``executor``; the trials of a chunk are identified together, so the last digits of
        the batched maximum likelihood, about 1e-11 mm, depend on it).
    progress : callable(done, total), optional
        Called as chunks complete, in units of ``weight`` per trial (default: the lines of
        :mod:`hexcal.core.progress`, when a caller turned them on).
    weight : int
        Work units per trial for ``progress`` (e.g. identifications per trial).

    Returns
    -------
    dict of name to ndarray
        Each chunk's arrays concatenated in trial order (first axis ``trials``).

    Examples
    --------
    >>> def squares(offset, idx):
    ...     return {"value": idx**2 + offset}
    >>> map_trials(squares, 1, 5, chunk_size=2)["value"].tolist()
    [1, 2, 5, 10, 17]
    """
    if progress is None:  # the library's progress lines (hexcal.core.progress), when turned on
        with task("trials", trials * weight) as step:
            seen = [0]

            def tick(done: int, total: int) -> None:
                step(done - seen[0])
                seen[0] = done

            return map_trials(fn, definition, trials, jobs=jobs, executor=executor, chunk_size=chunk_size,
                              progress=tick, weight=weight)  # fmt: skip
    n_jobs = resolve_jobs(jobs)
    chunks = chunk_indices(trials, chunk_size=chunk_size)  # the same wherever they run
    if executor is not None:
        return _collect(executor, fn, definition, chunks, trials, progress, weight)
    if n_jobs == 1 or len(chunks) == 1:
        return _collect(SerialExecutor(), fn, definition, chunks, trials, progress, weight)
    pool = ProcessPoolExecutor(
        max_workers=min(n_jobs, len(chunks)), initializer=worker_signals, initargs=(os.getpid(),)
    )
    try:
        out = _collect(pool, fn, definition, chunks, trials, progress, weight)
    except BaseException as exc:  # errors and KeyboardInterrupt: drop the queued chunks at once
        if isinstance(exc, KeyboardInterrupt):
            # else the workers would still finish the chunks already handed to them
            workers = getattr(pool, "_processes", None) or {}
            for process in list(workers.values()):
                process.terminate()
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown()
    return out


def _collect(
    executor: Executor,
    fn: ChunkFunction,
    definition: Any,
    chunks: list[NDArray[np.intp]],
    trials: int,
    progress: Progress | None,
    weight: int,
) -> dict[str, NDArray[Any]]:
    """Submit every chunk, wait for them as they complete, reassemble by trial index."""
    futures: dict[Future[Any], int] = {}
    for k, idx in enumerate(chunks):
        futures[executor.submit(fn, definition, idx)] = k
    results: list[Mapping[str, NDArray[Any]] | None] = [None] * len(chunks)
    pending, done = set(futures), 0
    try:
        while pending:
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in finished:
                k = futures[future]
                results[k] = future.result()
                done += len(chunks[k])
                if progress:
                    progress(done * weight, trials * weight)
    except BaseException:
        for future in pending:
            future.cancel()
        raise
    if not results:
        return {}
    return {name: np.concatenate([r[name] for r in results if r is not None]) for name in results[0] or {}}
