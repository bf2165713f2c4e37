"""One daemon per job store, by the store's identity, held for the daemon's whole life.

A path says little: a symlink, a hard link or a bind mount reaches the same ``jobs.db``
by another name, and two fleet stations may share a name on one server. So the lock is
taken on the store itself:

- SQLite: an ``flock`` on the database file (its device and inode, whatever the path).
  SQLite locks with ``fcntl`` byte ranges, which Linux keeps apart from ``flock``, so the
  daemon's own store is never blocked. The descriptor stays open until the daemon has
  closed the store: closing another descriptor of the file would drop SQLite's locks.
- PostgreSQL: a session-level advisory lock keyed by the station's name, on a connection
  of its own; a second station of that name on that server is refused. The server drops
  it with the session, so `AdvisoryLock.still_held` takes it again after an outage (or
  says the name is now someone else's).

Every lock is released by the kernel or the server when the daemon dies however it dies:
a stale lock never blocks a restart. For a server store the work folder is also locked by
path (``<work_dir>.lock``), since two daemons must not share one folder of job files.
"""

from __future__ import annotations

import fcntl
import logging
import os
import stat
from pathlib import Path
from typing import Any, Protocol

from station.config import Config
from station.errors import UserError
from station.storeengine import connect_postgres, is_server_url, without_password

log = logging.getLogger("station.lock")


class AlreadyRunning(UserError):
    """Another daemon holds the lock: nothing was touched."""


class Lock(Protocol):
    def release(self) -> None: ...


def lock_path(config: Config) -> Path:
    """``<work_dir>.lock``: the work folder's lock, for a store on a server."""
    work = config.resolve(config["store"]["work_dir"])
    return work.with_name(work.name + ".lock")


class DaemonLock:
    """``with DaemonLock(path):`` holds an flock on a lock file at ``path``; a second holder
    gets AlreadyRunning. The file keeps the holder's pid for the refusal message."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._fd: int | None = None

    def acquire(self) -> DaemonLock:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o640)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            raise AlreadyRunning(f"station already running (pid {holder}); its lock is "
                                 f"{self.path}") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        self._fd = fd
        return self

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)  # closing drops the flock; the file stays for the next daemon
            self._fd = None

    @property
    def held(self) -> bool:
        return self._fd is not None

    def __enter__(self) -> DaemonLock:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()


class StoreFileLock:
    """An flock on the SQLite database file itself (created empty if missing, which SQLite
    reads as a new database)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._fd: int | None = None

    def acquire(self) -> StoreFileLock:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        try:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o640)
        except IsADirectoryError:
            raise UserError(f"{self.path}: the job store is a folder, expected a database "
                            "file") from None
        except OSError as exc:
            raise UserError(f"{self.path}: cannot open the job store ({exc.strerror})"
                            ) from None
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            os.close(fd)
            raise UserError(f"{self.path}: the job store is not a regular file")
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            holder = flock_holder(st.st_dev, st.st_ino) or "unknown"
            raise AlreadyRunning(f"station already running (pid {holder}) on the job store "
                                 f"{self.path} (device {st.st_dev}, inode {st.st_ino}, "
                                 "however it is named)") from None
        self._fd = fd
        return self

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    @property
    def held(self) -> bool:
        return self._fd is not None


def flock_holder(device: int, inode: int, table: str = "/proc/locks") -> int | None:
    """The pid holding an flock on the file (device, inode), from the kernel's lock table."""
    key = f"{os.major(device):02x}:{os.minor(device):02x}:{inode}"
    try:
        lines = Path(table).read_text().splitlines()
    except OSError:
        return None
    for line in lines:
        fields = line.split()
        # "1: FLOCK  ADVISORY  WRITE 1234 08:02:5678 0 EOF" (a blocked waiter has "->")
        if len(fields) >= 6 and fields[1] == "FLOCK" and fields[5] == key:
            return int(fields[4])
    return None


#: the advisory lock's key is the server's own 64-bit hash of this text and the name
_KEY_SQL = "hashtextextended('station ' || %s, 0)"


class AdvisoryLock:
    """A session-level advisory lock on a PostgreSQL server, one per station name."""

    def __init__(self, url: str, name: str) -> None:
        self.url = url
        self.name = name
        #: how this daemon's lock session names itself on the server (refusals show it)
        self.app_name = f"station lock pid {os.getpid()} on {os.uname().nodename}"[:63]
        self._conn: Any = None

    def acquire(self) -> AdvisoryLock:
        if not self._try():
            holder = self._holder()
            raise AlreadyRunning(f"station {self.name or '(unnamed)'} already running on "
                                 f"{without_password(self.url)}{holder}")
        return self

    def _try(self) -> bool:
        self._close()
        try:
            self._conn = connect_postgres(self.url, application_name=self.app_name)
            row = self._conn.execute(f"select pg_try_advisory_lock({_KEY_SQL}) as ok",
                                     (self.name,)).fetchone()
        except Exception as exc:  # psycopg.Error: the server is not there
            self._close()
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise UserError(f"{without_password(self.url)}: cannot connect ({first})") from None
        if not row["ok"]:
            self._close()
        return bool(row["ok"])

    def _holder(self) -> str:
        """" (held by <application name>)", when the server tells us who holds it."""
        who = self._holder_name()
        return f" (held by {who})" if who else ""

    def _holder_name(self) -> str | None:
        """The application name of the session holding the lock, if the server says."""
        try:
            conn = connect_postgres(self.url)
            with conn:
                row = conn.execute(
                    "select a.application_name as who from pg_locks l join pg_stat_activity a "
                    "using (pid) where l.locktype = 'advisory' and l.granted and "
                    f"((l.classid::bigint << 32) | l.objid::bigint) = {_KEY_SQL}",
                    (self.name,)).fetchone()
        except Exception:
            return None
        return row["who"] if row else None

    def still_held(self) -> bool:
        """Whether this daemon still holds its name: after the session was lost (an outage,
        a restarted server) the lock is taken again if nobody else took it meanwhile."""
        try:
            self._conn.execute("select 1")
            return True
        except Exception:
            pass
        try:
            held = self._try()
        except UserError:
            return True  # the server is away: nobody else can take the name meanwhile
        if held:
            log.warning("job store session lost and back: station %s holds its name again",
                        self.name)
        elif self._holder_name() == self.app_name:
            return True  # our own lost session, not yet gone on the server: nobody else's
        return held

    def _close(self) -> None:
        if self._conn is not None:
            try:
                self._conn.close()
            except Exception:
                pass
            self._conn = None

    def release(self) -> None:
        self._close()  # ending the session releases the lock


class StoreLocks:
    """The locks of one daemon's store, released in reverse order."""

    def __init__(self, locks: list[Lock]) -> None:
        self.locks = locks

    def still_held(self) -> bool:
        return all(getattr(lock, "still_held", lambda: True)() for lock in self.locks)

    def release(self) -> None:
        for lock in reversed(self.locks):
            lock.release()
        self.locks = []

    @property
    def held(self) -> bool:
        return bool(self.locks)


def lock_store(config: Config) -> StoreLocks:
    """Take this daemon's store (before anything else is touched), or AlreadyRunning."""
    url = config["store"]["url"]
    if not is_server_url(url):
        return StoreLocks([StoreFileLock(config.resolve(url or config["store"]["path"])
                                         ).acquire()])
    work = DaemonLock(lock_path(config)).acquire()
    try:
        return StoreLocks([work, AdvisoryLock(url, config["station"]["name"]).acquire()])
    except BaseException:
        work.release()
        raise
