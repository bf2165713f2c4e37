"""The daemon defends itself: one per job store, bounded requests, submissions checked in a
bounded child while the console keeps answering, and a job loop no failure can kill."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from station.cli import main
from station.config import load_config
from station.control import MAX_REQUEST, ControlError, request
from station.daemon import Daemon, wait_until
from station.daemon_lock import AlreadyRunning
from station.errors import UserError
from tests.station.test_daemon import TickingPipeline

ROOT = Path(__file__).resolve().parents[2]
SPEC = ROOT / "tests" / "data" / "garments" / "garmentcode" / "tshirt_specification.json"


class CheckingPipeline(TickingPipeline):
    """The stand-in pipeline with a check that really reads the garment (as the station's
    does), plus two abusive ones: ``hog`` wants 16 GB, ``slow`` computes for 2.5 s."""

    def check(self, garment: str, fabric: str | None, options: dict) -> None:
        name = Path(garment).name
        if name.startswith("hog"):
            np.ones(2**31)
        elif name.startswith("slow"):
            end = time.monotonic() + 2.5
            while time.monotonic() < end:
                sum(range(10_000))  # pure Python: in-process it would hold the GIL
        elif name.endswith(".json"):
            from solver.garment import load_garment

            load_garment(garment)


def config_file(tmp_path: Path) -> Path:
    path = tmp_path / "station.toml"
    path.write_text(f'[store]\npath = "{tmp_path / "jobs.db"}"\nwork_dir = "{tmp_path / "work"}"\n'
                    f'[control]\nsocket = "{tmp_path / "station.sock"}"\ncheck_seconds = 30.0\n'
                    "check_memory_mb = 512\n")
    return path


@pytest.fixture
def station(tmp_path):
    cfg = config_file(tmp_path)
    daemon = Daemon(load_config(cfg), CheckingPipeline())
    daemon.recover()
    daemon.control.start()
    thread = threading.Thread(target=daemon.run_loop, daemon=True)
    thread.start()
    garment = tmp_path / "shirt.obj"
    garment.write_text("# stand-in\n")
    fabric = tmp_path / "fabric.json"
    fabric.write_text("{}")
    yield daemon, tmp_path / "station.sock", garment, fabric, cfg
    daemon.shutdown()
    thread.join(5)
    daemon.control.stop()
    daemon.lock.release()


def job_state(sock, job):
    return request(sock, "status", job=job)["job"]


def test_second_serve_refuses_and_the_first_keeps_answering_and_cutting(station):
    daemon, sock, garment, fabric, cfg = station
    job = request(sock, "submit", garment=str(garment), fabric=str(fabric))["job"]["id"]
    inode = os.stat(sock).st_ino
    db_before = (cfg.parent / "jobs.db").read_bytes()
    second = subprocess.run([sys.executable, "-m", "station.cli", "serve", "--simulate",
                             "--config", str(cfg)], capture_output=True, text=True, timeout=60,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert second.returncode == 2, second.stderr
    lines = second.stderr.strip().splitlines()
    assert len(lines) == 1 and f"station already running (pid {os.getpid()})" in lines[0]
    assert os.stat(sock).st_ino == inode  # the first daemon's socket is untouched
    assert request(sock, "ping")["pid"] == os.getpid()
    assert wait_until(lambda: job_state(sock, job)["state"] == "done", 10)
    assert len(request(sock, "jobs")["jobs"]) == 1
    assert db_before  # the second daemon opened no store: only the first one wrote
    with pytest.raises(AlreadyRunning, match="already running"):
        Daemon(load_config(cfg), CheckingPipeline())


def test_a_stale_socket_is_replaced_and_any_other_file_is_refused_untouched(tmp_path):
    cfg = config_file(tmp_path)
    sock = tmp_path / "station.sock"
    stale = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    stale.bind(str(sock))  # bound, never listening: what a killed daemon leaves
    stale.close()
    daemon = Daemon(load_config(cfg), CheckingPipeline())
    daemon.control.start()
    try:
        assert request(sock, "ping")["pid"] == os.getpid()
        other = tmp_path / "other"
        other.mkdir()
        live = config_file(other)
        live.write_text(live.read_text().replace(str(other / "station.sock"), str(sock)))
        with pytest.raises(UserError, match="another daemon listens on this control socket"):
            Daemon(load_config(live), CheckingPipeline())
    finally:
        daemon.control.stop()
        daemon.store.close()
        daemon.lock.release()
    sock.write_text("the job store, by a slip of the configuration")
    with pytest.raises(UserError, match="control.socket names a file, not a socket"):
        Daemon(load_config(cfg), CheckingPipeline())
    assert sock.read_text() == "the job store, by a slip of the configuration"
    elsewhere = {"control": {"socket": str(tmp_path / "elsewhere.sock")}}
    again = Daemon(load_config(cfg, elsewhere), CheckingPipeline())
    again.store.close()  # the refused daemon released the store's lock
    again.lock.release()


def pinger(sock: Path, stop: threading.Event, delays: list[float]) -> None:
    while not stop.is_set():
        t0 = time.monotonic()
        try:
            request(sock, "ping", timeout=5)
            delays.append(time.monotonic() - t0)
        except ControlError:
            delays.append(99.0)
        time.sleep(0.1)


def test_huge_submissions_are_checked_aside_while_pings_answer_within_a_second(
        station, tmp_path):
    daemon, sock, garment, fabric, cfg = station
    spec = json.loads(SPEC.read_text())
    for panel in spec["pattern"]["panels"].values():  # a panel 10^9 mm across
        panel["vertices"] = [[x * 1e7, y * 1e7] for x, y in panel["vertices"]]
    huge = tmp_path / "huge.json"
    huge.write_text(json.dumps(spec))
    hog = tmp_path / "hog.obj"
    hog.write_text("# asks for 16 GB\n")
    slow = tmp_path / "slow.obj"
    slow.write_text("# takes 2.5 s to check\n")
    stop, delays = threading.Event(), []
    thread = threading.Thread(target=pinger, args=(sock, stop, delays))
    thread.start()
    try:
        with pytest.raises(ControlError, match="huge.json: a panel spans"):
            request(sock, "submit", garment=str(huge), fabric=str(fabric), timeout=60)
        with pytest.raises(ControlError, match="memory"):
            request(sock, "submit", garment=str(hog), fabric=str(fabric), timeout=60)
        request(sock, "submit", garment=str(slow), fabric=str(fabric), timeout=60)
    finally:
        stop.set()
        thread.join()
    assert len(delays) >= 10 and max(delays) < 1.0, delays
    assert len(request(sock, "jobs")["jobs"]) == 1  # nothing refused entered the queue
    assert len(list((tmp_path / "work" / "inputs").iterdir())) == 1  # nor left its copies


def test_console_answers_and_the_submitter_waits_politely(station, tmp_path, capsys):
    daemon, sock, garment, fabric, cfg = station
    slow = tmp_path / "slow.obj"
    slow.write_text("# takes 2.5 s to check\n")
    stop, delays = threading.Event(), []
    thread = threading.Thread(target=pinger, args=(sock, stop, delays))
    thread.start()
    try:
        code = main(["submit", str(slow), "--fabric", str(fabric), "--socket", str(sock)])
    finally:
        stop.set()
        thread.join()
    out, err = capsys.readouterr()
    assert code == 0 and "submitted" in out
    assert "the daemon is checking" in err and "Traceback" not in err
    assert max(delays) < 1.0, delays


def test_a_submitter_that_gives_up_says_so_in_one_line(station, tmp_path, capsys):
    daemon, sock, garment, fabric, cfg = station
    slow = tmp_path / "slow.obj"
    slow.write_text("# takes 2.5 s to check\n")
    code = main(["submit", str(slow), "--fabric", str(fabric), "--socket", str(sock),
                 "--wait", "1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and "Traceback" not in "\n".join(err)
    assert "no answer within 1 s" in err[-1] and err[-1].startswith("station submit: error: ")


def test_submitted_inputs_are_copied_at_submit_time(station):
    daemon, sock, garment, fabric, cfg = station
    daemon.pipeline.tick = 1.0  # keep the job busy while the originals change
    job = request(sock, "submit", garment=str(garment), fabric=str(fabric))["job"]
    garment.write_text("# swapped after submitting\n")
    fabric.write_text('{"swapped": true}')
    assert Path(job["garment"]).read_text() == "# stand-in\n"
    assert Path(job["fabric"]).read_text() == "{}"
    assert Path(job["garment"]).is_relative_to(cfg.parent / "work" / "inputs")


def test_an_overlong_request_is_refused_before_it_is_buffered(station):
    daemon, sock, garment, fabric, cfg = station
    rss = _rss_kb()
    client = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    client.connect(str(sock))
    chunk = b"x" * (1 << 20)
    sent = 0
    try:
        for _ in range(20):  # 20 MB without a newline
            client.sendall(chunk)
            sent += len(chunk)
    except (BrokenPipeError, ConnectionResetError):
        pass
    answer = client.recv(4096)
    client.close()
    assert sent < 20 << 20 or answer  # the daemon stopped reading, or answered first
    assert json.loads(answer.splitlines()[0])["error"] == \
        f"request longer than {MAX_REQUEST} bytes refused"
    assert _rss_kb() - rss < 16 * 1024  # well under the 20 MB it would have buffered
    assert request(sock, "ping")["pid"] == os.getpid()


def _rss_kb() -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


class FailingPipeline(CheckingPipeline):
    """Planning fails after the job was already marked failed: recording the failure then
    fails too (the store refuses failed -> failed)."""

    def plan(self, job, captured, workdir, control):
        if job.id == 1:
            self.store.transition(job.id, "failed", "failed elsewhere first")
            raise RuntimeError("planning broke")
        return super().plan(job, captured, workdir, control)


def test_a_failure_while_handling_a_failure_never_kills_the_job_loop(tmp_path):
    cfg = config_file(tmp_path)
    pipeline = FailingPipeline()
    daemon = Daemon(load_config(cfg), pipeline)
    pipeline.store = daemon.store
    garment = tmp_path / "shirt.obj"
    garment.write_text("# stand-in\n")
    (tmp_path / "work" / "job-2").parent.mkdir(parents=True, exist_ok=True)
    (tmp_path / "work" / "job-2").write_text("a file where the job folder goes")
    for _ in range(3):
        daemon.store.submit(str(garment), None, {})
    try:
        daemon.run_loop(once=True)
    finally:
        daemon.lock.release()
    states = [j.state for j in daemon.store.jobs()]
    assert states == ["failed", "failed", "done"]
    assert "internal error" in daemon.store.job(2).reason


def test_serve_writes_job_files_0640(tmp_path):
    cfg = config_file(tmp_path)
    done = subprocess.run([sys.executable, "-m", "station.cli", "serve", "--simulate", "--once",
                           "--config", str(cfg)], capture_output=True, text=True, timeout=60,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 0, done.stderr
    assert os.stat(tmp_path / "jobs.db").st_mode & 0o777 == 0o640
    assert not (tmp_path / "jobs.db.lock").exists()  # the lock is on the store itself


def test_submissions_can_be_limited_to_configured_folders(tmp_path):
    cfg = config_file(tmp_path)
    (tmp_path / "incoming").mkdir()
    cfg.write_text(cfg.read_text() + f'submit_folders = ["{tmp_path / "incoming"}"]\n')
    daemon = Daemon(load_config(cfg), CheckingPipeline())
    daemon.control.start()
    inside = tmp_path / "incoming" / "shirt.obj"
    inside.write_text("# stand-in\n")
    outside = tmp_path / "elsewhere.obj"
    outside.write_text("# stand-in\n")
    sock = tmp_path / "station.sock"
    try:
        with pytest.raises(ControlError, match="accepted only from"):
            request(sock, "submit", garment=str(outside), fabric=None)
        (tmp_path / "incoming" / "link.obj").symlink_to(outside)
        with pytest.raises(ControlError, match="accepted only from"):
            request(sock, "submit", garment=str(tmp_path / "incoming" / "link.obj"))
        assert request(sock, "submit", garment=str(inside))["job"]["id"] == 1
    finally:
        daemon.control.stop()
        daemon.lock.release()


def test_stopping_kills_a_check_in_progress(station, tmp_path):
    daemon, sock, garment, fabric, cfg = station
    slow = tmp_path / "slow.obj"
    slow.write_text("# takes 2.5 s to check\n")
    errors = []

    def submit() -> None:
        try:
            request(sock, "submit", garment=str(slow), timeout=30)
        except ControlError as exc:
            errors.append(str(exc))

    thread = threading.Thread(target=submit)
    thread.start()
    assert wait_until(lambda: daemon.intake._child is not None, 5)
    t0 = time.monotonic()
    daemon.intake.stop()
    thread.join(10)
    assert time.monotonic() - t0 < 2.0 and errors and "signal 9" in errors[0]
    assert request(sock, "jobs")["jobs"] == []


def test_job_options_are_bounded_at_submit(station):
    daemon, sock, garment, fabric, cfg = station
    for options, match in (({"restarts": 10**9}, "restarts must be an integer 1 to 10,000"),
                           ({"seed": -1}, "seed must be an integer"),
                           ({"units": "x" * 1000}, "short number, text"),
                           ({f"k{i}": 1 for i in range(17)}, "at most 16 keys")):
        with pytest.raises(ControlError, match=match):
            request(sock, "submit", garment=str(garment), fabric=str(fabric), options=options)
    assert request(sock, "jobs")["jobs"] == []


class StationChecked(TickingPipeline):
    """The stand-in's steps with the station's own check of a submission."""

    def __init__(self, config) -> None:
        super().__init__()
        from station.pipeline import StationPipeline

        self.check = StationPipeline(config).check


def test_submit_with_allowance_pairs_grain_and_bias_is_accepted(tmp_path, capsys):
    cfg = config_file(tmp_path)
    config = load_config(cfg)
    daemon = Daemon(config, StationChecked(config))
    daemon.control.start()
    sock = tmp_path / "station.sock"
    try:
        allowance = tmp_path / "allowance.json"
        allowance.write_text('{"hem": 25, "3": 15}')
        pairs = tmp_path / "pairs.json"
        pairs.write_text('{"pairs": [["left_ftorso", "right_ftorso"]], "not_pairs": []}')
        args = ["submit", str(SPEC), "--detect", "--socket", str(sock), "--allowance",
                str(allowance),
                "--pairs", str(pairs), "--grain-line", "right_sleeve_b=90", "--bias",
                "left_sleeve_f"]
        assert main(args) == 0, capsys.readouterr().err
        job = request(sock, "jobs")["jobs"][0]
        options = daemon.store.job(job["id"]).options
        assert options["allowance"] == {"hem": 25, "3": 15}
        assert options["grain_lines"] == {"right_sleeve_b": 90.0}
        assert options["bias"] == ["left_sleeve_f"]
        assert options["pairs"]["pairs"] == [["left_ftorso", "right_ftorso"]]
        # the daemon's check still refuses a name the garment lacks, in one line
        assert main(args[:-1] + ["no_such_piece"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "no_such_piece" in err[0], err
        # and a shape no submit could send is refused before any check
        with pytest.raises(ControlError, match=r"option grain_lines must be \{\"piece\""):
            request(sock, "submit", garment=str(SPEC), options={"grain_lines": {"a": 1e300}})
    finally:
        daemon.control.stop()
        daemon.store.close()
        daemon.lock.release()
