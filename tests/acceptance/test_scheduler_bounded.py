"""``--scheduler`` bounded (issue 27): an address where no Dask scheduler answers fails within 30 s
with one clear line — an HTTP server (``python -m http.server``, which says nothing on a new
connection: this used to hang for ever) and a proxy that answers "HTTP/1.1 400" at once (whose
bytes Dask read as a message length: "MemoryError: Unable to allocate 3.07 EiB"). Real
subprocesses; the servers on free local ports."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
import time

import pytest

LIMIT_S = 30.0
ENV = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _boresight(corpus, out, address):
    s = corpus.root / "survey"
    return [sys.executable, "-m", "calidar", "boresight", *map(str, sorted((s / "strips").glob("*.laz"))[:2]),
            "--trajectory", str(s / "sbet.out"), "--sensor", str(s / "sensor.toml"), "--method", "vgicp",
            "--scheduler", address, "--out", str(out)]


def _check(corpus, tmp_path, address, *words):
    t0 = time.monotonic()
    r = subprocess.run(_boresight(corpus, tmp_path / "out", address), capture_output=True, text=True, env=ENV,
                       timeout=120)
    took = time.monotonic() - t0
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 1, r.stderr
    assert took < LIMIT_S, f"{took:.1f} s"
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in r.stderr, r.stderr
    for w in (address, *words):
        assert w in lines[0], lines[0]
    assert list(tmp_path.iterdir()) == []


def test_http_server_is_not_a_scheduler(corpus, tmp_path):
    port = _free_port()
    server = subprocess.Popen([sys.executable, "-m", "http.server", str(port), "--bind", "127.0.0.1"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=tmp_path)
    try:
        deadline = time.monotonic() + 20
        while True:  # wait until it listens
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                assert time.monotonic() < deadline and server.poll() is None
                time.sleep(0.05)
        _check(corpus, tmp_path, f"tcp://127.0.0.1:{port}", "no answer", "as a Dask scheduler would give")
    finally:
        server.terminate()
        server.wait(timeout=10)


@pytest.fixture
def proxy_400():
    """A TCP server answering every connection with "HTTP/1.1 400 Bad Request" at once."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    stop = threading.Event()

    def serve():
        srv.settimeout(0.2)
        while not stop.is_set():
            try:
                conn, _ = srv.accept()
            except OSError:
                continue
            with conn:
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\nConnection: close\r\n\r\n")

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    yield f"tcp://127.0.0.1:{srv.getsockname()[1]}"
    stop.set()
    t.join(timeout=5)
    srv.close()


def test_proxy_answering_400_is_not_a_scheduler(corpus, tmp_path, proxy_400):
    _check(corpus, tmp_path, proxy_400, "not a Dask scheduler", "HTTP/1.1")


def test_closed_port(corpus, tmp_path):
    _check(corpus, tmp_path, f"tcp://127.0.0.1:{_free_port()}", "cannot reach", "Connection refused")
