"""The job store: jobs, their pieces' cut state and an event log, in SQLite.

Nothing may be lost when the daemon is killed or the power fails, so every state change
is one short transaction (``BEGIN IMMEDIATE`` … ``COMMIT``) in WAL mode with
``synchronous=FULL``: once a call returns, the change is on disk. A piece is marked cut
only by its sync point (see `gcode.stream`), in the same transaction as the event that
records it, so the log and the state never disagree.

The schema is plain DDL that is safe to run on every start.
"""

from __future__ import annotations

import json
import re
import sqlite3
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

STATES = ("submitted", "capturing", "planning", "ready", "cutting", "done",
          "paused", "failed", "aborted")
ACTIVE = ("capturing", "planning", "ready", "cutting")
FINAL = ("done", "failed", "aborted")

# Allowed transitions: the happy path, plus pause/fail/abort from any active state.
TRANSITIONS: dict[str, tuple[str, ...]] = {
    "submitted": ("capturing", "planning", "aborted", "failed"),
    "capturing": ("planning", "paused", "failed", "aborted"),
    "planning": ("ready", "paused", "failed", "aborted"),
    "ready": ("cutting", "paused", "failed", "aborted"),
    "cutting": ("done", "paused", "failed", "aborted"),
    "paused": ("capturing", "planning", "ready", "cutting", "failed", "aborted"),
    "failed": ("submitted",),  # retry
    "aborted": ("submitted",),  # retry
    "done": (),
}

PIECE_STATES = ("pending", "cutting", "cut")

_SCHEMA = """
create table if not exists jobs (
    id integer primary key autoincrement,
    garment text not null,
    fabric text,                       -- FABRIC.json path, or null to detect from the camera
    options text not null default '{}',
    state text not null default 'submitted',
    reason text not null default '',
    resume_state text,                 -- where a paused job goes back to
    submitted_at real not null,
    updated_at real not null,
    plan text                          -- JSON: files the planning step wrote
);
create table if not exists pieces (
    job_id integer not null references jobs(id),
    piece integer not null,
    name text not null,
    state text not null default 'pending',
    cut_at real,
    primary key (job_id, piece)
);
create table if not exists events (
    id integer primary key autoincrement,
    job_id integer references jobs(id),
    at real not null,
    kind text not null,
    message text not null
);
create index if not exists events_job on events(job_id, id);
"""


_SCHEMA_NAMES = set(re.findall(r"create (?:table|index) if not exists (\w+)", _SCHEMA))


class JobStoreError(ValueError):
    """A request the store refuses (unknown job, forbidden transition); nothing changed."""


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

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


