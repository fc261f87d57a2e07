"""Issue 22, ``--scheduler``: whatever is at the address, one line within the connection
timeout, never a ``distributed`` traceback, a hang or an out-of-memory.

Every server here is a local socket started by the test (no network); the timeout is cut to
0.5 s (``dask_executor.CONNECT_TIMEOUT``) so that the silent ones cost half a second each.
"""

from __future__ import annotations

import http.server
import json
import os
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

pytest.importorskip("distributed", reason="the --scheduler tests need dask.distributed")

from hexcal.cli import main
from hexcal.errors import UsageError
from hexcal.simulation import dask_executor

SRC = Path(__file__).resolve().parents[1] / "src"
TIMEOUT = 0.5
STUDY = ["study", "selection", "--trials", "2", "--poses", "8", "--quiet"]

Q = struct.Struct("Q")  # Dask's frame lengths


def _silent(conn: socket.socket) -> None:
    conn.recv(1 << 16)  # reads what the client says, answers nothing, keeps the connection


def _close(conn: socket.socket) -> None:
    conn.close()


def _banner(conn: socket.socket) -> None:
    conn.sendall(b"SSH-2.0-OpenSSH_9.6\r\n")
    conn.recv(1 << 16)


def _huge_length(conn: socket.socket) -> None:
    conn.sendall(b"\xff" * 8 + b"garbage" * 10)  # a frame of 1.8e19 bytes
    conn.recv(1 << 16)


def _absurd_frame_count(conn: socket.socket) -> None:
    conn.sendall(Q.pack(16) + Q.pack(10**12) + Q.pack(0))  # struct.error in distributed
    conn.recv(1 << 16)


def _framed_garbage(conn: socket.socket) -> None:
    """Dask's framing, but a message that is not msgpack: passes the probe, fails the client."""
    conn.sendall(Q.pack(24) + Q.pack(1) + Q.pack(8) + b"\xc1" * 8)
    conn.recv(1 << 16)


def _trickle(conn: socket.socket) -> None:
    """One byte of a plausible length, then nothing: a read that never completes."""
    conn.sendall(b"\x18")
    conn.recv(1 << 16)


@pytest.fixture
def serve() -> Iterator[Callable[[Callable[[socket.socket], None]], str]]:
    """Start a local TCP server answering each connection with ``handler``; yields its address."""
    servers: list[socket.socket] = []
    conns: list[socket.socket] = []

    def start(handler: Callable[[socket.socket], None]) -> str:
        server = socket.create_server(("127.0.0.1", 0))
        servers.append(server)

        def accept() -> None:
            while True:
                try:
                    conn, _ = server.accept()
                except OSError:
                    return
                conns.append(conn)
                threading.Thread(target=_quietly, args=(handler, conn), daemon=True).start()

        threading.Thread(target=accept, daemon=True).start()
        return f"tcp://127.0.0.1:{server.getsockname()[1]}"

    yield start
    for sock in servers + conns:
        sock.close()


def _quietly(handler: Callable[[socket.socket], None], conn: socket.socket) -> None:
    try:
        handler(conn)
    except OSError:
        pass


@pytest.fixture
def http_server() -> Iterator[str]:
    """A real HTTP server (what Dask's dashboard is) on a free local port."""
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
    threading.Thread(target=httpd.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True).start()
    yield f"tcp://127.0.0.1:{httpd.server_address[1]}"
    httpd.shutdown()
    httpd.server_close()


