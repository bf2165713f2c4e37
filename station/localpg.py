"""A private PostgreSQL server in a folder, for the tests, the benchmark and the fleet demo.

The server binaries come from the ``pgserver`` wheel (PostgreSQL 16 built for manylinux,
installed by pip into the venv like every other dependency: nothing to install by hand,
no root, no package mirror), else from ``$STATION_PG_BIN``, the ``PATH`` or Debian's
``/usr/lib/postgresql/*/bin``. Only the binaries are used: pgserver's own manager widens
the permissions of every folder above its data folder and adds users, which a test has
no business doing. PostgreSQL refuses to run as root, so under root (CI) the server runs
as the ``postgres`` user, else ``nobody``.

The server listens on no TCP address at all, only on a Unix socket in a folder of its own
(mode 0700, owned by the user it runs as), with trust authentication: only that user (and
root) can reach it. It is a throw-away server for one test session or one demo, never a
shop's database.
"""

from __future__ import annotations

import glob
import importlib.util
import os
import pwd
import shutil
import subprocess
import tempfile
from pathlib import Path

from station.storeengine import connect_postgres


class PostgresUnavailable(RuntimeError):
    """No PostgreSQL server binaries could be found or started here."""


def server_bin(user: pwd.struct_passwd | None = None) -> Path:
    """The folder holding ``initdb``, ``pg_ctl`` and ``postgres`` (that ``user`` can run:
    a venv under a folder closed to others, such as /root, is skipped for the next)."""
    candidates: list[Path] = []
    if os.environ.get("STATION_PG_BIN"):
        candidates.append(Path(os.environ["STATION_PG_BIN"]))
    spec = importlib.util.find_spec("pgserver")
    if spec is not None and spec.submodule_search_locations:
        candidates.append(Path(spec.submodule_search_locations[0]) / "pginstall" / "bin")
    on_path = shutil.which("pg_ctl")
    if on_path:
        candidates.append(Path(on_path).resolve().parent)
    candidates += [Path(p) for p in sorted(glob.glob("/usr/lib/postgresql/*/bin"),
                                           reverse=True)]
    for folder in candidates:
        if all((folder / exe).is_file() for exe in ("initdb", "pg_ctl", "postgres")) and \
                _runs_as(folder / "postgres", user):
            return folder
    raise PostgresUnavailable("no PostgreSQL server binaries: `pip install pgserver` (the "
                              "dev extra does), or install Debian's postgresql")


def _runs_as(exe: Path, user: pwd.struct_passwd | None) -> bool:
    if user is None:
        return True
    try:
        return subprocess.run([str(exe), "-V"], user=user.pw_uid, group=user.pw_gid,
                              extra_groups=[], capture_output=True, timeout=30,
                              cwd="/").returncode == 0
    except OSError:
        return False


def _server_user() -> pwd.struct_passwd | None:
    """Who runs the server: nobody special, unless we are root (PostgreSQL refuses it)."""
    if os.geteuid() != 0:
        return None
    for name in ("postgres", "nobody"):
        try:
            return pwd.getpwnam(name)
        except KeyError:
            continue
    raise PostgresUnavailable("running as root, and neither a postgres nor a nobody user "
                              "exists to run the server")


class LocalPostgres:
    """initdb, start, stop, crash and restart one server; ``url`` connects to it.

    ``folder`` (default: a new one under the system's temporary folder) holds the data
    and the log; the socket is in a short folder of its own. Under root every folder above
    the data must be open to the server's user, so leave the default there.
    """

    def __init__(self, folder: str | Path | None = None) -> None:
        self._user = _server_user()
        self.bin = server_bin(self._user)
        self.folder = Path(folder or tempfile.mkdtemp(prefix="station-pg-"))
        self.folder.mkdir(parents=True, exist_ok=True)
        self.data = self.folder / "data"
        self.logfile = self.folder / "server.log"
        # the socket's own short folder: a Unix socket path is at most 107 bytes
        self.socket_dir = Path(tempfile.mkdtemp(prefix="station-pg-socket-"))
        self.port = 5432  # names the socket file only (.s.PGSQL.5432): no TCP port is opened
        os.chmod(self.socket_dir, 0o700)
        if self._user is not None:
            os.chmod(self.folder, 0o755)
            os.chown(self.folder, self._user.pw_uid, self._user.pw_gid)
            os.chown(self.socket_dir, self._user.pw_uid, self._user.pw_gid)

    @property
    def url(self) -> str:
        return self.url_for("postgres")

    def url_for(self, database: str) -> str:
        return f"postgresql://postgres@/{database}?host={self.socket_dir}&port={self.port}"

    def _run(self, *args: str, timeout: float = 60.0) -> None:
        kwargs = {}
        if self._user is not None:
            kwargs = {"user": self._user.pw_uid, "group": self._user.pw_gid,
                      "extra_groups": []}
        env = {**os.environ, "LC_ALL": "C", "HOME": str(self.folder)}
        result = subprocess.run([str(self.bin / args[0]), *args[1:]], cwd=self.folder,
                                env=env, capture_output=True, text=True, timeout=timeout,
                                **kwargs)
        if result.returncode != 0:
            log = self.logfile.read_text(errors="replace")[-1500:] \
                if self.logfile.exists() else ""
            raise PostgresUnavailable(f"{args[0]} failed ({result.returncode}): "
                                      f"{result.stderr.strip()[-800:]} {log}".strip())

    def start(self) -> LocalPostgres:
        """Create the cluster on first start; return when it accepts connections."""
        if not (self.data / "PG_VERSION").exists():
            self._run("initdb", "-D", str(self.data), "-U", "postgres", "--auth=trust",
                      "-E", "UTF8", "--no-sync")
        options = (f"-p {self.port} -k {self.socket_dir} -c listen_addresses='' "
                   "-c unix_socket_permissions=0700 -c max_connections=200")
        self._run("pg_ctl", "-D", str(self.data), "-l", str(self.logfile), "-o", options,
                  "-w", "-t", "60", "start")
        return self

    def stop(self, mode: str = "fast") -> None:
        """Stop the server: ``fast`` (clean) or ``immediate`` (as a crash would)."""
        if (self.data / "postmaster.pid").exists():
            self._run("pg_ctl", "-D", str(self.data), "-m", mode, "-w", "stop")

    def restart(self, mode: str = "immediate") -> None:
        self.stop(mode)
        self.start()

    def create_database(self, name: str) -> str:
        """A fresh, empty database; its URL."""
        with connect_postgres(self.url) as conn:
            conn.execute(f'create database "{name}"')
        return self.url_for(name)

    def close(self) -> None:
        """Stop the server (no final checkpoint: it is thrown away) and delete its folder."""
        try:
            self.stop("immediate")
        finally:
            shutil.rmtree(self.folder, ignore_errors=True)
            shutil.rmtree(self.socket_dir, ignore_errors=True)

    def __enter__(self) -> LocalPostgres:
        return self.start()

    def __exit__(self, *_exc) -> None:
        self.close()

