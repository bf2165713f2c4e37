"""Many stations on one job store: registration, heartbeats, claims and remote commands.
(`station.fleetmember` is a daemon's side of it: its heartbeat thread and claim loop.)

Claiming. A station takes work in one short transaction: first a job it owns that is
waiting for it (interrupted when it stopped, or resumed by the operator), else the oldest
unowned submitted job whose requirements it meets (tool, minimum table, station name). The row
is locked with ``FOR UPDATE SKIP LOCKED`` on PostgreSQL, so concurrent claimers never
take the same job and never wait on one another; SQLite serialises writers, which gives
the same guarantee to the one table it serves.

Heartbeats. Every station writes one every ``interval`` seconds (with its running job and
progress). A station silent for ``timeout`` seconds is "lost": the next heartbeat of any
station marks its active job "interrupted", still owned by it (but not within
``timeout`` of the reaper's own start or of the store coming back after an outage: then
every heartbeat is stale and says nothing). Only the owner resumes an
interrupted job (its controller's EEPROM holds the markers that tell which piece the
machine finished); if it comes back within the job, its heartbeat revives it. An
operator may reassign the job instead: it goes back to "submitted" for another station,
which re-detects the fabric and cuts only the pieces not recorded cut.

Remote commands. The console writes a request (the same JSON as on the control socket)
into ``commands`` for the owning station; that station's heartbeat thread runs it through
the daemon's own handler and writes the answer back. On PostgreSQL the request is also
sent with NOTIFY to the station, which LISTENs on its own connection and runs it at once
(milliseconds); without notifications (SQLite, or while that connection is down) the
heartbeat finds it within ``interval`` seconds (0.5 s by default).
"""

from __future__ import annotations

import hashlib
import json
import sqlite3
import time
from dataclasses import dataclass
from typing import Any

from gcode.machine import default_machine
from station.jobstore import ACTIVE, TOOLS, Job, JobStore, JobStoreError
from station.storeengine import StoreUnavailable, Tx, is_server_url
from station.storeschema import SchemaTooNew

LIVE = ("idle", "busy")


@dataclass(frozen=True)
class StationInfo:
    """What a station offers: its tool and table (machine x and y travel, mm)."""

    name: str
    tool: str
    table_mm: tuple[float, float]
    profile: str = ""

    def __post_init__(self) -> None:
        if not self.name:
            raise JobStoreError("a station needs a name")
        if self.tool not in TOOLS:
            raise JobStoreError(f"tool must be one of {', '.join(TOOLS)}, got {self.tool!r}")


