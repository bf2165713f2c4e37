"""The job store: jobs, their pieces' cut state and an event log, in SQLite or PostgreSQL.

Nothing may be lost when the daemon is killed or the power fails, so every state change
is one short transaction (see `station.storeengine`: SQLite in WAL mode with
``synchronous=FULL``, or a PostgreSQL server): once a call returns, the change is stored.
A piece is marked cut only by its sync point (see `gcode.stream`), in the same
transaction as the event that records it, so the log and the state never disagree.

The location is a path (SQLite, the embedded default for one table) or a
``postgresql://`` URL (one server for a room of stations, see `station.fleet`). The
schema is versioned (`station.storeschema`).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gcode.resume import OVERLAP_MM
from station.storeengine import Engine, Tx, open_engine
from station.storeschema import migrate

STATES = ("submitted", "capturing", "planning", "ready", "cutting", "done",
          "paused", "interrupted", "failed", "aborted")
ACTIVE = ("capturing", "planning", "ready", "cutting")
FINAL = ("done", "failed", "aborted")

# Allowed transitions: the happy path, plus pause/fail/abort from any active state.
# "interrupted": the station that owned the job stopped (its heartbeat ended); only that
# station resumes it (it alone knows its controller's markers), or an operator reassigns
# it ("submitted" again: the new station re-detects the fabric and cuts what is not cut).
TRANSITIONS: dict[str, tuple[str, ...]] = {
    "submitted": ("capturing", "planning", "aborted", "failed"),
    "capturing": ("planning", "paused", "interrupted", "failed", "aborted"),
    "planning": ("ready", "paused", "interrupted", "failed", "aborted"),
    "ready": ("cutting", "paused", "interrupted", "failed", "aborted"),
    "cutting": ("done", "paused", "interrupted", "failed", "aborted"),
    "paused": ("capturing", "planning", "ready", "cutting", "submitted", "failed",
               "aborted"),
    "interrupted": ("capturing", "planning", "ready", "cutting", "submitted", "failed",
                    "aborted"),
    "failed": ("submitted",),  # retry
    "aborted": ("submitted",),  # retry
    "done": (),
}

PIECE_STATES = ("pending", "cutting", "cut")
#: PostgreSQL NOTIFY channel told whenever a job becomes claimable (fleet stations LISTEN)
JOBS_CHANNEL = "station_jobs"
TOOLS = ("laser", "knife")


class JobStoreError(ValueError):
    """A request the store refuses (unknown job, forbidden transition); nothing changed."""


@dataclass(frozen=True)
class Requirements:
    """What a station must have to take a job: a tool, a table at least this large
    (machine x and y travel, mm), or one station by name. None: anything goes."""

    tool: str | None = None
    table_mm: tuple[float, float] | None = None
    station: str | None = None

    def __post_init__(self) -> None:
        if self.tool is not None and self.tool not in TOOLS:
            raise JobStoreError(f"tool must be one of {', '.join(TOOLS)}, got {self.tool!r}")
        if self.table_mm is not None and (len(self.table_mm) != 2
                                          or min(self.table_mm) <= 0):
            raise JobStoreError(f"table size must be two positive mm, got {self.table_mm!r}")

    def to_dict(self) -> dict[str, Any]:
        return {"tool": self.tool, "table_mm": list(self.table_mm) if self.table_mm else None,
                "station": self.station}


@dataclass(frozen=True)
class Job:
    id: int
    garment: str
    fabric: str | None
    options: dict[str, Any]
    state: str
    reason: str
    resume_state: str | None
    submitted_at: float
    updated_at: float
    plan: dict[str, Any] | None
    owner: str | None = None
    requirements: Requirements = Requirements()

    def to_dict(self) -> dict[str, Any]:
        out = dict(self.__dict__)
        out["requirements"] = self.requirements.to_dict()
        return out


class JobStore:
    """Jobs, pieces and events on one engine; safe to share between threads.

    ``location`` is an SQLite path or a ``postgresql://`` URL; ``engine_options`` go to
    `station.storeengine.PostgresEngine` (outage wait and hook).
    """

    def __init__(self, location: str | Path, **engine_options: Any) -> None:
        self.engine: Engine = open_engine(location, **engine_options)
        self.location = self.engine.location
        self.schema_version = migrate(self.engine)

    def close(self) -> None:
        self.engine.close()

    # ------------------------------------------------------------------ jobs
    def submit(self, garment: str, fabric: str | None, options: dict[str, Any],
               requirements: Requirements | None = None) -> Job:
        req = requirements or Requirements()
        now = time.time()

        def work(tx: Tx) -> int:
            row = tx.one(
                "insert into jobs (garment, fabric, options, submitted_at, updated_at, "
                "req_tool, req_x_mm, req_y_mm, req_station) values (?, ?, ?, ?, ?, ?, ?, ?, ?) "
                "returning id",
                garment, fabric, json.dumps(options, sort_keys=True), now, now, req.tool,
                req.table_mm[0] if req.table_mm else None,
                req.table_mm[1] if req.table_mm else None, req.station)
            needs = describe(req)
            self._event(tx, row["id"], "submitted", f"garment {garment}, fabric "
                        f"{fabric or 'detected from the camera'}"
                        + (f"; needs {needs}" if needs else ""))
            announce(tx)
            return row["id"]

        return self.job(self.engine.write(work))

    def job(self, job_id: int) -> Job:
        row = self.engine.read(lambda tx: tx.one("select * from jobs where id = ?", job_id))
        if row is None:
            raise JobStoreError(f"no job {job_id}")
        return job_from_row(row)

    def jobs(self, states: tuple[str, ...] | None = None) -> list[Job]:
        if states:
            marks = ",".join("?" * len(states))
            rows = self.engine.read(lambda tx: tx.all(
                f"select * from jobs where state in ({marks}) order by id", *states))
        else:
            rows = self.engine.read(lambda tx: tx.all("select * from jobs order by id"))
        return [job_from_row(r) for r in rows]

    def next_job(self) -> Job | None:
        """The oldest job waiting to run: one interrupted mid-way first, then submitted
        (one station alone on its store; a fleet claims with `station.fleet.claim`)."""
        row = self.engine.read(lambda tx: tx.one(
            "select * from jobs where state in ('capturing','planning','ready','cutting',"
            "'submitted') order by case when state = 'submitted' then 1 else 0 end, id "
            "limit 1"))
        return None if row is None else job_from_row(row)

    def transition(self, job_id: int, new_state: str, reason: str = "") -> Job:
        """Move a job to ``new_state`` if allowed; the event records why."""
        if new_state not in STATES:
            raise JobStoreError(f"unknown job state {new_state!r}")
        self.engine.write(lambda tx: self.transition_in(tx, job_id, new_state, reason))
        return self.job(job_id)

    def transition_in(self, tx: Tx, job_id: int, new_state: str, reason: str = "",
                      owner: str | None = None) -> str:
        """`transition` inside a caller's transaction (``owner`` also set if given);
        the state it left."""
        row = tx.one("select state, resume_state from jobs where id = ?", job_id)
        if row is None:
            raise JobStoreError(f"no job {job_id}")
        old = row["state"]
        if new_state not in TRANSITIONS[old]:
            raise JobStoreError(f"job {job_id} is {old}; it cannot become {new_state}")
        resume = old if new_state in ("paused", "interrupted") else None
        tx.run("update jobs set state = ?, reason = ?, resume_state = ?, updated_at = ? "
               "where id = ?", new_state, reason, resume, time.time(), job_id)
        if owner is not None:
            tx.run("update jobs set owner = ? where id = ?", owner, job_id)
        if new_state == "submitted":  # retry: start the plan afresh, keep cut pieces
            tx.run("update jobs set plan = null where id = ?", job_id)
            announce(tx)
        self._event(tx, job_id, "state", f"{old} -> {new_state}"
                    + (f": {reason}" if reason else ""))
        return old

    def set_inputs(self, job_id: int, garment: str, fabric: str | None) -> None:
        """The job's checked copies of its inputs replace the paths it was queued with."""
        def work(tx: Tx) -> None:
            tx.run("update jobs set garment = ?, fabric = ?, updated_at = ? where id = ?",
                   garment, fabric, time.time(), job_id)
            self._event(tx, job_id, "intake", f"inputs copied and checked: {garment}"
                        + (f", {fabric}" if fabric else ""))

        self.engine.write(work)

    def set_plan(self, job_id: int, plan: dict[str, Any]) -> None:
        self.engine.write(lambda tx: tx.run(
            "update jobs set plan = ?, updated_at = ? where id = ?",
            json.dumps(plan), time.time(), job_id))

    def summary(self, job: Job) -> dict[str, Any]:
        """What the console shows of a job: state, owner, piece counts, times."""
        pieces = self.pieces(job.id)
        counts = {s: sum(p["state"] == s for p in pieces) for s in PIECE_STATES}
        out = {"id": job.id, "state": job.state, "reason": job.reason,
               "garment": job.garment, "fabric": job.fabric, "pieces": counts,
               "owner": job.owner, "requirements": job.requirements.to_dict(),
               "submitted_at": job.submitted_at, "updated_at": job.updated_at}
        garment_of = (job.plan or {}).get("garments")
        if isinstance(garment_of, dict):  # an order: its pieces counted per garment
            per: dict[str, dict[str, int]] = {}
            for p in pieces:
                c = per.setdefault(str(garment_of.get(p["name"], "-")), {"cut": 0, "total": 0})
                c["total"] += 1
                c["cut"] += p["state"] == "cut"
            out["garments"] = per
        return out

    # ------------------------------------------------------------------ pieces
    def set_pieces(self, job_id: int, names: list[str]) -> None:
        """Declare the job's pieces once planning knows them; cut states are kept."""

        def work(tx: Tx) -> None:
            known = {r["piece"] for r in tx.all("select piece from pieces where job_id = ?",
                                                job_id)}
            new = [(job_id, i, n) for i, n in enumerate(names) if i not in known]
            if new:
                tx.many("insert into pieces (job_id, piece, name) values (?, ?, ?)", new)

        self.engine.write(work)

    def pieces(self, job_id: int) -> list[dict[str, Any]]:
        return self.engine.read(lambda tx: tx.all(
            "select piece, name, state, cut_at, cut_mm, path_mm, bite from pieces "
            "where job_id = ? "
            "order by piece",
            job_id))

    def set_piece_bites(self, job_id: int, bites: dict[str, int]) -> None:
        """Journal the bite each piece (by name) is cut in, before the first bite is cut."""
        self.engine.write(lambda tx: tx.many(
            "update pieces set bite = ? where job_id = ? and name = ?",
            [(int(b), job_id, name) for name, b in bites.items()]))

    def set_piece_state(self, job_id: int, piece: int, state: str) -> None:
        """Record a piece's cut state; 'cut' is final and is never undone or repeated."""
        if state not in PIECE_STATES:
            raise JobStoreError(f"unknown piece state {state!r}")

        def work(tx: Tx) -> None:
            row = tx.one("select state, name from pieces where job_id = ? and piece = ?",
                         job_id, piece)
            if row is None:
                raise JobStoreError(f"job {job_id} has no piece {piece}")
            if row["state"] == "cut":
                if state == "cut" and getattr(self.engine, "retried", False):
                    return  # our own commit landed before the link dropped
                raise JobStoreError(f"piece {piece} ({row['name']}) of job {job_id} is "
                                    "already cut")
            tx.run("update pieces set state = ?, cut_at = ? where job_id = ? and piece = ?",
                   state, time.time() if state == "cut" else None, job_id, piece)
            self._event(tx, job_id, "piece", f"piece {piece} ({row['name']}) {state}")

        self.engine.write(work)

    def set_piece_progress(self, job_id: int, piece: int, cut_mm: float, path_mm: float
                           ) -> None:
        """Journal how far along its strokes an unfinished piece was cut (mm of ``path_mm``):
        a resumed piece continues from there (see `gcode.resume`). No event: it is written
        several times a second while cutting."""
        self.engine.write(lambda tx: tx.run(
            "update pieces set cut_mm = ?, path_mm = ? where job_id = ? and piece = ? "
            "and state != 'cut'", float(cut_mm), float(path_mm), job_id, piece))

    def reset_unfinished_pieces(self, job_id: int) -> int:
        """After an interruption the piece in progress is not cut: back to pending."""
        return self.engine.write(lambda tx: tx.run(
            "update pieces set state = 'pending' where job_id = ? and state = 'cutting'",
            job_id))

    # ------------------------------------------------------------------ events
    def log(self, job_id: int | None, kind: str, message: str) -> None:
        self.engine.write(lambda tx: self._event(tx, job_id, kind, message))

    def events(self, job_id: int | None = None, after: int = 0) -> list[dict[str, Any]]:
        if job_id is None:
            return self.engine.read(lambda tx: tx.all(
                "select * from events where id > ? order by id", after))
        return self.engine.read(lambda tx: tx.all(
            "select * from events where job_id = ? and id > ? order by id", job_id, after))

    @staticmethod
    def _event(tx: Tx, job_id: int | None, kind: str, message: str) -> None:
        tx.run("insert into events (job_id, at, kind, message) values (?, ?, ?, ?)",
               job_id, time.time(), kind, message)


