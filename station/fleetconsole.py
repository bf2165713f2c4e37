"""The operator's console for a room of stations: answers from the shared job store.

`request` takes the same commands and answers as the daemon's control socket, so
`station jobs|status|log|pause|resume|abort|retry|submit` print the same things whether
they talk to one daemon or to the fleet. Reading commands read the store. Commands for a
job that a station owns travel to that station through the store (`Fleet.send`) and its
daemon runs them with its own handler, within its heartbeat interval (0.5 s by default);
a job nobody owns yet is changed in the store directly. ``--station NAME`` picks a
station (pause, resume, abort: its running job; submit: a job only it may take).
`open_fleet_store` opens the store a console command names (``--store`` or the
configuration).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from station.cliargs import load_config_arg
from station.control import ControlError
from station.errors import UserError
from station.fleet import Fleet, open_store
from station.jobstore import FINAL, JobStore, JobStoreError, Requirements
from station.storeengine import PASSWORD_ADVICE, holds_password, is_server_url

#: Seconds to wait for the owning station's answer.
ANSWER_TIMEOUT = 10.0


class FleetConsole:
    def __init__(self, store: JobStore, fleet: Fleet | None = None) -> None:
        self.store = store
        self.fleet = fleet or Fleet(store)

    def request(self, cmd: str, station: str | None = None, **fields: Any) -> dict[str, Any]:
        """One console request, answered like the control socket answers it."""
        handler = getattr(self, f"cmd_{cmd}", None)
        if handler is None:
            raise ControlError(f"unknown command {cmd!r}")
        try:
            return {"ok": True, **handler(station, fields)}
        except JobStoreError as exc:
            raise ControlError(str(exc)) from None

    # ------------------------------------------------------------------ reading
    def summary(self, job_id: int) -> dict[str, Any]:
        job = self.store.job(job_id)
        out = self.store.summary(job)
        if job.owner:
            st = [s for s in self.fleet.stations() if s["name"] == job.owner]
            if st and st[0]["job_id"] == job.id and st[0]["progress"]:
                out["progress"] = st[0]["progress"]
            out["station_state"] = st[0]["state"] if st else "unknown"
        return out

    def cmd_jobs(self, station: str | None, _fields: dict[str, Any]) -> dict[str, Any]:
        return {"jobs": [self.summary(j.id) for j in self.store.jobs()
                         if station is None or j.owner == station]}

    def cmd_status(self, station: str | None, fields: dict[str, Any]) -> dict[str, Any]:
        job_id = fields.get("job")
        if job_id is None:
            job_id = self._running(station) if station else None
            if job_id is None:
                jobs = [j for j in self.store.jobs() if station is None or j.owner == station]
                job_id = jobs[-1].id if jobs else None
            if job_id is None:
                return {"job": None}
        return {"job": self.summary(int(job_id))}

    def cmd_log(self, _station: str | None, fields: dict[str, Any]) -> dict[str, Any]:
        job_id = fields.get("job")
        events = self.store.events(None if job_id is None else int(job_id))
        return {"events": events[-int(fields.get("limit", 200)):]}

    def cmd_plan(self, _station: str | None, fields: dict[str, Any]) -> dict[str, Any]:
        job = self.store.job(int(fields["job"]))
        return {"job": job.id, "state": job.state, "plan": job.plan}

    # ------------------------------------------------------------------ changing
    def cmd_submit(self, station: str | None, fields: dict[str, Any]) -> dict[str, Any]:
        req = Requirements(fields.get("tool"), fields.get("table_mm"), station)
        job = self.store.submit(fields["garment"], fields.get("fabric"),
                                fields.get("options") or {}, req)
        return {"job": job.to_dict()}

    def cmd_pause(self, station: str | None, fields: dict[str, Any]) -> dict[str, Any]:
        return self._relay("pause", station, fields)

    def cmd_resume(self, station: str | None, fields: dict[str, Any]) -> dict[str, Any]:
        return self._relay("resume", station, fields)

    def cmd_abort(self, station: str | None, fields: dict[str, Any]) -> dict[str, Any]:
        job_id = fields.get("job")
        if job_id is not None and station is None:
            job = self.store.job(int(job_id))
            if job.state in FINAL:
                raise ControlError(f"job {job.id} is already {job.state}")
            if job.owner is None or job.state == "interrupted":
                self.store.transition(job.id, "aborted", "aborted by the operator")
                return {"job": job.id, "message": "aborted"}
        return self._relay("abort", station, fields)

    def cmd_retry(self, _station: str | None, fields: dict[str, Any]) -> dict[str, Any]:
        if fields.get("job") is None:
            raise ControlError("retry needs a job number")
        job = self.store.job(int(fields["job"]))
        if job.state not in ("failed", "aborted"):
            raise ControlError(f"job {job.id} is {job.state}; only failed or aborted jobs "
                               "can be retried")
        self.store.transition(job.id, "submitted", "retried by the operator")
        return {"job": job.id, "message": "queued again; pieces already cut stay cut"}

    def _running(self, station: str) -> int | None:
        return self.fleet.station(station)["job_id"]

    def _relay(self, cmd: str, station: str | None, fields: dict[str, Any]) -> dict[str, Any]:
        """Send ``cmd`` to the station that owns the job (or the one named); its answer."""
        job_id = fields.get("job")
        if station is None:
            if job_id is None:
                raise ControlError(f"{cmd} needs a job number or --station NAME")
            station = self.store.job(int(job_id)).owner
            if station is None:
                raise ControlError(f"job {job_id} is not on any station yet")
        target = self.fleet.station(station)
        if target["state"] not in ("idle", "busy"):
            raise ControlError(f"station {station} is {target['state']} (last heartbeat "
                               f"{target['seconds_since_heartbeat']:.0f} s ago); "
                               "`station reassign JOB` gives its job to another station")
        request = {"cmd": cmd, **({"job": int(job_id)} if job_id is not None else {})}
        answer = self.fleet.wait_answer(self.fleet.send(station, request), ANSWER_TIMEOUT)
        if answer is None:
            raise ControlError(f"station {station} did not answer within "
                               f"{ANSWER_TIMEOUT:g} s")
        if not answer.get("ok"):
            raise ControlError(f"station {station}: {answer.get('error', 'refused')}")
        return {**{k: v for k, v in answer.items() if k != "ok"}, "station": station}


def open_fleet_store(args: argparse.Namespace) -> JobStore:
    """The shared job store named by ``--store`` or the configuration."""
    store = getattr(args, "store", None)
    overrides = None
    if store:
        store = checked_store_arg(store)
        overrides = {"store": {"url": store} if "://" in store
                     else {"url": "", "path": str(Path(store).resolve())}}
    return open_store(load_config_arg(args, overrides))


def checked_store_arg(value: str) -> str:
    """``--store``: a postgresql:// URL without a password (the command line is visible to
    every user through ps; libpq reads PGPASSWORD or PGPASSFILE), or an existing store file
    (a console never creates one)."""
    if is_server_url(value):
        try:
            password = holds_password(value)
        except ValueError as exc:
            raise UserError(f"--store: {exc}") from None
        if password:
            raise UserError("--store: a password on the command line is visible to every "
                            f"user; {PASSWORD_ADVICE}")
        return value
    if "://" in value:
        raise UserError(f"--store: a postgresql:// URL or a job store file, not "
                        f"{value.split('://', 1)[0][:20]}://...")
    if not Path(value).is_file():
        raise UserError(f"{value}: no job store there (--store names an existing store "
                        "file or a postgresql:// URL)")
    return value
