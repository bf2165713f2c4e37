"""Submitted files are read by the bytes actually read (a /proc file that says 0 bytes
is refused after one chunk), only when regular, copied before anything parses them, and
a refusal names the file and the fault, never the file's content."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

import untrusted
from station.config import load_config
from station.control import ControlError, request
from station.daemon import Daemon
from station.intake import withhold_content
from tests.station.test_daemon_defence import StationChecked, config_file


@pytest.fixture
def checked_station(tmp_path):
    config = load_config(config_file(tmp_path))
    daemon = Daemon(config, StationChecked(config))
    daemon.control.start()
    yield daemon, tmp_path / "station.sock"
    daemon.control.stop()
    daemon.store.close()
    daemon.lock.release()


def written_bytes() -> int:
    """Bytes this process has passed to write() so far (the kernel's count)."""
    for line in Path("/proc/self/io").read_text().splitlines():
        if line.startswith("wchar:"):
            return int(line.split()[1])
    raise AssertionError("no wchar in /proc/self/io")


def test_a_file_that_gives_more_than_its_size_is_refused_after_one_chunk(tmp_path):
    with pytest.raises(untrusted.InputError, match="gives more bytes than its size of 0"):
        untrusted.read_bytes("/proc/self/pagemap", what="garment", max_bytes=1 << 30)
    before = written_bytes()
    with pytest.raises(untrusted.InputError, match="/proc/self/pagemap: garment gives more"):
        untrusted.copy_file("/proc/self/pagemap", tmp_path / "copy", what="garment",
                            max_bytes=1 << 30)
    assert written_bytes() - before <= 2 * untrusted.files.CHUNK
    assert not (tmp_path / "copy").exists()
    os.mkfifo(tmp_path / "fifo")
    t0 = time.monotonic()
    with pytest.raises(untrusted.InputError, match="is not a regular file"):
        untrusted.read_bytes(tmp_path / "fifo", what="garment", max_bytes=100)
    assert time.monotonic() - t0 < 1.0  # opened without blocking, never read
    big = tmp_path / "big.json"
    big.write_bytes(b" " * 5000)
    with pytest.raises(untrusted.InputError, match="of 5,000 bytes exceeds the limit of 4,096"):
        untrusted.copy_file(big, tmp_path / "big-copy", what="fabric", max_bytes=4096)


def test_the_daemon_refuses_a_proc_file_without_copying_it(checked_station):
    daemon, sock = checked_station
    before = written_bytes()
    t0 = time.monotonic()
    with pytest.raises(ControlError, match=r"^/proc/\d+/pagemap: garment gives more bytes"):
        request(sock, "submit", garment="/proc/self/pagemap")
    assert time.monotonic() - t0 < 5.0
    assert written_bytes() - before < 4 << 20  # the daemon runs in this process
    assert list((daemon.work_dir / "inputs").iterdir()) == []
    with pytest.raises(ControlError, match=r"^/dev/zero: is not a regular file"):
        request(sock, "submit", garment="/dev/zero")
    assert request(sock, "jobs")["jobs"] == []


def test_a_refusal_names_the_file_and_fault_never_its_content(checked_station, tmp_path):
    _daemon, sock = checked_station
    secret = tmp_path / "secret.obj"
    secret.write_text("v 0 0 0\nv SECRET-TOKEN-1234 0 0\nv 1 0 0\nf 1 2 3\n")
    with pytest.raises(ControlError) as refused:
        request(sock, "submit", garment=str(secret))
    message = str(refused.value)
    assert message == f"{secret}: bad number in vertex line 2", message
    faces = tmp_path / "faces.obj"
    faces.write_text("v 0 0 0\nv 0 1 0\nv 1 0 0\nf 1 2\n")
    with pytest.raises(ControlError, match=r"face line 1 is incomplete \(truncated\?\)$"):
        request(sock, "submit", garment=str(faces))


def test_quoted_content_of_the_file_is_withheld_from_any_message(tmp_path):
    copy = tmp_path / "g.json"
    copy.write_text('{"group": "p4-SECRET-TOKEN"}')
    said = withhold_content("g.json: unknown group 'p4-SECRET-TOKEN'; 'p4m' is near", [copy])
    assert said == "g.json: unknown group (content withheld); 'p4m' is near"


def test_a_job_queued_straight_into_the_store_is_checked_as_the_socket_checks(tmp_path):
    """Anyone who reaches a shared store can queue a job: its files are copied within
    limits and from the allowed folders only, before the station reads them."""
    from tests.station.test_daemon import TickingPipeline

    allowed = tmp_path / "patterns"
    allowed.mkdir()
    (allowed / "shirt.obj").write_text("# stand-in\n")
    (tmp_path / "secret.obj").write_text("# not the submitter's to read\n")
    config = load_config(None, {
        "store": {"path": str(tmp_path / "jobs.db"), "work_dir": str(tmp_path / "work")},
        "control": {"socket": str(tmp_path / "station.sock"),
                    "submit_folders": [str(allowed)]}})
    daemon = Daemon(config, TickingPipeline(tick=0.01))
    outside = daemon.store.submit(str(tmp_path / "secret.obj"), None, {})
    inside = daemon.store.submit(str(allowed / "shirt.obj"), None, {})
    proc = daemon.store.submit("/proc/self/pagemap", None, {})
    daemon.run_loop(once=True)
    try:
        refused = daemon.store.job(outside.id)
        assert refused.state == "failed" and "submissions are accepted only from" in \
            refused.reason, refused.reason
        done = daemon.store.job(inside.id)
        assert done.state == "done"
        assert Path(done.garment).is_relative_to(tmp_path / "work" / "inputs")
        assert daemon.store.job(proc.id).state == "failed"
    finally:
        daemon.store.close()
        daemon.lock.release()