def announce(tx: Tx) -> None:
    """Tell listening stations a job can be claimed (PostgreSQL: sent at commit)."""
    if tx.dialect == "postgresql":
        tx.run(f"notify {JOBS_CHANNEL}")


def describe(req: Requirements) -> str:
    """The requirements in words, for events and the console ('' when none)."""
    parts = []
    if req.tool:
        parts.append(req.tool)
    if req.table_mm:
        parts.append(f"table >= {req.table_mm[0]:g} x {req.table_mm[1]:g} mm")
    if req.station:
        parts.append(f"station {req.station}")
    return ", ".join(parts)


def job_from_row(row: dict[str, Any]) -> Job:
    x, y = row.get("req_x_mm"), row.get("req_y_mm")
    return Job(
        id=row["id"], garment=row["garment"], fabric=row["fabric"],
        options=json.loads(row["options"]), state=row["state"], reason=row["reason"],
        resume_state=row["resume_state"], submitted_at=row["submitted_at"],
        updated_at=row["updated_at"], plan=json.loads(row["plan"]) if row["plan"] else None,
        owner=row.get("owner"),
        requirements=Requirements(row.get("req_tool"),
                                  (x, y) if x is not None and y is not None else None,
                                  row.get("req_station")),
    )


def interrupted_reason(pieces: list[dict[str, Any]]) -> str:
    """"interrupted at piece 4 (back), 62 % cut: resume continues from there" for the
    piece the journal saw in progress; "" when none was."""
    partial = [p for p in pieces if p["state"] != "cut" and (p.get("cut_mm") or 0) > 0]
    if not partial:
        return ""
    p = partial[0]
    share = 100.0 * p["cut_mm"] / p["path_mm"] if p.get("path_mm") else 0.0
    return (f"interrupted at piece {p['piece']} ({p['name']}), {share:.0f} % cut: resume "
            f"continues from there ({OVERLAP_MM:g} mm back for a clean join)")
