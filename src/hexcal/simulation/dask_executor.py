"""Run the chunks of trials on the workers of a Dask cluster (``pip install hexcal[dask]``).

:func:`dask_executor` connects to a running Dask scheduler (``dask scheduler`` and
``dask worker``, or any cluster manager) and yields a :class:`DaskExecutor`, an executor
for :func:`hexcal.simulation.runner.map_trials`. Every chunk is one task, a pure function
of (definition, trial indices): the trial seeds fix its numbers wherever it runs, and the
runner reassembles the chunks by trial index, so a study gives the same numbers locally,
with any ``--jobs`` and on any cluster. When a worker dies in the middle of a run, the
scheduler recomputes its lost tasks on the other workers (it costs time, not results).

Whatever is at ``--scheduler ADDRESS``, the connection ends within :data:`CONNECT_TIMEOUT`
seconds, successfully or with one line (:func:`connect`): the address must be
``tcp://HOST:PORT`` (or ``tls://``, or ``HOST:PORT``); before any Dask code touches it,
:func:`probe` connects with plain sockets and checks that the server greets first, as a Dask
scheduler does, with a frame of Dask's size (a silent socket, an HTTP server such as the
dashboard on port 8787, an SSH banner or garbage fail here, never allocating what a garbage
length asks for); the client then gets what is left of the same deadline for its whole start
(connection, handshake, registration), and is closed at once if it fails.

``distributed`` is imported inside the functions only: this module imports without it.
"""

from __future__ import annotations

import contextlib
import itertools
import socket
import struct
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from concurrent.futures import Future
from contextlib import contextmanager
from typing import Any

from hexcal.errors import UsageError

