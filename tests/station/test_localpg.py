"""The bundled test PostgreSQL is reachable by its user only: no TCP address, one Unix
socket in a folder that user owns, mode 0700 (trust authentication is safe only so)."""

from __future__ import annotations

import os
import stat

import psycopg


def test_the_test_server_listens_only_on_a_socket_in_a_folder_its_user_owns(postgres):
    folder = os.stat(postgres.socket_dir)
    assert stat.S_IMODE(folder.st_mode) == 0o700
    server_uid = os.stat(postgres.data).st_uid  # the data folder is the server user's
    assert folder.st_uid == server_uid
    assert (postgres.socket_dir / f".s.PGSQL.{postgres.port}").is_socket()
    assert "127.0.0.1" not in postgres.url and f"host={postgres.socket_dir}" in postgres.url
    with psycopg.connect(postgres.url) as conn:
        listen, address = conn.execute(
            "select current_setting('listen_addresses'), inet_server_addr()").fetchone()
    assert listen == "" and address is None  # connected over the socket; no TCP at all