class JobStore:
    """SQLite-backed jobs, pieces and events; safe to share between threads."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.RLock()
        self._conn = sqlite3.connect(self.path, isolation_level=None, timeout=5.0,
                                     check_same_thread=False)
        self._conn.row_factory = sqlite3.Row
        self._conn.execute("pragma journal_mode=wal")
        self._conn.execute("pragma synchronous=full")
        self._conn.execute("pragma foreign_keys=on")
        self._conn.execute("pragma busy_timeout=5000")
        with self._lock:
            self._create_schema()

    def _create_schema(self, timeout: float = 30.0) -> None:
        """The tables, unless they all exist (read first: reading never waits in WAL mode).

        Why: creating them takes the write lock, and the busy handler only polls for it, so
        a process committing in a tight loop (the daemon while a second store opens the
        file it has just created) can hold it past the busy timeout ("database is locked")
        although it has created them meanwhile. So the write is tried in short waits, and
        the schema looked for again between them.
        """
        end = time.monotonic() + timeout
        while not _SCHEMA_NAMES <= {r[0] for r in self._conn.execute(
                "select name from sqlite_master")}:
            self._conn.execute("pragma busy_timeout=100")
            try:
                self._conn.executescript(_SCHEMA)
            except sqlite3.OperationalError as exc:
                if "locked" not in str(exc) or time.monotonic() > end:
                    raise
            finally:
                self._conn.execute("pragma busy_timeout=5000")

    def close(self) -> None:
        with self._lock:
            self._conn.close()

    @contextmanager
    def transaction(self) -> Iterator[sqlite3.Cursor]:
        """One atomic, durable change: committed on success, rolled back on error."""
        with self._lock:
            cur = self._conn.cursor()
            cur.execute("begin immediate")
            try:
                yield cur
            except BaseException:
                cur.execute("rollback")
                raise
            cur.execute("commit")

    # ------------------------------------------------------------------ jobs
    def submit(self, garment: str, fabric: str | None, options: dict[str, Any]) -> Job:
        now = time.time()
        with self.transaction() as cur:
            cur.execute(
                "insert into jobs (garment, fabric, options, submitted_at, updated_at) "
                "values (?, ?, ?, ?, ?)",
                (garment, fabric, json.dumps(options, sort_keys=True), now, now),
            )
            job_id = cur.lastrowid
            self._event(cur, job_id, "submitted", f"garment {garment}, fabric "
                        f"{fabric or 'detected from the camera'}")
        return self.job(job_id)

    def job(self, job_id: int) -> Job:
        row = self._conn.execute("select * from jobs where id = ?", (job_id,)).fetchone()
        if row is None:
            raise JobStoreError(f"no job {job_id}")
        return _job(row)

    def jobs(self, states: tuple[str, ...] | None = None) -> list[Job]:
        if states:
            marks = ",".join("?" * len(states))
            rows = self._conn.execute(f"select * from jobs where state in ({marks}) "
                                      "order by id", states)
        else:
            rows = self._conn.execute("select * from jobs order by id")
        return [_job(r) for r in rows.fetchall()]

    def next_job(self) -> Job | None:
        """The oldest job waiting to run: one interrupted mid-way first, then submitted."""
        row = self._conn.execute(
            "select * from jobs where state in ('capturing','planning','ready','cutting',"
            "'submitted') order by case when state = 'submitted' then 1 else 0 end, id limit 1"
        ).fetchone()
        return None if row is None else _job(row)

    def transition(self, job_id: int, new_state: str, reason: str = "") -> Job:
        """Move a job to ``new_state`` if allowed; the event records why."""
        if new_state not in STATES:
            raise JobStoreError(f"unknown job state {new_state!r}")
        with self.transaction() as cur:
            row = cur.execute("select state, resume_state from jobs where id = ?",
                              (job_id,)).fetchone()
            if row is None:
                raise JobStoreError(f"no job {job_id}")
            old = row["state"]
            if new_state not in TRANSITIONS[old]:
                raise JobStoreError(f"job {job_id} is {old}; it cannot become {new_state}")
            resume = old if new_state == "paused" else None
            cur.execute("update jobs set state = ?, reason = ?, resume_state = ?, "
                        "updated_at = ? where id = ?",
                        (new_state, reason, resume, time.time(), job_id))
            if new_state == "submitted":  # retry: start the plan afresh, keep cut pieces
                cur.execute("update jobs set plan = null where id = ?", (job_id,))
            self._event(cur, job_id, "state", f"{old} -> {new_state}"
                        + (f": {reason}" if reason else ""))
        return self.job(job_id)

    def set_plan(self, job_id: int, plan: dict[str, Any]) -> None:
        with self.transaction() as cur:
            cur.execute("update jobs set plan = ?, updated_at = ? where id = ?",
                        (json.dumps(plan), time.time(), job_id))

    # ------------------------------------------------------------------ pieces
    def set_pieces(self, job_id: int, names: list[str]) -> None:
        """Declare the job's pieces once planning knows them; cut states are kept."""
        with self.transaction() as cur:
            cur.executemany(
                "insert or ignore into pieces (job_id, piece, name) values (?, ?, ?)",
                [(job_id, i, n) for i, n in enumerate(names)],
            )

    def pieces(self, job_id: int) -> list[dict[str, Any]]:
        rows = self._conn.execute("select piece, name, state, cut_at from pieces "
                                  "where job_id = ? order by piece", (job_id,))
        return [dict(r) for r in rows.fetchall()]

    def set_piece_state(self, job_id: int, piece: int, state: str) -> None:
        """Record a piece's cut state; 'cut' is final and is never undone or repeated."""
        if state not in PIECE_STATES:
            raise JobStoreError(f"unknown piece state {state!r}")
        with self.transaction() as cur:
            row = cur.execute("select state, name from pieces where job_id = ? and piece = ?",
                              (job_id, piece)).fetchone()
            if row is None:
                raise JobStoreError(f"job {job_id} has no piece {piece}")
            if row["state"] == "cut":
                raise JobStoreError(f"piece {piece} ({row['name']}) of job {job_id} is "
                                    "already cut")
            cur.execute("update pieces set state = ?, cut_at = ? where job_id = ? and piece = ?",
                        (state, time.time() if state == "cut" else None, job_id, piece))
            self._event(cur, job_id, "piece", f"piece {piece} ({row['name']}) {state}")

    def reset_unfinished_pieces(self, job_id: int) -> int:
        """After an interruption the piece in progress is not cut: back to pending."""
        with self.transaction() as cur:
            cur.execute("update pieces set state = 'pending' where job_id = ? "
                        "and state = 'cutting'", (job_id,))
            return cur.rowcount

    # ------------------------------------------------------------------ events
    def log(self, job_id: int | None, kind: str, message: str) -> None:
        with self.transaction() as cur:
            self._event(cur, job_id, kind, message)

    def events(self, job_id: int | None = None, after: int = 0) -> list[dict[str, Any]]:
        if job_id is None:
            rows = self._conn.execute("select * from events where id > ? order by id", (after,))
        else:
            rows = self._conn.execute("select * from events where job_id = ? and id > ? "
                                      "order by id", (job_id, after))
        return [dict(r) for r in rows.fetchall()]

    @staticmethod
    def _event(cur: sqlite3.Cursor, job_id: int | None, kind: str, message: str) -> None:
        cur.execute("insert into events (job_id, at, kind, message) values (?, ?, ?, ?)",
                    (job_id, time.time(), kind, message))


def _job(row: sqlite3.Row) -> Job:
    return Job(
        id=row["id"], garment=row["garment"], fabric=row["fabric"],
        options=json.loads(row["options"]), state=row["state"], reason=row["reason"],
        resume_state=row["resume_state"], submitted_at=row["submitted_at"],
        updated_at=row["updated_at"], plan=json.loads(row["plan"]) if row["plan"] else None,
    )