#: Seconds to wait for the scheduler before giving up: the whole connection, whatever is at
#: the address (read when :func:`connect` is called).
CONNECT_TIMEOUT = 3.0
#: Address schemes accepted by ``--scheduler`` (``inproc://`` exists only inside one process).
SCHEMES = ("tcp", "tls")
#: Largest greeting accepted from a scheduler, bytes (a Dask greeting is a few hundred bytes;
#: a garbage length is refused rather than allocated).
MAX_GREETING_BYTES = 1 << 20
#: Most frames of a greeting (Dask sends one or two).
MAX_GREETING_FRAMES = 64
#: Dask's frame lengths: unsigned 64-bit integers in the machine's byte order.
_LENGTH = struct.Struct("Q")
#: The usual port of a Dask scheduler, and of its dashboard (an HTTP server).
DASK_PORT, DASHBOARD_PORT = 8786, 8787
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
def dask_executor(address: str, timeout: float | None = None) -> Iterator[DaskExecutor]:
    """Connect to the Dask scheduler at ``address`` and yield an executor on its workers.

    Pending tasks are cancelled and the client closed on leaving (also on errors and
    Ctrl-C). The workers must have hexcal installed (the same version).

    Parameters
    ----------
    address : str
        The scheduler, e.g. ``tcp://127.0.0.1:8786``.
    timeout : float, optional
        Seconds for the whole connection (default :data:`CONNECT_TIMEOUT`).

    Raises
    ------
    UsageError
        ``distributed`` is not installed, the address is not a scheduler's, or no Dask
        scheduler answers there within ``timeout`` (one line naming the address).
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


def parse_address(address: str) -> tuple[str, str, int]:
    """``(scheme, host, port)`` of a ``--scheduler`` address, or one :class:`UsageError` line.

    >>> parse_address("tcp://127.0.0.1:8786")
    ('tcp', '127.0.0.1', 8786)
    >>> parse_address("[::1]:8786")
    ('tcp', '::1', 8786)
    >>> parse_address("inproc://10.0.0.1/1234/1")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    hexcal.errors.UsageError: --scheduler 'inproc://10.0.0.1/1234/1': an inproc:// address ...
    """
    scheme, sep, rest = address.strip().partition("://")
    scheme, rest = (scheme.lower(), rest) if sep else ("tcp", scheme)
    usage = (
        f"give the scheduler's tcp://HOST:PORT (usually port {DASK_PORT}), e.g. tcp://127.0.0.1:{DASK_PORT}"
    )
    if scheme == "inproc":
        raise UsageError(
            f"--scheduler {address!r}: an inproc:// address reaches a scheduler only from inside its "
            f"own Python process; {usage}"
        )
    if scheme not in SCHEMES:
        raise UsageError(f"--scheduler {address!r}: unknown scheme {scheme!r}; {usage}")
    if rest.startswith("["):  # an IPv6 address: [::1]:8786
        host, _, port = rest[1:].partition("]")
        port = port.removeprefix(":") if port.startswith(":") else ""
    else:
        host, _, port = rest.rpartition(":")
    if (
        not host
        or any(c.isspace() or c in "/[]@" for c in host)
        or not (port.isdigit() and 0 < int(port) < 65536)
    ):
        raise UsageError(f"--scheduler {address!r}: not a scheduler address; {usage}")
    return scheme, host, int(port)


def _fail(address: str, reason: str, timeout: float) -> UsageError:
    return UsageError(f"cannot connect to the Dask scheduler at {address!r} within {timeout:g} s: {reason}")


def _resolve(host: str, port: int, wait: float) -> list[Any]:
    """``getaddrinfo`` within ``wait`` seconds (a daemon thread: a stuck resolver is left)."""
    found: dict[str, Any] = {}

    def run() -> None:
        try:
            found["infos"] = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
        except (OSError, UnicodeError) as exc:
            found["error"] = exc

    thread = threading.Thread(target=run, name="hexcal-resolve", daemon=True)
    thread.start()
    thread.join(max(wait, 0.0))
    if "infos" in found:
        return list(found["infos"])
    if "error" in found:
        raise OSError(f"cannot resolve {host!r} ({found['error']})")
    raise TimeoutError(f"{host!r} was not resolved in time")


def _receive(sock: socket.socket, size: int, deadline: float) -> bytes:
    data = b""
    while len(data) < size:
        sock.settimeout(max(deadline - time.monotonic(), 0.001))
        chunk = sock.recv(min(size - len(data), 65536))
        if not chunk:
            raise ConnectionResetError("closed")
        data += chunk
    return data


def probe(address: str, deadline: float, timeout: float) -> None:
    """Check with plain sockets, by ``deadline`` (``time.monotonic``), that a Dask scheduler
    answers at ``address``: it accepts the connection and greets first, with a frame of
    Dask's form (a length, then at most :data:`MAX_GREETING_FRAMES` frame lengths) no larger
    than :data:`MAX_GREETING_BYTES`. One :class:`UsageError` line otherwise."""
    scheme, host, port = parse_address(address)
    dashboard = ""
    if port == DASHBOARD_PORT:
        dashboard = (
            f" (port {port} is Dask's dashboard, an HTTP server; the scheduler's is usually {DASK_PORT})"
        )
    try:
        infos = _resolve(host, port, deadline - time.monotonic())
        sock = None
        error: OSError = ConnectionRefusedError("no address")
        for family, kind, proto, _, where in infos:
            sock = socket.socket(family, kind, proto)
            try:
                sock.settimeout(max(deadline - time.monotonic(), 0.001))
                sock.connect(where)
                break
            except OSError as exc:
                sock.close()
                sock, error = None, exc
        if sock is None:
            raise error
    except TimeoutError as exc:
        raise _fail(address, f"no answer ({exc})", timeout) from None
    except OSError as exc:
        raise _fail(address, f"{exc.strerror or exc}{dashboard}", timeout) from None
    if scheme == "tls":  # the greeting is encrypted: the client checks the rest
        sock.close()
        return
    try:
        (size,) = _LENGTH.unpack(_receive(sock, _LENGTH.size, deadline))
        body = _receive(sock, size, deadline) if 2 * _LENGTH.size <= size <= MAX_GREETING_BYTES else b""
        frames = _LENGTH.unpack_from(body)[0] if body else 0
        if not (1 <= frames <= MAX_GREETING_FRAMES and _LENGTH.size * (1 + frames) <= size):
            raise _fail(address, f"the server does not speak Dask's protocol{dashboard}", timeout)
    except TimeoutError:
        raise _fail(
            address,
            "the server accepted the connection but sent nothing Dask would; a Dask scheduler greets at "
            f"once (an HTTP server waits for a request){dashboard}",
            timeout,
        ) from None
    except OSError:
        raise _fail(
            address, f"the server closed the connection without a Dask greeting{dashboard}", timeout
        ) from None
    finally:
        sock.close()


def bounded_client(address: str, timeout: float) -> Any:
    """A :class:`distributed.Client` whose whole start ends within ``timeout`` seconds.

    ``Client(timeout=...)`` bounds the TCP connection but not the handshake that follows (a
    server that accepts and never speaks kept it waiting for minutes); here the start is
    bounded too, and a client that fails to start is closed at once (otherwise its
    ``__del__`` printed a traceback after the error line, 6 s later).
    """
    from distributed import Client

    class BoundedClient(Client):  # type: ignore[misc]
        def __init__(self, where: str, seconds: float) -> None:
            self.hexcal_start_timeout = seconds
            super().__init__(where, timeout=seconds, set_as_default=False)

        def start(self, **kwargs: Any) -> None:
            try:  # Client.start hands callback_timeout to distributed.utils.sync
                super().start(callback_timeout=self.hexcal_start_timeout, **kwargs)
            except BaseException:
                with contextlib.suppress(Exception):
                    self.close(timeout=1)
                raise

    return BoundedClient(address, timeout)


def connect(address: str, timeout: float | None = None) -> Any:
    """A :class:`distributed.Client` of the scheduler at ``address``, or one clear error.

    The address is checked (:func:`parse_address`), the server probed (:func:`probe`), and
    the client started (:func:`bounded_client`), all within ``timeout`` seconds (default
    :data:`CONNECT_TIMEOUT`) together. Any failure is one :class:`UsageError` line.

    Examples
    --------
    >>> connect("no-such-protocol://x", timeout=0.5)  # doctest: +IGNORE_EXCEPTION_DETAIL
    Traceback (most recent call last):
    hexcal.errors.UsageError: ...
    """
    timeout = CONNECT_TIMEOUT if timeout is None else float(timeout)
    deadline = time.monotonic() + timeout
    parse_address(address)
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise UsageError(f"--scheduler needs dask.distributed: {INSTALL_HINT}") from None
    probe(address, deadline, timeout)
    import logging

    # a failed connection logs tracebacks (of its retries, of a message it cannot decode, at
    # levels up to CRITICAL, some on the client's own thread): the error below says it all
    disabled = logging.root.manager.disable
    logging.disable(logging.CRITICAL)
    detail = None
    try:
        return bounded_client(address, max(deadline - time.monotonic(), 0.05))
    except Exception as exc:  # whatever a misbehaving server makes distributed raise
        name = type(exc).__name__
        detail = (str(exc).splitlines() or [""])[0][:120]
        detail = name if detail in ("", name) else f"{name}: {detail}"
    finally:
        if detail is not None:  # the failed connection's objects go now, their last logs unheard
            import gc

            gc.collect()
        logging.disable(disabled)
    raise _fail(address, f"the server does not complete Dask's handshake ({detail})", timeout)
