"""One daemon per job store: an exclusive lock file held for the daemon's whole life.

The lock is an ``flock`` on a file beside the store (or beside the work folder when the
store is not a local file), so it works for any store engine and is released by the kernel
when the daemon dies however it dies: a stale socket or lock file never blocks a restart,
and a live daemon's socket is never removed by a second one.
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path

from station.config import Config
from station.errors import UserError


class AlreadyRunning(UserError):
    """Another daemon holds the lock: nothing was touched."""


def lock_path(config: Config) -> Path:
    """``jobs.db.lock`` beside a file store; ``<work_dir>.lock`` for a server store."""
    store = config["store"]["path"]
    if "://" not in store:
        path = config.resolve(store)
        return path.with_name(path.name + ".lock")
    work = config.resolve(config["store"]["work_dir"])
    return work.with_name(work.name + ".lock")


class DaemonLock:
    """``with DaemonLock(path):`` holds the lock; a second holder gets AlreadyRunning."""

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
