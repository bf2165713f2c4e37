"""Stations sharing one job store: schema versions, claims by requirement, concurrent
claims, lost stations, reassignment and remote commands; on SQLite and PostgreSQL."""

from __future__ import annotations

import sqlite3
import threading
import time
from pathlib import Path

import pytest

from station.fleet import Fleet, StationInfo
from station.fleetmember import FleetMember
from station.jobstore import JobStore, JobStoreError, Requirements
from station.storeschema import SCHEMA_VERSION, SchemaTooNew

LASER = StationInfo("laser-big", "laser", (1600.0, 1000.0))
SMALL = StationInfo("laser-small", "laser", (600.0, 400.0))
KNIFE = StationInfo("knife", "knife", (2500.0, 1600.0))


def test_schema_is_versioned_and_a_newer_one_is_refused(store_location):
    store = JobStore(store_location)
    assert store.schema_version == SCHEMA_VERSION
    store.engine.write(lambda tx: tx.run(
        "insert into schema_version (version, description, applied_at) values (?, ?, ?)",
        SCHEMA_VERSION + 1, "from the future", 0.0))
    store.close()
    with pytest.raises(SchemaTooNew, match=f"version {SCHEMA_VERSION + 1}, newer"):
        JobStore(store_location)


def test_a_store_from_before_versions_is_upgraded_with_its_jobs(tmp_path):
    path = tmp_path / "old.db"
    with sqlite3.connect(path) as conn:  # the version-1 schema, as the first release made it
        conn.executescript(
            "create table jobs (id integer primary key autoincrement, garment text not null,"
            " fabric text, options text not null default '{}', state text not null default "
            "'submitted', reason text not null default '', resume_state text, submitted_at "
            "real not null, updated_at real not null, plan text);"
            "create table pieces (job_id integer not null references jobs(id), piece integer "
            "not null, name text not null, state text not null default 'pending', cut_at real,"
            " primary key (job_id, piece));"
            "create table events (id integer primary key autoincrement, job_id integer "
            "references jobs(id), at real not null, kind text not null, message text not null);"
            "insert into jobs (garment, submitted_at, updated_at) values ('old.obj', 1, 1);")
    store = JobStore(path)
    job = store.job(1)
    assert job.garment == "old.obj" and job.owner is None and job.requirements == Requirements()
    assert Fleet(store).claim(LASER).id == 1


def test_claims_follow_requirements_and_order(store_location):
    store = JobStore(store_location)
    fleet = Fleet(store)
    for info in (LASER, SMALL, KNIFE):
        fleet.register(info)
    big = store.submit("big.obj", None, {}, Requirements(table_mm=(1200, 900)))
    knife = store.submit("k.obj", None, {}, Requirements(tool="knife"))
    named = store.submit("n.obj", None, {}, Requirements(station="laser-small"))
    anyone = store.submit("a.obj", None, {})
    # the small laser cannot take the big or the knife job: its first fit is the named one
    assert fleet.claim(SMALL).id == named.id
    assert fleet.claim(KNIFE).id == big.id  # the knife's table is big enough too
    assert fleet.claim(LASER).id == anyone.id
    assert fleet.claim(LASER).id == anyone.id  # its own active job first, until it ends
    for state in ("capturing", "planning", "ready", "cutting", "done"):
        store.transition(anyone.id, state)
    assert fleet.claim(LASER) is None  # the knife job is not for a laser
    assert fleet.claim(KNIFE) is not None
    assert store.job(knife.id).owner is None  # still the knife's own big job first
    owners = {j.id: j.owner for j in store.jobs()}
    assert owners == {big.id: "knife", knife.id: None, named.id: "laser-small",
                      anyone.id: "laser-big"}
    claims = [e["message"] for e in store.events() if e["kind"] == "claim"]
    assert claims == ["claimed by station laser-small", "claimed by station knife",
                      "claimed by station laser-big"]
    with pytest.raises(JobStoreError, match="tool must be"):
        Requirements(tool="plasma")


def _claim_all(location: str, info: StationInfo, got: list[int], start: threading.Event
               ) -> None:
    store = JobStore(location)
    fleet = Fleet(store)
    start.wait()
    while (job := fleet.claim(info)) is not None:
        got.append(job.id)
        store.transition(job.id, "capturing")
        store.transition(job.id, "failed", "test: done with it")  # frees the station
        time.sleep(0.01)  # a station works on its job a while before it claims again
    store.close()


