"""The daemon's job loop and control socket, driven the way the console drives them.

The pipeline here is a stand-in whose cut step marks pieces cut one per tick and honours
pause and abort like the streamer does; the whole station runs end to end with the real
pipeline in test_serve_simulated.py.
"""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import pytest

from station.config import load_config
from station.control import ControlError, request
from station.daemon import Daemon, JobControl, wait_until
from station.jobstore import Job, JobStore


class Recorded:
    """What a stand-in step hands on: the record the store keeps, and a plan's pieces."""

    def __init__(self, files: dict, pieces: list | None = None) -> None:
        self.files, self.pieces = files, pieces or []

    def record(self) -> dict:
        return {**self.files, **({"pieces": self.pieces} if self.pieces else {})}


class TickingPipeline:
    """Three pieces, cut one per ``tick`` seconds, as the streamer would report them."""

    def __init__(self, tick: float = 0.15) -> None:
        self.tick = tick
        self.cut_calls: list[tuple[int, bool]] = []

    def check(self, garment: str, fabric: str | None, options: dict) -> None:
        if not garment.endswith(".obj"):
            raise ValueError(f"{garment}: not a garment file")

    def capture(self, job: Job, workdir: Path, control: JobControl) -> Recorded:
        return Recorded({"fabric": job.fabric or "detected.json"})

    def plan(self, job: Job, captured: Recorded | None, workdir: Path, control: JobControl
             ) -> Recorded:
        fabric = (captured.record() if captured is not None else job.plan)["fabric"]
        return Recorded({"fabric": fabric}, ["front", "back", "sleeve"])

    def cut(self, job: Job, plan: Recorded | None, store: JobStore, control: JobControl,
            resuming: bool) -> None:
        self.cut_calls.append((job.id, resuming))
        for piece in store.pieces(job.id):
            if piece["state"] == "cut":
                continue
            store.set_piece_state(job.id, piece["piece"], "cutting")
            end = time.monotonic() + self.tick
            while time.monotonic() < end or control.pause.is_set():
                control.checkpoint(hold_in_place=True)
                time.sleep(0.01)
            store.set_piece_state(job.id, piece["piece"], "cut")


@pytest.fixture
def station(tmp_path):
    config = load_config(None, {
        "store": {"path": str(tmp_path / "jobs.db"), "work_dir": str(tmp_path / "work")},
        "control": {"socket": str(tmp_path / "station.sock")},
    })
    pipeline = TickingPipeline()
    daemon = Daemon(config, pipeline)
    daemon.recover()
    daemon.control.start()
    thread = threading.Thread(target=daemon.run_loop, daemon=True)
    thread.start()
    garment = tmp_path / "shirt.obj"
    garment.write_text("# stand-in\n")
    fabric = tmp_path / "fabric.json"
    fabric.write_text("{}")
    yield daemon, tmp_path / "station.sock", garment, fabric
    daemon.shutdown()
    thread.join(5)
    daemon.control.stop()


def state(sock, job):
    return request(sock, "status", job=job)["job"]


def test_submit_runs_to_done_and_logs_every_step(station):
    daemon, sock, garment, fabric = station
    job = request(sock, "submit", garment=str(garment), fabric=str(fabric))["job"]["id"]
    assert wait_until(lambda: state(sock, job)["state"] == "done", 10)
    assert state(sock, job)["pieces"] == {"pending": 0, "cutting": 0, "cut": 3}
    messages = [e["message"] for e in request(sock, "log", job=job)["events"]]
    assert "cutting -> done" in messages
    assert sum(m.endswith(" cut") for m in messages) == 3


def test_pause_holds_in_place_and_resume_finishes(station):
    daemon, sock, garment, fabric = station
    job = request(sock, "submit", garment=str(garment), fabric=str(fabric))["job"]["id"]
    assert wait_until(lambda: state(sock, job)["state"] == "cutting", 5)
    request(sock, "pause", job=job)
    assert state(sock, job)["state"] == "paused"
    cut_before = state(sock, job)["pieces"]["cut"]
    time.sleep(0.5)
    assert state(sock, job)["pieces"]["cut"] <= cut_before + 1  # at most the piece in hand
    request(sock, "resume", job=job)
    assert wait_until(lambda: state(sock, job)["state"] == "done", 10)
    assert daemon.pipeline.cut_calls == [(job, False)]  # one stream, held and resumed


def test_abort_then_retry_cuts_only_the_rest(station):
    daemon, sock, garment, fabric = station
    job = request(sock, "submit", garment=str(garment), fabric=str(fabric))["job"]["id"]
    assert wait_until(lambda: state(sock, job)["pieces"]["cut"] >= 1, 5)
    request(sock, "abort", job=job)
    assert wait_until(lambda: state(sock, job)["state"] == "aborted", 5)
    cut = state(sock, job)["pieces"]["cut"]
    assert cut < 3
    request(sock, "retry", job=job)
    assert wait_until(lambda: state(sock, job)["state"] == "done", 10)
    events = request(sock, "log", job=job)["events"]
    for piece in ("front", "back", "sleeve"):  # every piece cut exactly once
        assert sum(e["message"] == f"piece {['front', 'back', 'sleeve'].index(piece)} "
                   f"({piece}) cut" for e in events) == 1


def test_bad_requests_get_clear_errors_and_change_nothing(station):
    daemon, sock, garment, fabric = station
    with pytest.raises(ControlError, match="no such garment file"):
        request(sock, "submit", garment=str(garment) + ".missing", fabric=str(fabric))
    bad = garment.with_suffix(".txt")
    bad.write_text("x")
    with pytest.raises(ControlError, match="not a garment file"):
        request(sock, "submit", garment=str(bad), fabric=str(fabric))
    with pytest.raises(ControlError, match="unknown command"):
        request(sock, "explode")
    with pytest.raises(ControlError, match="only failed or aborted"):
        job = request(sock, "submit", garment=str(garment), fabric=str(fabric))["job"]["id"]
        request(sock, "retry", job=job)
    assert len(request(sock, "jobs")["jobs"]) == 1


@pytest.mark.skipif(os.getuid() != 0, reason="needs root to act as another user")
def test_socket_refuses_a_user_who_is_not_allowed(station):
    daemon, sock, garment, fabric = station
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # child: become nobody, then try the socket
        os.close(read)
        os.setgid(65534)
        os.setuid(65534)
        try:
            request(sock, "jobs")
            os.write(write, b"allowed")
        except ControlError as exc:
            os.write(write, str(exc).encode()[:200])
        os._exit(0)
    os.close(write)
    os.waitpid(pid, 0)
    answer = os.read(read, 300).decode()
    assert "permission denied" in answer
    assert oct(os.stat(sock).st_mode & 0o777) == "0o660"
