"""The job store's schema as numbered migrations, the same on SQLite and PostgreSQL.

A store records the migrations applied to it (``schema_version``). Opening a store
applies the missing ones in one transaction (on PostgreSQL under an advisory lock, so
stations starting together upgrade it once); a store whose schema is newer than this
station knows is refused: an old station must not write rows it does not understand.
A file from before versioning has the version-1 tables and no ``schema_version``; the
version-1 DDL is safe to re-run on it.
"""

from __future__ import annotations

import sqlite3
import time

from station.storeengine import DIALECTS, Engine, Tx

#: (version, what it adds, DDL with {id} and {real} for the engine's types).
MIGRATIONS: list[tuple[int, str, str]] = [
    (1, "jobs, pieces and events", """
create table if not exists jobs (
    id {id},
    garment text not null,
    fabric text,
    options text not null default '{{}}',
    state text not null default 'submitted',
    reason text not null default '',
    resume_state text,
    submitted_at {real} not null,
    updated_at {real} not null,
    plan text
);
create table if not exists pieces (
    job_id integer not null references jobs(id),
    piece integer not null,
    name text not null,
    state text not null default 'pending',
    cut_at {real},
    primary key (job_id, piece)
);
create table if not exists events (
    id {id},
    job_id integer references jobs(id),
    at {real} not null,
    kind text not null,
    message text not null
);
create index if not exists events_job on events(job_id, id)
"""),
    (2, "stations, job requirements and owners, remote commands", """
alter table jobs add column owner text;
alter table jobs add column req_tool text;
alter table jobs add column req_x_mm {real};
alter table jobs add column req_y_mm {real};
alter table jobs add column req_station text;
create index jobs_state on jobs(state, id);
create table stations (
    name text primary key,
    tool text not null,
    table_x_mm {real} not null,
    table_y_mm {real} not null,
    profile text not null default '',
    state text not null default 'idle',
    job_id integer,
    progress text not null default '{{}}',
    started_at {real} not null,
    heartbeat_at {real} not null
);
create table commands (
    id {id},
    station text not null,
    request text not null,
    at {real} not null,
    answered_at {real},
    answer text
);
create index commands_open on commands(station, answered_at, id)
"""),
    (3, "progress within a piece", """
alter table pieces add column cut_mm {real};
alter table pieces add column path_mm {real}
"""),
    (4, "the bite each piece is cut in (a marker longer than the table)", """
alter table pieces add column bite integer
"""),
]

SCHEMA_VERSION = MIGRATIONS[-1][0]


class SchemaTooNew(RuntimeError):
    """The store was upgraded by a newer station; this one must not touch it."""


def migrate(engine: Engine) -> int:
    """Bring the store up to `SCHEMA_VERSION`; the version it is at afterwards."""

    def version(tx: Tx) -> int | None:
        names = {"sqlite": "select name from sqlite_master where name = 'schema_version'",
                 "postgresql": "select to_regclass('schema_version') as name"}
        found = tx.one(names[tx.dialect])
        if not found or found["name"] is None:
            return None
        row = tx.one("select max(version) as v from schema_version")
        return int(row["v"]) if row and row["v"] is not None else 0

    current = engine.read(version)  # no write lock when there is nothing to do
    if current == SCHEMA_VERSION:
        return current

    def work(tx: Tx) -> int:
        if tx.dialect == "postgresql":
            tx.run("select pg_advisory_xact_lock(19190019)")
        tx.run(f"create table if not exists schema_version (version integer primary key, "
               f"description text not null, applied_at {DIALECTS[tx.dialect]['real']} "
               f"not null)")
        row = tx.one("select max(version) as v from schema_version")
        current = int(row["v"]) if row and row["v"] is not None else 0
        if current > SCHEMA_VERSION:
            raise SchemaTooNew(f"{engine.location}: the job store's schema is version "
                               f"{current}, newer than this station's {SCHEMA_VERSION}; "
                               "upgrade the station")
        for version, description, ddl in MIGRATIONS:
            if version <= current:
                continue
            for statement in ddl.format(**DIALECTS[tx.dialect]).split(";"):
                if statement.strip():
                    tx.run(statement)
            tx.run("insert into schema_version (version, description, applied_at) "
                   "values (?, ?, ?)", version, description, time.time())
        return max(current, SCHEMA_VERSION)

    if engine.dialect != "sqlite":
        return engine.write(work)
    # SQLite's busy handler only polls for the write lock: a process committing in a tight
    # loop (the daemon, right after it created the file) can hold it past any busy timeout
    # although it has migrated meanwhile ("database is locked"). So: short tries, and the
    # version looked at again between them.
    end = time.monotonic() + 30.0
    while True:
        try:
            return engine.write(work, patience=0.1)
        except sqlite3.OperationalError:
            if engine.read(version) == SCHEMA_VERSION:
                return SCHEMA_VERSION
            if time.monotonic() > end:
                raise