def test_concurrent_claims_take_every_job_exactly_once(store_location):
    store = JobStore(store_location)
    fleet = Fleet(store)
    stations = [StationInfo(f"s{i}", "laser", (1600, 1000)) for i in range(6)]
    for info in stations:
        fleet.register(info)
    ids = [store.submit(f"g{i}.obj", None, {}).id for i in range(60)]
    got: list[list[int]] = [[] for _ in stations]
    start = threading.Event()
    threads = [threading.Thread(target=_claim_all, args=(store_location, s, g, start))
               for s, g in zip(stations, got)]
    for t in threads:
        t.start()
    start.set()
    for t in threads:
        t.join(60)
    claimed = sorted(j for g in got for j in g)
    assert claimed == ids  # each job once: never two stations, never none
    assert sum(bool(g) for g in got) >= 2  # and the claimers really ran side by side
    for job in store.jobs():
        assert job.owner in {s.name for s in stations}
        assert sum(e["kind"] == "claim" for e in store.events(job.id)) == 1


def test_a_lost_station_keeps_its_job_interrupted_until_it_returns(store_location):
    store = JobStore(store_location)
    fleet = Fleet(store, timeout=1.0)
    fleet.register(LASER)
    fleet.register(SMALL)
    job = store.submit("a.obj", None, {})
    assert fleet.claim(LASER).id == job.id
    for state in ("capturing", "planning", "ready", "cutting"):
        store.transition(job.id, state)
    store.set_pieces(job.id, ["front", "back"])
    store.set_piece_state(job.id, 0, "cutting")
    store.set_piece_state(job.id, 0, "cut")
    store.set_piece_state(job.id, 1, "cutting")
    fleet.heartbeat(SMALL.name, None, {})
    assert fleet.reap() == []  # fresh heartbeats: nobody is lost
    time.sleep(1.2)
    fleet.heartbeat(SMALL.name, None, {})
    assert fleet.reap() == [job.id]
    lost = store.job(job.id)
    assert (lost.state, lost.owner, lost.resume_state) == ("interrupted", LASER.name, "cutting")
    assert [p["state"] for p in store.pieces(job.id)] == ["cut", "pending"]
    assert {s["name"]: s["state"] for s in fleet.stations()} == {LASER.name: "lost",
                                                                 SMALL.name: "idle"}
    assert fleet.claim(SMALL) is None  # only the owner may resume it
    fleet.register(LASER)  # the station restarts
    resumed = fleet.claim(LASER)
    assert (resumed.id, resumed.state) == (job.id, "cutting")
    messages = [e["message"] for e in store.events(job.id)]
    assert "cutting -> interrupted: station laser-big lost" in " ".join(messages)
    assert messages[-1] == "interrupted -> cutting: resumed by station laser-big"


def test_a_reassigned_job_goes_to_another_station_with_its_cut_pieces_kept(store_location):
    store = JobStore(store_location)
    fleet = Fleet(store, timeout=1.0)
    job = store.submit("a.obj", None, {}, Requirements(station=LASER.name))
    fleet.claim(LASER)
    for state in ("capturing", "planning", "ready", "cutting"):
        store.transition(job.id, state)
    store.set_pieces(job.id, ["front", "back"])
    store.set_piece_state(job.id, 0, "cut")
    store.transition(job.id, "interrupted", "test: the station burnt out")
    with pytest.raises(JobStoreError, match="only an interrupted, paused or failed"):
        fleet.reassign(store.submit("b.obj", None, {}).id)
    fleet.reassign(job.id, SMALL.name)
    moved = store.job(job.id)
    assert (moved.state, moved.owner, moved.requirements.station) == ("submitted", None,
                                                                      SMALL.name)
    assert fleet.claim(LASER).id != job.id  # b.obj, not the reassigned job
    assert fleet.claim(SMALL).id == job.id
    assert [p["state"] for p in store.pieces(job.id)] == ["cut", "pending"]


