"""Run the chunks of trials on the workers of a Dask cluster (``pip install hexcal[dask]``).

:func:`dask_executor` connects to a running Dask scheduler (``dask scheduler`` and
``dask worker``, or any cluster manager) and yields a :class:`DaskExecutor`, an executor
for :func:`hexcal.simulation.runner.map_trials`. Every chunk is one task, a pure function
of (definition, trial indices): the trial seeds fix its numbers wherever it runs, and the
runner reassembles the chunks by trial index, so a study gives the same numbers locally,
with any ``--jobs`` and on any cluster. When a worker dies in the middle of a run, the
scheduler recomputes its lost tasks on the other workers (it costs time, not results).

``distributed`` is imported inside the functions only: this module imports without it.
"""

from __future__ import annotations

import itertools
import uuid
from collections.abc import Callable, Iterator
from concurrent.futures import Future
from contextlib import contextmanager
from typing import Any

from hexcal.errors import UsageError

#: Seconds to wait for the scheduler before giving up.
CONNECT_TIMEOUT = 3.0
#: Hint printed when ``distributed`` is missing.
INSTALL_HINT = "pip install hexcal[dask]"


class DaskExecutor:
    """An executor whose ``submit`` runs a call as a task of a Dask cluster.

    It returns :class:`concurrent.futures.Future` objects (completed from the Dask
    futures' callbacks), so the runner waits on them as on a local process pool, and it
    keeps the Dask futures alive until they complete (a released future is cancelled).

    Parameters
    ----------
    client : distributed.Client
        A connected client.
    """

    def __init__(self, client: Any) -> None:
        self.client = client
        self._run = uuid.uuid4().hex[:12]
        self._count = itertools.count()
        self._alive: dict[str, Any] = {}

    @property
    def workers(self) -> int:
        """Worker threads of the cluster now (at least 1)."""
        try:
            return max(1, sum(self.client.nthreads().values()))
        except Exception:  # scheduler gone: the submits will say so
            return 1

    def submit(self, fn: Callable[..., Any], /, *args: Any) -> Future[Any]:
        key = f"hexcal-{getattr(fn, '__name__', 'task')}-{self._run}-{next(self._count)}"
        # pure=False with an explicit key: no hashing of the (large) arguments; the
        # task is nevertheless deterministic, so a recomputation gives the same result
        task = self.client.submit(fn, *args, key=key, pure=False, retries=0)
        self._alive[key] = task
        future: Future[Any] = Future()
        future.set_running_or_notify_cancel()

        def done(task: Any) -> None:
            self._alive.pop(key, None)
            if future.done():
                return
            try:
                future.set_result(task.result())
            except BaseException as exc:  # a failed or cancelled task
                future.set_exception(exc if isinstance(exc, Exception) else RuntimeError(str(exc)))

        task.add_done_callback(done)
        return future

    def cancel(self) -> None:
        """Cancel every task still pending."""
        alive, self._alive = list(self._alive.values()), {}
        if alive:
            try:
                self.client.cancel(alive)
            except Exception:  # the scheduler is gone: nothing to cancel
                pass


@contextmanager
def dask_executor(address: str, timeout: float = CONNECT_TIMEOUT) -> Iterator[DaskExecutor]:
    """Connect to the Dask scheduler at ``address`` and yield an executor on its workers.

    Pending tasks are cancelled and the client closed on leaving (also on errors and
    Ctrl-C). The workers must have hexcal installed (the same version).

    Parameters
    ----------
    address : str
        The scheduler, e.g. ``tcp://127.0.0.1:8786``.
    timeout : float
        Seconds to wait for the connection.

    Raises
    ------
    UsageError
        ``distributed`` is not installed, or the scheduler does not answer within
        ``timeout`` (one line naming the address).
    """
    client = connect(address, timeout)
    executor = DaskExecutor(client)
    try:
        yield executor
    finally:
        executor.cancel()
        try:
            client.close(timeout=2)
        except Exception:  # closing a client of a vanished scheduler
            pass


def connect(address: str, timeout: float = CONNECT_TIMEOUT) -> Any:
    """A :class:`distributed.Client` of the scheduler at ``address``, or one clear error.

    Examples
    --------
    >>> connect("no-such-protocol://x", timeout=0.5)  # doctest: +IGNORE_EXCEPTION_DETAIL
    Traceback (most recent call last):
    hexcal.errors.UsageError: ...
    """
    try:
        from distributed import Client
    except ImportError:
        raise UsageError(f"--scheduler needs dask.distributed: {INSTALL_HINT}") from None
    import logging

    # a failed connection logs tracebacks of its retries: the error below says it all
    log = logging.getLogger("distributed")
    level = log.level
    log.setLevel(logging.CRITICAL)
    try:
        return Client(address, timeout=timeout, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise UsageError(
            f"cannot connect to the Dask scheduler at {address!r} within {timeout:g} s ({reason[:120]})"
        ) from None
    finally:
        log.setLevel(level)
