"""Job stores for the station tests: an SQLite file, or a database on a real PostgreSQL
server that this test session starts itself (`station.localpg`, once per session).

Without a server the PostgreSQL cases skip with the reason here, but fail under CI
(CI=true): there the server must be had, and a silent skip would hide that it was not.
"""

from __future__ import annotations

import os
import uuid

import pytest

from station.localpg import LocalPostgres, PostgresUnavailable


@pytest.fixture(scope="session")
def postgres():
    """One real PostgreSQL server for the whole session."""
    try:
        server = LocalPostgres().start()
    except (PostgresUnavailable, OSError) as exc:
        if os.environ.get("CI"):
            pytest.fail(f"CI needs a PostgreSQL server and none started: {exc}")
        pytest.skip(f"no PostgreSQL server here: {exc}")
    yield server
    server.close()


@pytest.fixture
def pg_url(postgres) -> str:
    """A fresh, empty database on the session's server."""
    return postgres.create_database(f"t_{uuid.uuid4().hex[:12]}")


@pytest.fixture(params=["sqlite", "postgresql"])
def store_location(request, tmp_path) -> str:
    """Where a job store lives: each store test runs on both engines."""
    if request.param == "sqlite":
        return str(tmp_path / "jobs.db")
    return request.getfixturevalue("pg_url")