def test_console_requests_travel_through_the_store_to_the_owner(store_location):
    store = JobStore(store_location)
    fleet = Fleet(store)
    seen: list[dict] = []

    def handle(request: dict) -> dict:
        seen.append(request)
        if request["cmd"] == "pause":
            return {"job": request["job"], "message": "paused (feed hold)"}
        raise JobStoreError("no such thing")

    # PostgreSQL notifies the station at once, so even a slow heartbeat answers fast;
    # SQLite has only the heartbeat's polling.
    notified = store.engine.dialect == "postgresql"
    member = FleetMember(fleet, LASER, lambda: (7, {"step": "cutting", "fraction": 0.5}),
                         handle, interval=5.0 if notified else 0.05)
    member.join()
    member.start()
    try:
        time.sleep(0.5)  # up and listening
        t0 = time.monotonic()
        ok = fleet.wait_answer(fleet.send(LASER.name, {"cmd": "pause", "job": 7}), 5.0)
        latency = time.monotonic() - t0
        bad = fleet.wait_answer(fleet.send(LASER.name, {"cmd": "frobnicate"}), 5.0)
    finally:
        member.stop()
    assert ok == {"ok": True, "job": 7, "message": "paused (feed hold)"}
    assert bad == {"ok": False, "error": "no such thing"}
    assert seen == [{"cmd": "pause", "job": 7}, {"cmd": "frobnicate"}]
    assert latency < 1.0
    station = fleet.station(LASER.name)
    assert station["state"] == "stopped"  # signed off cleanly
    assert station["progress"] == {"step": "cutting", "fraction": 0.5}


def test_a_transaction_rolled_back_for_a_deadlock_runs_again(pg_url):
    """Two stores lock two rows in opposite orders: the server kills one transaction,
    the engine runs it again, and both changes land exactly once."""
    first, second = JobStore(pg_url), JobStore(pg_url)
    fleet = Fleet(first)
    fleet.register(LASER)
    fleet.register(SMALL)
    both_locked = threading.Barrier(2, timeout=10)
    attempts = {"a": 0, "b": 0}

    def crossing(key: str, one: str, other: str):
        def work(tx):
            attempts[key] += 1
            tx.run("update stations set progress = progress || '' where name = ?", one)
            if attempts[key] == 1:
                both_locked.wait()
            tx.run("update stations set profile = profile || ? where name = ?", key, other)
        return work

    threads = [threading.Thread(target=first.engine.write,
                                args=(crossing("a", LASER.name, SMALL.name),)),
               threading.Thread(target=second.engine.write,
                                args=(crossing("b", SMALL.name, LASER.name),))]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    profiles = {s["name"]: s["profile"] for s in fleet.stations()}
    assert profiles == {SMALL.name: "a", LASER.name: "b"}
    assert sorted(attempts.values()) == [1, 2]  # one ran again after the deadlock


def test_an_unreachable_server_or_a_newer_schema_is_one_line_and_exit_2(store_location,
                                                                         capsys, tmp_path):
    from station.cli import main

    assert main(["fleet", "--store", "postgresql://station@127.0.0.1:1/none"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("station fleet: error: postgresql://station@127.0.0.1:1/none: "
                          "cannot connect") and err.count("\n") == 1
    # a password never goes on the command line, and nothing is created for a non-store
    for store, fault in (("postgresql://station:secret@127.0.0.1:1/none", "PGPASSFILE"),
                         ("mysql://root:secret@db/x", "not mysql://"),
                         ("not a url", "no job store there")):
        assert main(["fleet", "--store", store]) == 2
        err = capsys.readouterr().err
        assert fault in err and err.count("\n") == 1 and "secret" not in err, err
    assert not Path("not a url").exists()
    spec = tmp_path / "spec.json"
    spec.write_text('{"not": "a job store"}')
    assert main(["fleet", "--store", str(spec)]) == 2
    assert "not a job store (file is not a database)" in capsys.readouterr().err
    store = JobStore(store_location)
    store.engine.write(lambda tx: tx.run(
        "insert into schema_version (version, description, applied_at) values (?, ?, ?)",
        SCHEMA_VERSION + 1, "from the future", 0.0))
    store.close()
    assert main(["jobs", "--fleet", "--store", store_location]) == 2
    err = capsys.readouterr().err
    assert "newer than this station's" in err and err.count("\n") == 1


def test_an_idle_station_is_woken_by_a_submission(store_location):
    """PostgreSQL tells listening stations at once; SQLite leaves it to their polling."""
    store = JobStore(store_location)
    woken = threading.Event()
    member = FleetMember(Fleet(store), LASER, lambda: (None, {}), lambda r: {},
                         interval=5.0, wake=woken.set)
    member.join()
    member.start()
    try:
        time.sleep(0.5)  # up and listening
        JobStore(store_location).submit("a.obj", None, {})
        assert woken.wait(1.0) == (store.engine.dialect == "postgresql")
    finally:
        member.stop()
