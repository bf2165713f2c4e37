"""What every open console page sees, read once for all of them.

One thread reads the station a few times a second through the daemon's own read commands
(``jobs``, the same answer as `station jobs`) and the job store (pieces, events), and
keeps the latest view with a version number. Each page's event stream looks at that
number (in memory, ten times a second) and sends the view only when it changed, so ten
pages cost the store no more than one, and a page never asks the store anything itself.
"""

from __future__ import annotations

import logging
import threading
from collections import deque
from typing import Any

log = logging.getLogger("station.web")

EVENTS_KEPT = 300  # the log lines a page is shown (newest last)
JOBS_SHOWN = 50  # the newest jobs on the page; older ones stay in `station jobs`
PIECES_FOR = 12  # jobs whose pieces are listed one by one (the newest)


class Feed:
    """The station as the console shows it, refreshed every ``interval`` seconds."""

    def __init__(self, daemon: Any, questions: dict[str, str], interval: float = 0.25) -> None:
        self.daemon = daemon
        self.questions = questions  # reason prefix -> the command that answers it
        self.interval = interval
        self.version = 0
        self.view: dict[str, Any] = {}
        self._events: deque[dict[str, Any]] = deque(maxlen=EVENTS_KEPT)
        self._last_event = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="console-feed", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(5)

    @property
    def stopped(self) -> bool:
        return self._stop.is_set()

    def _run(self) -> None:
        failing = False
        while True:
            try:
                self.refresh()
            except Exception as exc:  # the store away, say: the pages keep the last view
                if not failing:  # once per outage, not four times a second
                    log.warning("console: reading the station failed (%s); the pages show "
                                "the last view", exc)
                failing = True
            else:
                failing = False
            if self._stop.wait(self.interval):
                return

    def refresh(self) -> None:
        view = self.read()
        if view != self.view:
            self.view = view  # one assignment: a page reads the old view or the new one
            self.version += 1

    def read(self) -> dict[str, Any]:
        """The view: this station, the fleet, jobs with their pieces, questions, events."""
        store = self.daemon.store
        jobs = self.daemon.handle({"cmd": "jobs"})["jobs"][-JOBS_SHOWN:]
        for event in store.events(None, after=self._last_event)[-EVENTS_KEPT:]:
            self._events.append({k: event[k] for k in ("id", "job_id", "at", "kind",
                                                         "message")})
            self._last_event = event["id"]
        pieces = {str(j["id"]): [{"piece": p["piece"], "name": p["name"], "state": p["state"]}
                                 for p in store.pieces(j["id"])]
                  for j in jobs[-PIECES_FOR:]}
        return {"station": self._station(), "stations": self._stations(), "jobs": jobs,
                "pieces": pieces, "questions": self._questions(jobs),
                "events": list(self._events)}

    def _station(self) -> dict[str, Any]:
        running = self.daemon.running
        fleet = self.daemon.fleet
        return {"name": fleet.info.name if fleet else "this station",
                "state": "busy" if running else "idle",
                "job": running.job_id if running else None,
                "step": (running.progress.get("step") if running else None)}

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
