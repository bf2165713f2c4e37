"""A room of stations on one real PostgreSQL server, checked against their machines.

Every station here is a real `Daemon` claiming from the shared store and cutting with
the real streamer on its own GRBL emulator; only capture and planning are replaced by
tiny layouts (`fleet_helpers.TinyJobs`: the full alignment and nesting of fifty garments
would take many minutes). The motion traces are the witness of what was cut.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from gcode.resume import OVERLAP_MM
from simulators.grbl import GrblEmulator
from simulators.grbl.pty import PtyBridge
from station.daemon import wait_until
from station.fleet import Fleet
from station.jobstore import JobStore

from .fleet_helpers import (
    RunningStation,
    beam_segments,
    complete_runs,
    coverage,
    densify,
    piece_contour,
    stand_in_garment,
    station_config,
)

ROOT = Path(__file__).resolve().parents[2]
KERF = 0.2  # the built-in machine's


def check_each_piece_cut_once(store: JobStore, machines: dict[str, object]) -> int:
    """Every piece recorded cut once, cut by its owner's machine (twice only over the
    overlap where a resumed attempt joins the kerf) and by no other."""
    n = 0
    for job in store.jobs():
        pieces = store.pieces(job.id)
        assert pieces and all(p["state"] == "cut" for p in pieces), (job, pieces)
        events = [e["message"] for e in store.events(job.id)]
        for p in pieces:
            assert events.count(f"piece {p['piece']} ({p['name']}) cut") == 1
            contour = piece_contour(job.id, p["piece"], len(pieces), KERF,
                                    job.options.get("size", 12.0))
            for name, m in machines.items():
                samples, covered, runs = coverage(m.trace, contour)
                if name != job.owner:
                    assert covered.max() == 0, (job.id, p["name"], name)
                    continue
                # cut all round, twice only where a resumed attempt joins the kerf
                assert covered.min() >= 1, (job.id, p["name"], "not cut all round")
                step = np.hypot(*np.diff(samples, axis=0).T)
                twice = float(step[(covered[:-1] > 1) & (covered[1:] > 1)].sum())
                assert twice <= (runs - 1) * (OVERLAP_MM + 1.0), (job.id, p["name"], twice)
            n += 1
    return n


@pytest.mark.slow
def test_fifty_jobs_on_three_stations_each_done_once_each_piece_cut_once(pg_url, tmp_path):
    store = JobStore(pg_url)
    garment = stand_in_garment(tmp_path)
    jobs = [store.submit(garment, None, {"pieces": 3}).id for _ in range(50)]
    stations = [RunningStation(station_config(tmp_path, f"table-{i}", pg_url))
                for i in range(3)]
    try:
        assert wait_until(lambda: all(j.state == "done" for j in store.jobs()), 120, 0.2), \
            [(j.id, j.state, j.owner, j.reason) for j in store.jobs() if j.state != "done"]
    finally:
        for s in stations:
            s.stop()
    done = store.jobs()
    assert [j.id for j in done] == jobs
    owners = {s.config["station"]["name"]: sum(j.owner == s.config["station"]["name"]
                                               for j in done) for s in stations}
    assert sum(owners.values()) == 50 and min(owners.values()) >= 5, owners
    for job in done:  # claimed once, done once
        events = [e for e in store.events(job.id)]
        assert sum(e["kind"] == "claim" for e in events) == 1
        assert sum(e["message"] == "cutting -> done" for e in events) == 1
    machines = {s.config["station"]["name"]: s.emulator for s in stations}
    assert check_each_piece_cut_once(store, machines) == 150
    # nothing else was cut: each machine's beam-on moves all lie on its own pieces
    for name, m in machines.items():
        mine = np.vstack([densify(np.c_[c, np.roll(c, -1, axis=0)])
                          for j in done if j.owner == name
                          for c in (piece_contour(j.id, k, 3, KERF) for k in range(3))])
        seg = beam_segments(m.trace)
        assert len(seg) and cKDTree(mine).query(densify(seg))[0].max() < 0.4, name
    fleet = Fleet(store)
    assert {s["name"]: s["state"] for s in fleet.stations()} == {n: "stopped" for n in owners}


class KillableStation:
    """A `station serve`-like process for one fleet station; its machine (a pty emulator)
    lives in this process and outlives it, as a real controller does."""

    def __init__(self, tmp: Path, url: str, name: str, speed: float) -> None:
        self.tmp = tmp
        self.name = name
        tmp.mkdir(parents=True, exist_ok=True)
        self.emulator = GrblEmulator(speed=speed, force_origin=True, name=f"kill-{id(tmp)}",
                                     settings={32: 1, 130: 1600, 131: 1000, 20: 1, 22: 1,
                                               23: 3, 110: 12000, 111: 12000, 120: 1500,
                                               121: 1500})
        self.bridge = PtyBridge(self.emulator, link=str(tmp / "ttyGRBL"))
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self.bridge.serve, args=(self._stop,),
                                        daemon=True)
        self._thread.start()
        self.config = tmp / "station.toml"
        self.config.write_text(
            f'[serial]\nport = "{tmp / "ttyGRBL"}"\n'
            f'[store]\nurl = "{url}"\nwork_dir = "{tmp / "work"}"\n'
            f'[control]\nsocket = "{tmp / "station.sock"}"\n'
            "[machine]\ncheck_mode = false\n"
            f'[station]\nname = "{name}"\nheartbeat_s = 0.2\nlost_after_s = 1.0\n')
        self.proc: subprocess.Popen | None = None
        self.starts = 0

    def start(self) -> None:
        self.starts += 1
        log = open(self.tmp / f"station-{self.starts}.log", "wb")  # noqa: SIM115
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "tests.station.fleet_helpers", str(self.config)],
            stdout=log, stderr=log, cwd=ROOT,
            env={**os.environ, "PYTHONPATH": os.pathsep.join(
                [str(ROOT), os.environ.get("PYTHONPATH", "")])})
        log.close()

    def log(self) -> str:
        return (self.tmp / f"station-{self.starts}.log").read_text(errors="replace")[-3000:]

    def close(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        self._stop.set()
        self._thread.join(5)
        self.bridge.close()
        self.emulator.close()


def test_a_station_killed_mid_cut_keeps_its_job_and_resumes_it_after_restart(pg_url,
                                                                             tmp_path):
    store = JobStore(pg_url)
    killed = KillableStation(tmp_path / "k", pg_url, "table-k", speed=8.0)
    other = None
    try:
        killed.start()
        job = store.submit(stand_in_garment(tmp_path), None, {"pieces": 5, "size": 30.0}).id
        assert wait_until(lambda: store.job(job).owner == "table-k", 30), killed.log()
        assert wait_until(lambda: sum(p["state"] == "cut" for p in store.pieces(job)) >= 1
                          and any(p["state"] == "cutting" for p in store.pieces(job)),
                          60, 0.01), killed.log()
        killed.proc.send_signal(signal.SIGKILL)
        killed.proc.wait()
        # a second station in the room: it sees the first one lost, and must not take its job
        other = RunningStation(station_config(tmp_path, "table-o", pg_url))
        assert wait_until(lambda: store.job(job).state == "interrupted", 15), store.job(job)
        lost = store.job(job)
        assert lost.owner == "table-k" and lost.resume_state == "cutting"
        assert "station table-k lost" in lost.reason
        time.sleep(1.0)  # the other station keeps claiming: the job is not for it
        assert store.job(job).state == "interrupted" and store.job(job).owner == "table-k"
        assert {s["name"]: s["state"] for s in Fleet(store).stations()} == \
            {"table-k": "lost", "table-o": "idle"}
        killed.start()
        assert wait_until(lambda: store.job(job).state == "done", 90), \
            (store.job(job), killed.log())
        killed.proc.send_signal(signal.SIGTERM)
        assert killed.proc.wait(30) == 0, killed.log()
        messages = [e["message"] for e in store.events(job)]
        assert "interrupted -> cutting: resumed by station table-k" in messages
        assert other.emulator is None  # its machine was never even opened
        assert check_each_piece_cut_once(store, {"table-k": killed.emulator}) == 5
    finally:
        if other is not None:
            other.stop()
        killed.close()


def test_the_database_restarted_mid_cut_holds_the_machines_then_goes_on(postgres, pg_url,
                                                                        tmp_path):
    """Two stations cutting; the server crashes and is down longer than a station may
    be silent: both hold, neither is taken for lost, both finish."""
    store = JobStore(pg_url)
    stations = [RunningStation(station_config(tmp_path, f"table-db{i}", pg_url, speed=6.0,
                                              lost_after=1.0)) for i in range(2)]
    try:
        jobs = [store.submit(stand_in_garment(tmp_path), None, {"pieces": 4, "size": 30.0}).id
                for _ in stations]
        assert wait_until(lambda: all(sum(p["state"] == "cut" for p in store.pieces(j)) >= 1
                                      for j in jobs), 60, 0.01)
        machines = {s.config["station"]["name"]: s.emulator for s in stations}
        store.close()
        postgres.stop("immediate")  # as a crash would; the stations' links break

        def held(station) -> bool:  # the heartbeat (0.2 s) finds the store gone
            running = station.daemon.running
            return running is not None and bool(running.progress.get("held_for_store"))

        assert wait_until(lambda: all(held(s) for s in stations), 10, 0.01)
        assert wait_until(lambda: all(m.state in ("Hold:0", "Idle")
                                      for m in machines.values()), 10, 0.01)
        before = [len(beam_segments(m.trace)) for m in machines.values()]
        time.sleep(1.5)
        assert [len(beam_segments(m.trace)) for m in machines.values()] == before
        postgres.start()
        store = JobStore(pg_url)
        assert wait_until(lambda: all(store.job(j).state == "done" for j in jobs), 60), \
            [store.job(j) for j in jobs]
    finally:
        for s in stations:
            s.stop()
    assert check_each_piece_cut_once(store, machines) == 8
    assert not [e for e in store.events() if "interrupted" in e["message"]]


def test_console_commands_reach_the_owning_station_through_the_store(pg_url, tmp_path,
                                                                     capsys):
    from station.cli import main

    garment = ROOT / "tests" / "data" / "garments" / "berkeley" / "tshirt-coarse.obj"
    fabric = tmp_path / "fabric.json"
    fabric.write_text('{"group": "p4m", "w1": [60, 0], "w2": [0, 60], "origin": [0, 0]}')
    store = JobStore(pg_url)
    station = RunningStation(station_config(tmp_path, "table-c", pg_url, speed=6.0))

    def cli(*argv: str) -> dict:
        capsys.readouterr()
        assert main([*argv, "--store", pg_url, "--json"]) == 0
        return json.loads(capsys.readouterr().out)

    try:
        assert main(["submit", str(garment), "--fabric", str(fabric), "--units", "m",
                     "--fleet", "--store", pg_url, "--tool", "knife"]) == 0
        assert main(["submit", str(garment), "--fabric", str(fabric), "--units", "m",
                     "--station", "table-c", "--store", pg_url]) == 0
        knife, job = (j.id for j in store.jobs())
        assert store.job(job).requirements.station == "table-c"
        store.engine.write(lambda tx: tx.run(  # TinyJobs: six squares, long enough to pause
            "update jobs set options = ? where id = ?", '{"pieces": 6, "size": 40.0}', job))
        assert wait_until(lambda: store.job(job).state == "cutting", 30)
        paused = cli("pause", str(job), "--fleet")
        assert paused["station"] == "table-c" and "feed hold" in paused["message"]
        assert store.job(job).state == "paused"
        assert wait_until(lambda: station.emulator.state.startswith("Hold:0"), 10)
        cut = sum(p["state"] == "cut" for p in store.pieces(job))
        time.sleep(1.0)
        assert sum(p["state"] == "cut" for p in store.pieces(job)) == cut  # held in place
        status = cli("status", str(job), "--fleet")["job"]
        assert status["owner"] == "table-c" and status["station_state"] == "busy"
        rows = cli("fleet")["stations"]
        assert [(r["name"], r["state"], r["job_id"]) for r in rows] == [("table-c", "busy",
                                                                         job)]
        assert cli("resume", "--station", "table-c")["message"] == "resumed"
        assert main(["watch", str(job), "--fleet", "--store", pg_url]) == 0  # until done
        assert store.job(job).state == "done"
        assert "cutting" in capsys.readouterr().err  # the progress bars it drew
        assert store.job(knife).state == "submitted"  # no knife in this room
        assert cli("abort", str(knife), "--fleet")["message"] == "aborted"
        capsys.readouterr()
        assert main(["pause", str(job), "--fleet", "--store", pg_url]) == 2
        err = capsys.readouterr().err  # done: nothing to pause there, said in one line
        assert err == "station pause: error: station table-c: that job is not running\n"
    finally:
        station.stop()


def test_a_reassigned_job_is_finished_by_another_station_cutting_only_what_was_not_cut(
        pg_url, tmp_path, capsys):
    from station.cli import main
    from station.fleet import StationInfo

    store = JobStore(pg_url)
    fleet = Fleet(store, timeout=1.0)
    ghost = StationInfo("table-gone", "laser", (1600.0, 1000.0))
    fleet.register(ghost)  # a station that cut two pieces, then its computer died
    job = store.submit(stand_in_garment(tmp_path), None, {"pieces": 5}).id
    assert fleet.claim(ghost).id == job
    for state in ("capturing", "planning", "ready", "cutting"):
        store.transition(job, state)
    store.set_pieces(job, [f"j{job}p{i}" for i in range(5)])
    for piece in (0, 3):
        store.set_piece_state(job, piece, "cut")
    store.set_piece_state(job, 1, "cutting")
    other = RunningStation(station_config(tmp_path, "table-new", pg_url))
    try:
        assert wait_until(lambda: store.job(job).state == "interrupted", 10)
        time.sleep(0.5)
        assert store.job(job).owner == "table-gone"  # not taken over by itself
        assert main(["reassign", str(job), "--to", "table-new", "--store", pg_url]) == 0
        assert "queued again for table-new" in capsys.readouterr().out
        assert wait_until(lambda: store.job(job).state == "done", 30), store.job(job)
    finally:
        other.stop()
    assert store.job(job).owner == "table-new"
    machine = other.emulator
    for piece in range(5):
        runs = complete_runs(machine.trace, piece_contour(job, piece, 5, KERF))
        assert runs == (0 if piece in (0, 3) else 1), (piece, runs)
    events = [e["message"] for e in store.events(job)]
    assert events.count(f"piece 1 (j{job}p1) cut") == 1
    moved = next(i for i, m in enumerate(events)
                 if "reassigned by the operator from table-gone to station table-new" in m)
    assert "submitted -> capturing" in events[moved:]  # the fabric is captured again