def _refused_port() -> str:
    sock = socket.create_server(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    sock.close()
    return f"tcp://127.0.0.1:{port}"


def _one_line(capsys, tmp_path, monkeypatch, address: str) -> tuple[str, float]:
    monkeypatch.setattr(dask_executor, "CONNECT_TIMEOUT", TIMEOUT)
    start = time.monotonic()
    status = main([*STUDY, "--scheduler", address, "--out", str(tmp_path / "res")])
    took = time.monotonic() - start
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert status == 1 and out == "" and len(lines) == 1, err
    assert lines[0].startswith("hexcal: error: ") and "Traceback" not in err and "out of memory" not in err
    assert not (tmp_path / "res").exists()
    return lines[0], took


@pytest.mark.parametrize(
    ("address", "words"),
    [
        ("garbage", "not a scheduler address"),
        ("tcp://", "not a scheduler address"),
        ("tcp://127.0.0.1:port", "not a scheduler address"),
        ("tcp://127.0.0.1:70000", "not a scheduler address"),
        ("tcp://a b:8786", "not a scheduler address"),
        ("inproc://10.0.0.1/1234/1", "an inproc:// address reaches a scheduler only from inside"),
        ("ucx://127.0.0.1:8786", "unknown scheme 'ucx'"),
    ],
)
def test_an_address_that_is_not_a_schedulers_is_one_line(capsys, tmp_path, monkeypatch, address, words):
    line, _ = _one_line(capsys, tmp_path, monkeypatch, address)
    assert line.startswith(f"hexcal: error: --scheduler {address!r}: {words}"), line


@pytest.mark.parametrize(
    ("handler", "words"),
    [
        (_silent, "accepted the connection but sent nothing"),
        (_close, "closed the connection without a Dask greeting"),
        (_banner, "does not speak Dask's protocol"),
        (_huge_length, "does not speak Dask's protocol"),
        (_absurd_frame_count, "does not speak Dask's protocol"),
        (_framed_garbage, "the server does not complete Dask's handshake"),
        (_trickle, "accepted the connection but sent nothing"),
    ],
    ids=lambda v: getattr(v, "__name__", "")[1:] if callable(v) else "",
)
def test_a_server_that_is_not_a_scheduler_is_one_line(capsys, tmp_path, monkeypatch, serve, handler, words):
    address = serve(handler)
    line, _ = _one_line(capsys, tmp_path, monkeypatch, address)
    assert line.startswith(f"hexcal: error: cannot connect to the Dask scheduler at {address!r} within 0.5 s")
    assert words in line


def test_an_http_server_such_as_the_dashboard_is_one_line(capsys, tmp_path, monkeypatch, http_server):
    line, _ = _one_line(capsys, tmp_path, monkeypatch, http_server)
    assert "sent nothing Dask would" in line and "an HTTP server waits for a request" in line


def test_nothing_listening_is_one_line_at_once(capsys, tmp_path, monkeypatch):
    address = _refused_port()
    line, _ = _one_line(capsys, tmp_path, monkeypatch, address)
    assert f"at {address!r}" in line and "refused" in line


def test_the_dashboard_port_is_named(capsys, tmp_path, monkeypatch):
    try:
        probe = socket.create_server(("127.0.0.1", 8787))
    except OSError:
        pytest.skip("port 8787 is in use here")
    probe.close()  # nothing listens there now: refused, with the hint
    line, _ = _one_line(capsys, tmp_path, monkeypatch, "tcp://127.0.0.1:8787")
    assert "port 8787 is Dask's dashboard" in line and "usually 8786" in line


def test_the_client_start_is_bounded_even_past_the_probe(serve):
    """A server that accepts and never speaks held distributed's handshake for minutes: the
    client's whole start is bounded by its timeout, and the failed client is closed."""
    address = serve(_silent)
    with pytest.raises(Exception) as info:
        dask_executor.bounded_client(address, 0.3)
    assert "timed out" in str(info.value).lower() or isinstance(info.value, TimeoutError)
    with pytest.raises(UsageError, match="sent nothing"):
        dask_executor.connect(address, timeout=0.3)


#: A script run in a fresh interpreter: each bad address through ``main``, then a normal exit;
#: a failed client's ``__del__`` would print its traceback there, after the error lines.
SCRIPT = r"""
import contextlib, io, json, socket, struct, sys, threading, time
import distributed  # its log handlers write to this process's stderr, not to a redirection
from hexcal.cli import main
from hexcal.simulation import dask_executor
dask_executor.CONNECT_TIMEOUT = 0.5

def server(reply):
    s = socket.create_server(("127.0.0.1", 0))
    def run():
        while True:
            c, _ = s.accept()
            with contextlib.suppress(OSError):
                if reply is not None:
                    c.sendall(reply)
                c.recv(65536)
    threading.Thread(target=run, daemon=True).start()
    return f"tcp://127.0.0.1:{s.getsockname()[1]}"

Q = struct.Struct("Q")
addresses = [server(None), server(b"\xff" * 16), server(Q.pack(24) + Q.pack(1) + Q.pack(8) + b"\xc1" * 8),
             "inproc://x", "garbage"]
results = []
for address in addresses:
    err = io.StringIO()
    start = time.monotonic()
    with contextlib.redirect_stderr(err):
        status = main(["study", "selection", "--trials", "2", "--poses", "8", "--quiet",
                       "--scheduler", address])
    results.append({"status": status, "err": err.getvalue(), "seconds": time.monotonic() - start})
print(json.dumps(results))
"""


def test_a_failed_connection_leaves_no_traceback_at_exit(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0 and done.stderr == "", done.stderr
    results = json.loads(done.stdout)
    for result in results:
        assert result["status"] == 1 and len(result["err"].splitlines()) == 1, result
        assert result["err"].startswith("hexcal: error: ")