class Fleet:
    """The fleet's tables in a job store; every method is one transaction."""

    def __init__(self, store: JobStore, timeout: float = 30.0) -> None:
        self.store = store
        self.timeout = timeout

    # ------------------------------------------------------------------ stations
    def register(self, info: StationInfo) -> None:
        """Join (or rejoin) the fleet as idle; the station's row keeps its name."""
        now = time.time()

        def work(tx: Tx) -> None:
            tx.run("delete from stations where name = ?", info.name)
            tx.run("insert into stations (name, tool, table_x_mm, table_y_mm, profile, "
                   "state, job_id, progress, started_at, heartbeat_at) "
                   "values (?, ?, ?, ?, ?, 'idle', null, '{}', ?, ?)",
                   info.name, info.tool, float(info.table_mm[0]), float(info.table_mm[1]),
                   info.profile, now, now)
            self.store._event(tx, None, "station", f"station {info.name} joined "
                              f"({info.tool}, {info.table_mm[0]:g} x {info.table_mm[1]:g} mm)")

        self.store.engine.write(work)

    def sign_off(self, name: str) -> None:
        """A clean stop: the station is "stopped", not lost (if the server answers soon:
        a stopping station does not wait out an outage)."""
        self.store.engine.write(lambda tx: tx.run(
            "update stations set state = 'stopped', job_id = null where name = ?", name),
            patience=5.0)

    def heartbeat(self, name: str, job_id: int | None, progress: dict[str, Any]) -> None:
        """I am alive, running ``job_id``; revive that job if others gave it up for lost."""

        def work(tx: Tx) -> None:
            tx.run("update stations set state = ?, job_id = ?, progress = ?, heartbeat_at = ? "
                   "where name = ?", "busy" if job_id is not None else "idle", job_id,
                   json.dumps(progress, default=float), time.time(), name)
            if job_id is None:
                return
            row = tx.one("select state, resume_state, owner from jobs where id = ?", job_id)
            if row and row["state"] == "interrupted" and row["owner"] == name:
                self.store.transition_in(tx, job_id, row["resume_state"] or "cutting",
                                         f"station {name} answers again")

        self.store.engine.write(work)

    def reap(self) -> list[int]:
        """Mark the active jobs of stations silent for `timeout` s interrupted; their ids."""
        now = time.time()

        def work(tx: Tx) -> list[int]:
            lost = tx.all("select name, heartbeat_at from stations where state in "
                          "('idle', 'busy') and heartbeat_at < ?", now - self.timeout)
            reaped: list[int] = []
            for st in lost:
                marks = ",".join("?" * len(ACTIVE))
                jobs = tx.all(f"select id from jobs where owner = ? and state in ({marks}) "
                              "order by id {skip_locked}", st["name"], *ACTIVE)
                for j in jobs:
                    silent = now - st["heartbeat_at"]
                    self.store.transition_in(tx, j["id"], "interrupted",
                                             f"station {st['name']} lost (no heartbeat for "
                                             f"{silent:.0f} s); it resumes the job when it "
                                             "returns, or reassign it")
                    tx.run("update pieces set state = 'pending' where job_id = ? "
                           "and state = 'cutting'", j["id"])
                    reaped.append(j["id"])
                tx.run("update jobs set owner = null where owner = ? and state = 'submitted'",
                       st["name"])  # claimed but not begun: free for anyone again
                tx.run("update stations set state = 'lost' where name = ? and state in "
                       "('idle', 'busy')", st["name"])
            return reaped

        return self.store.engine.write(work)

    def stations(self) -> list[dict[str, Any]]:
        """Every station with its state ("lost" once silent too long), job and progress."""
        rows = self.store.engine.read(lambda tx: tx.all("select * from stations order by name"))
        now = time.time()
        for r in rows:
            r["progress"] = json.loads(r["progress"] or "{}")
            r["seconds_since_heartbeat"] = now - r["heartbeat_at"]
            if r["state"] in LIVE and now - r["heartbeat_at"] > self.timeout:
                r["state"] = "lost"
        return rows

    def station(self, name: str) -> dict[str, Any]:
        found = [s for s in self.stations() if s["name"] == name]
        if not found:
            raise JobStoreError(f"no station {name!r} in the fleet")
        return found[0]

    # ------------------------------------------------------------------ claims
    def claim(self, info: StationInfo) -> Job | None:
        """The job this station runs next, now owned by it; None when nothing fits."""

        def work(tx: Tx) -> int | None:
            marks = ",".join("?" * len(ACTIVE))
            row = tx.one(f"select id, state, resume_state from jobs where owner = ? and "
                         f"state in ('interrupted', 'submitted', {marks}) order by id limit 1 "
                         "{skip_locked}", info.name, *ACTIVE)
            if row is not None:
                if row["state"] == "interrupted":
                    self.store.transition_in(tx, row["id"], row["resume_state"] or "submitted",
                                             f"resumed by station {info.name}")
            else:
                row = tx.one(
                    "select id from jobs where state = 'submitted' and owner is null "
                    "and (req_tool is null or req_tool = ?) "
                    "and (req_x_mm is null or req_x_mm <= ?) "
                    "and (req_y_mm is null or req_y_mm <= ?) "
                    "and (req_station is null or req_station = ?) "
                    "order by id limit 1 {skip_locked}",
                    info.tool, float(info.table_mm[0]), float(info.table_mm[1]), info.name)
                if row is None:
                    return None
                tx.run("update jobs set owner = ?, updated_at = ? where id = ?",
                       info.name, time.time(), row["id"])
                self.store._event(tx, row["id"], "claim", f"claimed by station {info.name}")
            tx.run("update stations set state = 'busy', job_id = ?, heartbeat_at = ? "
                   "where name = ?", row["id"], time.time(), info.name)
            return row["id"]

        job_id = self.store.engine.write(work)
        return None if job_id is None else self.store.job(job_id)

    def reassign(self, job_id: int, station: str | None = None) -> Job:
        """Give an interrupted, paused or failed job to another station (or any).

        The job goes back to "submitted" without an owner; the pieces recorded cut stay
        cut, so the new station (after detecting the fabric again) cuts only the rest.
        """

        def work(tx: Tx) -> None:
            row = tx.one("select state, owner from jobs where id = ?", job_id)
            if row is None:
                raise JobStoreError(f"no job {job_id}")
            if row["state"] not in ("interrupted", "paused", "failed"):
                raise JobStoreError(f"job {job_id} is {row['state']}; only an interrupted, "
                                    "paused or failed job can be reassigned")
            if row["owner"] and row["state"] == "paused":
                owner = tx.one("select state, job_id, heartbeat_at from stations "
                               "where name = ?", row["owner"])
                if owner and owner["state"] == "busy" and owner["job_id"] == job_id and \
                        time.time() - owner["heartbeat_at"] < self.timeout:
                    raise JobStoreError(f"job {job_id} is held on station {row['owner']}; "
                                        "abort it there first")
            to = f"station {station}" if station else "any compatible station"
            self.store.transition_in(tx, job_id, "submitted",
                                     f"reassigned by the operator from {row['owner']} to {to}")
            tx.run("update jobs set owner = null, req_station = ? where id = ?", station,
                   job_id)
            tx.run("update pieces set state = 'pending' where job_id = ? and state = 'cutting'",
                   job_id)

        self.store.engine.write(work)
        return self.store.job(job_id)

    # ------------------------------------------------------------------ commands
    def send(self, station: str, request: dict[str, Any]) -> int:
        """Queue a console request for ``station`` (on PostgreSQL also NOTIFY it, so that
        it runs the request at once rather than at its next heartbeat); its id."""

        def work(tx: Tx) -> int:
            row = tx.one("insert into commands (station, request, at) values (?, ?, ?) "
                         "returning id", station, json.dumps(request), time.time())
            if tx.dialect == "postgresql":
                tx.run("select pg_notify(?, ?)", channel(station), str(row["id"]))
            return row["id"]

        return self.store.engine.write(work)

    def open_commands(self, station: str) -> list[tuple[int, dict[str, Any]]]:
        rows = self.store.engine.read(lambda tx: tx.all(
            "select id, request from commands where station = ? and answered_at is null "
            "order by id", station))
        return [(r["id"], json.loads(r["request"])) for r in rows]

    def answer(self, command_id: int, answer: dict[str, Any]) -> None:
        self.store.engine.write(lambda tx: tx.run(
            "update commands set answered_at = ?, answer = ? where id = ?",
            time.time(), json.dumps(answer, default=float), command_id))

    def wait_answer(self, command_id: int, timeout: float) -> dict[str, Any] | None:
        """The station's answer, or None if none came within ``timeout`` seconds."""
        end = time.monotonic() + timeout
        while True:
            row = self.store.engine.read(lambda tx: tx.one(
                "select answer from commands where id = ?", command_id))
            if row and row["answer"] is not None:
                return json.loads(row["answer"])
            if time.monotonic() > end:
                return None
            time.sleep(0.1)


def channel(station: str) -> str:
    """The LISTEN/NOTIFY channel of a station (a plain identifier whatever its name)."""
    return "station_" + hashlib.sha1(station.encode()).hexdigest()[:16]


def open_store(config) -> JobStore:
    """The configured job store: ``[store] url`` if set, else the SQLite file at ``path``."""
    url = config["store"]["url"]
    location = url if is_server_url(url) else config.resolve(url or config["store"]["path"])
    try:
        return JobStore(location, **({"outage_seconds": config["station"]["outage_s"]}
                                     if is_server_url(url) else {}))
    except (StoreUnavailable, SchemaTooNew) as exc:
        raise JobStoreError(str(exc)) from None  # one line for the operator, exit 2
    except sqlite3.DatabaseError as exc:  # a JSON file, a folder: anything but a job store
        raise JobStoreError(f"{location}: not a job store ({exc})") from None


def station_info(config, machine=None) -> StationInfo:
    """This station as the fleet sees it: ``[station] name`` and the machine profile."""
    machine = machine or default_machine()
    x0, y0, x1, y1 = machine.work_area
    return StationInfo(config["station"]["name"], machine.tool, (x1 - x0, y1 - y0),
                       config["machine"]["profile"] or "built-in")
