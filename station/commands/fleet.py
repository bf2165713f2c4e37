"""`station fleet` (the stations of a shared job store) and `station reassign JOB`."""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

from station.cliargs import add_config_argument
from station.errors import UserError
from station.fleet import Fleet
from station.fleetconsole import open_fleet_store
from station.jobstore import JobStore, JobStoreError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("fleet", help="the stations sharing the job store",
                       description="Every station of the fleet: state (idle, busy, stopped, "
                       "or lost when its heartbeat stopped), tool, table, running job, "
                       "progress and last heartbeat.")
    _common(p, run_fleet)
    p = sub.add_parser("reassign", help="give an interrupted job to another station",
                       description="Move an interrupted, paused or failed job back to the "
                       "queue for another station (or only --to NAME). Pieces recorded cut "
                       "stay cut: the new station detects the fabric again and cuts the rest.")
    p.add_argument("job", type=int)
    p.add_argument("--to", metavar="NAME", help="only this station may take it")
    _common(p, run_reassign)


def _common(p: argparse.ArgumentParser, func) -> None:
    add_config_argument(p)
    p.add_argument("--store", metavar="URL", help="the shared job store (default: from the "
                   "config)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=func)


def _fleet(args: argparse.Namespace) -> tuple[JobStore, Fleet]:
    store = open_fleet_store(args)
    return store, Fleet(store)


def run_fleet(args: argparse.Namespace) -> int:
    store, fleet = _fleet(args)
    try:
        stations = fleet.stations()
        jobs = {s["job_id"]: store.summary(store.job(s["job_id"])) for s in stations
                if s["job_id"] is not None}
    finally:
        store.close()
    if args.json:
        print(json.dumps({"stations": stations, "jobs": {str(k): v for k, v in jobs.items()}},
                         default=float))
        return 0
    if not stations:
        print("no stations have joined this job store")
    for s in stations:
        print(station_line(s, jobs.get(s["job_id"])))
    return 0


def station_line(s: dict[str, Any], job: dict[str, Any] | None) -> str:
    text = (f"{s['name']:<14} {s['state']:<8} {s['tool']:<6} "
            f"{s['table_x_mm']:g} x {s['table_y_mm']:g} mm")
    if job is not None:
        p = job["pieces"]
        text += f"  job {job['id']} {job['state']} {p['cut']}/{sum(p.values())} pieces cut"
        progress = s.get("progress") or {}
        if progress.get("step"):
            text += f"  {progress['step']}"
        if progress.get("fraction") is not None:
            text += f" {100 * progress['fraction']:.0f}%"
    stamp = time.strftime("%H:%M:%S", time.localtime(s["heartbeat_at"]))
    return text + f"  heartbeat {stamp} ({s['seconds_since_heartbeat']:.1f} s ago)"


def run_reassign(args: argparse.Namespace) -> int:
    store, fleet = _fleet(args)
    try:
        job = fleet.reassign(args.job, args.to)
    except JobStoreError as exc:
        raise UserError(str(exc)) from None
    finally:
        store.close()
    if args.json:
        print(json.dumps({"job": job.to_dict()}))
    else:
        print(f"job {job.id} queued again for {args.to or 'any compatible station'}; "
              "pieces already cut stay cut")
    return 0
