"""What every open console page sees, read once for all of them, and only while one looks.

One thread reads the station twice a second while at least one page is open, and not at
all otherwise: the daemon's streamer and the emulator share the interpreter with it, and
a cut must never wait for a screen nobody watches. Each read asks the job store for the
events since the last one; only when there are some (every change of a job or a piece
writes one) are the jobs and their pieces read again. What changes without an event, the
running job's progress, comes from the daemon's memory. The view carries a version
number; each page's event stream sends it only when that number moved, so ten pages cost
the store no more than one.
"""

from __future__ import annotations

import logging
import threading
from collections import deque
from typing import Any

from station.progress import step_label

log = logging.getLogger("station.web")

EVENTS_KEPT = 300  # the log lines a page is shown (newest last)
JOBS_SHOWN = 50  # the newest jobs on the page; older ones stay in `station jobs`
PIECES_FOR = 12  # jobs whose pieces are listed one by one (the newest)


class Feed:
    """The station as the console shows it, read every ``interval`` seconds while watched."""

    def __init__(self, daemon: Any, questions: dict[str, str], interval: float = 0.5) -> None:
        self.daemon = daemon
        self.questions = questions  # reason prefix -> the command that answers it
        self.interval = interval
        self.version = 0
        self.view: dict[str, Any] = {}
        self.watchers = 0  # open event streams
        self._events: deque[dict[str, Any]] = deque(maxlen=EVENTS_KEPT)
        self._last_event = -1  # -1: nothing read yet
        self._jobs: list[dict[str, Any]] = []
        self._pieces: dict[str, list[dict[str, Any]]] = {}
        self._read_lock = threading.Lock()
        self._wanted = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="console-feed", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._wanted.set()
        if self._thread.is_alive():
            self._thread.join(5)

    @property
    def stopped(self) -> bool:
        return self._stop.is_set()

    def watch(self) -> None:
        """A page opened its event stream: read from now on."""
        self.watchers += 1
        self._wanted.set()

    def unwatch(self) -> None:
        self.watchers -= 1

    def _run(self) -> None:
        failing = False
        while not self._stop.is_set():
            if self.watchers <= 0:
                self._wanted.clear()
                self._wanted.wait()
                continue
            try:
                self.refresh()
            except Exception as exc:  # the store away, say: the pages keep the last view
                if not failing:  # once per outage, not twice a second
                    log.warning("console: reading the station failed (%s); the pages show "
                                "the last view", exc)
                failing = True
            else:
                failing = False
            self._stop.wait(self.interval)

    def refresh(self) -> None:
        """Read the station now (the feed's thread, or a page asking once)."""
        with self._read_lock:
            view = self.read()
            if view != self.view:
                self.view = view  # one assignment: a page sends the old view or the new
                self.version += 1

    def read(self) -> dict[str, Any]:
        """The view: this station, the fleet, jobs with their pieces, questions, events."""
        store = self.daemon.store
        new = store.events(None, after=max(self._last_event, 0))
        if new or self._last_event < 0:
            for event in new[-EVENTS_KEPT:]:
                self._events.append({k: event[k] for k in ("id", "job_id", "at", "kind",
                                                             "message")})
            self._last_event = new[-1]["id"] if new else 0
            self._jobs = [store.summary(job) for job in store.jobs()[-JOBS_SHOWN:]]
            self._pieces = {str(j["id"]): [{k: p[k] for k in ("piece", "name", "state")}
                                           for p in store.pieces(j["id"])]
                            for j in self._jobs[-PIECES_FOR:]}
        running = self.daemon.running
        return {"station": self._station(), "stations": self._stations(), "jobs": self._jobs,
                "progress": None if running is None else {"job": running.job_id,
                                                          **running.progress},
                "pieces": self._pieces, "questions": self._questions(self._jobs),
                "events": list(self._events)}

    def _station(self) -> dict[str, Any]:
        running = self.daemon.running
        fleet = self.daemon.fleet
        return {"name": fleet.info.name if fleet else "this station",
                "state": "busy" if running else "idle",
                "job": running.job_id if running else None,
                "step": (step_label(running.progress) if running else None)}

    def _stations(self) -> list[dict[str, Any]]:
        """The fleet's stations with their state, or this lone station."""
        fleet = self.daemon.fleet
        if fleet is None:
            return [self._station()]
        return [{"name": s["name"], "state": s["state"], "job": s.get("job_id"),
                 "step": (s.get("progress") or {}).get("step"),
                 "seconds_since_heartbeat": round(s["seconds_since_heartbeat"], 1)}
                for s in fleet.fleet.stations()]

    def _questions(self, jobs: list[dict[str, Any]]) -> list[dict[str, Any]]:
        """Jobs waiting for the operator, with the command that answers each."""
        asked = []
        for job in jobs:
            for prefix, command in self.questions.items():
                if job["state"] == "paused" and (job.get("reason") or "").startswith(prefix):
                    asked.append({"job": job["id"], "question": prefix, "answer": command,
                                  "reason": job["reason"]})
        return asked
