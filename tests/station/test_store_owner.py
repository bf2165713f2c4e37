"""One daemon per job store by the store's identity: a symlink, a hard link or a second
station of the same name on one PostgreSQL server is refused with one line, touching
nothing."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import psycopg
import pytest

from station.config import load_config
from station.daemon import Daemon, wait_until
from station.daemon_lock import AdvisoryLock, AlreadyRunning, flock_holder
from station.errors import UserError
from tests.station.test_daemon import TickingPipeline

ROOT = Path(__file__).resolve().parents[2]


def sqlite_config(folder: Path, store: Path):
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "station.toml"
    path.write_text(f'[store]\npath = "{store}"\nwork_dir = "{folder / "work"}"\n'
                    f'[control]\nsocket = "{folder / "station.sock"}"\n')
    return path


def test_a_second_daemon_through_a_symlink_refuses_in_one_line(tmp_path):
    first = Daemon(load_config(sqlite_config(tmp_path / "a", tmp_path / "a" / "jobs.db")),
                   TickingPipeline())
    try:
        db = tmp_path / "a" / "jobs.db"
        link = tmp_path / "elsewhere.db"
        link.symlink_to(db)
        before = db.read_bytes()
        cfg = sqlite_config(tmp_path / "b", link)
        second = subprocess.run([sys.executable, "-m", "station.cli", "serve", "--simulate",
                                 "--config", str(cfg)], capture_output=True, text=True,
                                timeout=60, env={**os.environ, "PYTHONPATH": str(ROOT)})
        assert second.returncode == 2, second.stderr
        lines = second.stderr.strip().splitlines()
        assert len(lines) == 1, lines
        assert f"station already running (pid {os.getpid()}) on the job store {link}" \
            in lines[0]
        assert db.read_bytes() == before
        assert not (tmp_path / "b" / "station.sock").exists()
        assert not (tmp_path / "b" / "work").exists()
    finally:
        first.store.close()
        first.lock.release()


def test_a_hard_link_is_the_same_store_and_the_lock_goes_with_the_daemon(tmp_path):
    db = tmp_path / "a" / "jobs.db"
    first = Daemon(load_config(sqlite_config(tmp_path / "a", db)), TickingPipeline())
    (tmp_path / "b").mkdir()
    os.link(db, tmp_path / "b" / "same.db")
    st = os.stat(db)
    assert flock_holder(st.st_dev, st.st_ino) == os.getpid()
    second = load_config(sqlite_config(tmp_path / "b", tmp_path / "b" / "same.db"))
    with pytest.raises(AlreadyRunning, match="already running"):
        Daemon(second, TickingPipeline())
    first.store.close()
    first.lock.release()
    assert flock_holder(st.st_dev, st.st_ino) is None
    again = Daemon(second, TickingPipeline())  # released: the other name may take it now
    again.store.close()
    again.lock.release()


def test_a_store_path_that_is_a_folder_is_one_line(tmp_path):
    (tmp_path / "folder.db").mkdir()
    with pytest.raises(UserError, match="job store is a folder"):
        Daemon(load_config(sqlite_config(tmp_path / "a", tmp_path / "folder.db")),
               TickingPipeline())


def fleet_config(folder: Path, url: str, name: str):
    return load_config(None, {
        "store": {"url": url, "work_dir": str(folder / "work")},
        "control": {"socket": str(folder / "station.sock")},
        "station": {"name": name}})


def test_two_stations_of_one_name_on_one_server_refuse_the_second(pg_url, tmp_path):
    first = Daemon(fleet_config(tmp_path / "a", pg_url, "cutter-1"), TickingPipeline())
    try:
        with pytest.raises(AlreadyRunning, match=r"station cutter-1 already running on "
                           r"postgresql://.*\(held by station lock pid \d+"):
            Daemon(fleet_config(tmp_path / "b", pg_url, "cutter-1"), TickingPipeline())
        other = Daemon(fleet_config(tmp_path / "c", pg_url, "cutter-2"), TickingPipeline())
        other.store.close()
        other.lock.release()
    finally:
        first.store.close()
        first.lock.release()
    again = Daemon(fleet_config(tmp_path / "b", pg_url, "cutter-1"), TickingPipeline())
    again.store.close()
    again.lock.release()


def test_a_lost_session_takes_the_name_again_unless_another_took_it(pg_url):
    lock = AdvisoryLock(pg_url, "cutter-1").acquire()
    kill = "select pg_terminate_backend(pid) from pg_stat_activity where " \
           "application_name like 'station lock pid%'"
    with psycopg.connect(pg_url, autocommit=True) as admin:
        admin.execute(kill)
        # nobody else: taken again (or, while the killed session is still ending on the
        # server, known to be this daemon's own)
        assert lock.still_held()
        admin.execute(kill)
        assert wait_until(lambda: not admin.execute(
            "select count(*) from pg_stat_activity where application_name like "
            "'station lock pid%'").fetchone()[0], 10)
        thief = AdvisoryLock(pg_url, "cutter-1")
        thief.app_name = "station lock pid 1 on another host"
        thief.acquire()
        assert not lock.still_held()
        thief.release()
    lock.release()
