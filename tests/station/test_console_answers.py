"""The console always answers its operator: idle or trickling connections cannot fill
it, and status, jobs, pause and abort answer from memory while the job store is away."""

from __future__ import annotations

import socket
import threading
import time

import pytest

import station.control
from station.config import load_config
from station.control import request
from station.daemon import Daemon, wait_until
from tests.station.test_daemon import TickingPipeline


@pytest.fixture
def lone_station(tmp_path):
    config = load_config(None, {
        "store": {"path": str(tmp_path / "jobs.db"), "work_dir": str(tmp_path / "work")},
        "control": {"socket": str(tmp_path / "station.sock")}})
    daemon = Daemon(config, TickingPipeline())
    daemon.control.start()
    yield daemon, tmp_path / "station.sock"
    daemon.control.stop()
    daemon.store.close()
    daemon.lock.release()


def connect(path) -> socket.socket:
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.connect(str(path))
    return s


def trickle(path, stop: threading.Event) -> None:
    """One byte every 0.2 s, never a whole line; reconnects when closed."""
    s = connect(path)
    while not stop.wait(0.2):
        try:
            s.send(b" ")
        except OSError:
            s.close()
            s = connect(path)
    s.close()


def test_idle_and_trickling_connections_never_stop_jobs_answering(lone_station):
    _daemon, sock = lone_station
    idle = [connect(sock) for _ in range(32)]
    stop = threading.Event()
    tricklers = [threading.Thread(target=trickle, args=(sock, stop)) for _ in range(4)]
    for t in tricklers:
        t.start()
    try:
        time.sleep(0.3)
        for _ in range(5):
            t0 = time.monotonic()
            assert request(sock, "jobs", timeout=1.0)["jobs"] == []
            assert time.monotonic() - t0 < 1.0
    finally:
        stop.set()
        for t in tricklers:
            t.join()
        for s in idle:
            s.close()


def test_a_silent_or_trickling_connection_is_closed_within_seconds(lone_station,
                                                                    monkeypatch):
    _daemon, sock = lone_station
    monkeypatch.setattr(station.control, "IDLE_SECONDS", 0.5)
    silent, trickler = connect(sock), connect(sock)
    silent.settimeout(3.0)
    t0 = time.monotonic()
    while time.monotonic() - t0 < 2.0:
        try:
            trickler.send(b"{")
        except OSError:
            break  # closed by the daemon
        time.sleep(0.1)
    assert silent.recv(100) == b""  # closed, having said nothing
    assert time.monotonic() - t0 < 2.0
    trickler.settimeout(1.0)
    try:
        said = trickler.recv(100)
    except ConnectionResetError:  # closed with our bytes unread: the kernel resets it
        said = b""
    assert said == b""  # closed, having said nothing
    silent.close()
    trickler.close()


def test_the_console_answers_from_memory_while_the_store_is_away(postgres, pg_url, tmp_path):
    config = load_config(None, {
        "store": {"url": pg_url, "work_dir": str(tmp_path / "work")},
        "control": {"socket": str(tmp_path / "station.sock")},
        "station": {"name": "cutter-1", "outage_s": 60.0}})
    sock = tmp_path / "station.sock"
    daemon = Daemon(config, TickingPipeline(tick=0.3))
    daemon.recover()
    daemon.control.start()
    worker = threading.Thread(target=daemon.run_loop, daemon=True)
    worker.start()
    try:
        garment = tmp_path / "shirt.obj"
        garment.write_text("# stand-in\n")
        job = request(sock, "submit", garment=str(garment), fabric=str(garment))["job"]["id"]
        assert wait_until(lambda: request(sock, "status", job=job)["job"]["state"] ==
                          "cutting", 10)
        assert request(sock, "jobs")["jobs"][0]["id"] == job
        postgres.stop("immediate")
        time.sleep(0.5)  # the worker's next piece write is now waiting for the server
        answers = {}
        for cmd in ("status", "jobs", "pause", "abort"):
            t0 = time.monotonic()
            answers[cmd] = request(sock, cmd, timeout=1.0)
            assert time.monotonic() - t0 < 1.0, cmd
        assert answers["status"]["job"]["id"] == job
        assert [j["id"] for j in answers["jobs"]["jobs"]] == [job]
        assert answers["pause"]["message"].startswith("paused (feed hold)")
        assert answers["abort"]["message"] == "aborting (safe stop)"
        assert all(answers[cmd].get("store") == "unreachable: answered from memory"
                   for cmd in ("status", "jobs", "pause"))  # abort only raises a flag
    finally:
        postgres.start()
    assert wait_until(lambda: request(sock, "status", job=job)["job"]["state"] == "aborted",
                      20)
    daemon.shutdown()
    worker.join(10)
    daemon.control.stop()
    daemon.store.close()
    daemon.lock.release()
