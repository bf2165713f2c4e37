"""A daemon's seat in the fleet: joining, claiming, and the heartbeat thread.

The heartbeat thread writes the station's heartbeat (running job, progress), runs the
console requests sent to this station through the store with the daemon's own handler,
and marks the jobs of lost stations interrupted (see `station.fleet`). On PostgreSQL it
LISTENs for its channel between beats, so a request runs at once; otherwise it polls.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from station.fleet import Fleet, StationInfo, channel
from station.jobstore import ACTIVE, JOBS_CHANNEL, Job, JobStore, interrupted_reason
from station.storeengine import connect_postgres

log = logging.getLogger("station.fleet")


class FleetMember:
    """A daemon's seat in the fleet: claims, and a heartbeat thread serving commands.

    ``running`` tells the heartbeat what the daemon is doing (job id, progress);
    ``handle`` is the daemon's control handler, the same one the Unix socket calls.
    """

    def __init__(self, fleet: Fleet, info: StationInfo,
                 running: Callable[[], tuple[int | None, dict[str, Any]]],
                 handle: Callable[[dict[str, Any]], dict[str, Any]],
                 interval: float = 0.5, wake: Callable[[], None] | None = None) -> None:
        self.fleet = fleet
        self.info = info
        self.running = running
        self.handle = handle
        self.interval = interval
        self.wake = wake  # called when a job may have become claimable
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def join(self) -> None:
        self.fleet.register(self.info)

    def claim(self) -> Job | None:
        return self.fleet.claim(self.info)

    def interrupt_own(self) -> list[Job]:
        """After a crash: this station's jobs found active were interrupted."""
        out = []
        for job in self.fleet.store.jobs(ACTIVE):
            if job.owner == self.info.name:
                self.fleet.store.reset_unfinished_pieces(job.id)
                where = interrupted_reason(self.fleet.store.pieces(job.id))
                out.append(self.fleet.store.transition(
                    job.id, "interrupted", f"interrupted: station {self.info.name} was not "
                    "running; it resumes the job" + (f"; {where}" if where else "")))
        return out

    def start(self) -> None:
        self._thread = threading.Thread(target=self._beat, name="heartbeat", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the heartbeat and sign off (idempotent)."""
        if self._stop.is_set():
            return
        self._stop.set()
        if self._thread is not None:
            if self.fleet.store.engine.dialect == "postgresql":
                try:  # wake the listener now rather than at the end of its interval
                    self.fleet.store.engine.write(lambda tx: tx.run(
                        "select pg_notify(?, 'stop')", channel(self.info.name)), patience=1.0)
                except Exception:
                    pass  # the store is gone: the listener is polling, it stops in time
            self._thread.join(10)
        try:
            self.fleet.sign_off(self.info.name)
        except Exception:  # the store may be gone at shutdown; lost is then the truth
            log.warning("could not sign off from the fleet")

    def _beat(self) -> None:
        listener = Listener(self.fleet.store, (channel(self.info.name), JOBS_CHANNEL))
        try:
            while not self._stop.is_set():
                if listener.wait(self.interval, self._stop) == JOBS_CHANNEL and self.wake:
                    self.wake()  # a job was queued: claim it now, not at the next poll
                if self._stop.is_set():
                    break
                try:
                    self.tick()
                except Exception:  # the next beat tries again; never let the thread die
                    log.exception("heartbeat failed")
        finally:
            listener.close()

    def tick(self) -> None:
        job_id, progress = self.running()
        self.fleet.heartbeat(self.info.name, job_id, progress)
        for command_id, request in self.fleet.open_commands(self.info.name):
            try:
                answer = {"ok": True, **self.handle(request)}
            except Exception as exc:  # the console shows it, as the socket would
                answer = {"ok": False, "error": str(exc).strip("'\"")}
            self.fleet.answer(command_id, answer)
        if time.monotonic() - self.fleet.store.engine.reachable_since < self.fleet.timeout:
            return  # after an outage everyone's heartbeat is stale: give them time first
        reaped = self.fleet.reap()
        for job in reaped:
            log.warning("job %d interrupted: its station stopped answering", job)


class Listener:
    """Waits for a station's notifications on its own PostgreSQL connection.

    On SQLite (no notifications) and whenever the server is unreachable, `wait` is a
    plain sleep of one interval: the heartbeat's polling is the fallback, never lost.
    """

    def __init__(self, store: JobStore, channels: tuple[str, ...]) -> None:
        self.engine = store.engine
        self.channels = channels
        self._conn = None

    def wait(self, seconds: float, stop: threading.Event) -> str | None:
        """Sleep up to ``seconds``; the channel whose notification ended it, if any."""
        if self.engine.dialect != "postgresql":
            stop.wait(seconds)
            return None
        try:
            if self._conn is None or self._conn.closed:
                self._conn = connect_postgres(self.engine.url)
                for name in self.channels:
                    self._conn.execute(f"listen {name}")
            for note in self._conn.notifies(timeout=seconds, stop_after=1):
                return note.channel
            return None
        except Exception:  # the server went away: poll until it is back
            self.close()
            stop.wait(seconds)
            return None

    def close(self) -> None:
        if self._conn is not None:
            try:
                self._conn.close()
            except Exception:
                pass
            self._conn = None
