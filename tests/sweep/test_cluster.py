"""Reaching an existing Dask scheduler (fatigue_pin.sweep.cluster): a malformed address, a port
that accepts TCP but never answers, an HTTP server, another protocol's banner, a closed port:
one line each, every wait bounded. Servers listen on 127.0.0.1 only."""

from __future__ import annotations

import contextlib
import http.server
import socket
import threading
import time

import pytest

from conftest import small_curl
from fatigue_pin.cli.main import main
from fatigue_pin.sweep import cluster
from fatigue_pin.sweep.cluster import check_scheduler, scheduler_address
from fatigue_pin.sweep.plan import SweepError

TIMEOUT = 1.0  # s, each wait of the probe in these tests


@contextlib.contextmanager
def _server(mode: str):
    """A TCP server on 127.0.0.1 that, to every connection: ``silent`` says nothing and keeps it
    open, ``banner`` sends an SSH banner, ``close`` closes it at once."""
    listener = socket.create_server(("127.0.0.1", 0))
    listener.settimeout(0.2)
    held: list[socket.socket] = []
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            try:
                conn, _ = listener.accept()
            except (socket.timeout, OSError):
                continue
            if mode == "banner":
                conn.sendall(b"SSH-2.0-OpenSSH_9.2p1\r\n")
            if mode == "close":
                conn.close()
            else:
                held.append(conn)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{listener.getsockname()[1]}"
    finally:
        stop.set()
        thread.join(2)
        for conn in held:
            conn.close()
        listener.close()


@contextlib.contextmanager
def _http_server():
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


@pytest.mark.parametrize("address", ["", "127.0.0.1", "tcp://127.0.0.1", "http://127.0.0.1:8786", "tcp://127.0.0.1:0",
                                     "tcp://127.0.0.1:99999", "tcp://127.0.0.1:port", "tcp://:8786", "tcp://a b:1",
                                     "tcp://127.0.0.1:8786/x", "tcp://[::1]8786", "::1:8786"])
def test_malformed_addresses(address):
    with pytest.raises(SweepError, match=r"--scheduler .*: expected tcp://HOST:PORT") as err:
        scheduler_address(address)
    assert "\n" not in str(err.value)


def test_well_formed_addresses():
    assert scheduler_address("tcp://127.0.0.1:8786") == ("tcp", "127.0.0.1", 8786)
    assert scheduler_address("localhost:1") == ("tcp", "localhost", 1)
    assert scheduler_address("tls://[::1]:65535") == ("tls", "::1", 65535)


@pytest.mark.parametrize("mode, message", [
    ("silent", r"accepted the connection but sent nothing within 1 s"),
    ("banner", r"answered 'SSH-2.0-OpenSSH_9.2p1', another protocol"),
    ("close", r"closed the connection without a word"),
])
def test_servers_that_are_not_dask(mode, message):
    with _server(mode) as address:
        t0 = time.monotonic()
        with pytest.raises(SweepError, match=message):
            check_scheduler(address, TIMEOUT)
        assert time.monotonic() - t0 < 5 * TIMEOUT


def test_an_http_server_is_not_a_scheduler():
    with _http_server() as address:
        t0 = time.monotonic()
        with pytest.raises(SweepError, match=r"sent nothing within 1 s"):
            check_scheduler(address, TIMEOUT)
        assert time.monotonic() - t0 < 5 * TIMEOUT


def test_a_closed_port():
    with socket.create_server(("127.0.0.1", 0)) as s:
        port = s.getsockname()[1]
    with pytest.raises(SweepError, match=r"cannot be reached \(Connection refused\)"):
        check_scheduler(f"127.0.0.1:{port}", TIMEOUT)


def test_a_real_scheduler_answers():
    from distributed import LocalCluster

    with LocalCluster(n_workers=0, processes=False, protocol="tcp://", host="127.0.0.1", dashboard_address=None) as c:
        assert check_scheduler(c.scheduler_address, 5.0) == c.scheduler_address
        assert check_scheduler(c.scheduler_address.removeprefix("tcp://"), 5.0) == c.scheduler_address


def test_sweep_command_line_is_one_line_and_bounded(tmp_path, capsys, monkeypatch):
    """``fatigue-pin sweep --scheduler`` at a silent port, an HTTP server or a malformed address:
    exit 2, one line, nothing written, within a few timeouts."""
    monkeypatch.setattr(cluster, "SCHEDULER_TIMEOUT_S", TIMEOUT)
    (tmp_path / "base.toml").write_text(small_curl("full").to_toml())
    sweep = tmp_path / "sweep.toml"
    sweep.write_text('base = "base.toml"\n[grid]\n"fatigue.S" = [0.0, 10.0]\n')
    with _server("silent") as silent, _http_server() as web:
        for address, message in ((silent, "sent nothing within 1 s"), (web, "sent nothing within 1 s"),
                                 ("tcp://127.0.0.1:http", "expected tcp://HOST:PORT")):
            t0 = time.monotonic()
            code = main(["sweep", str(sweep), "--out", str(tmp_path / "out"), "--scheduler", address])
            err = capsys.readouterr().err
            assert code == 2 and err.count("\n") == 1 and message in err, err
            assert time.monotonic() - t0 < 5 * TIMEOUT + 5
    assert not list(tmp_path.glob("out/*.h5"))
