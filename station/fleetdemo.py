"""`station demo --fleet N --jobs M`: a room of simulated stations on one PostgreSQL server.

A private PostgreSQL server (`station.localpg`) holds the one job store. Each station is
the real `Daemon` and `StationPipeline` of `station serve --simulate`, with its own GRBL
emulator, synthetic camera, work folder and control socket; they run side by side in
this process and claim the jobs from the store as real stations would. The jobs are
queued through the fleet console (`station.fleetconsole`), the first one for a named
station, the rest for any. DIR/report.json has every job's station, pieces and times.
"""

from __future__ import annotations

import json
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

import numpy as np

from simulators.grbl import lookup
from station.daemon import Daemon
from station.errors import UserError
from station.fleetconsole import FleetConsole
from station.jobstore import FINAL, JobStore
from station.localpg import LocalPostgres, PostgresUnavailable
from station.simstation import copy_job_files, read_json_or_empty, start_simulated_station


def run(args) -> int:
    if args.fleet < 1 or args.jobs < 1:
        raise ValueError("--fleet and --jobs must be at least 1")
    garment = Path(args.garment)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="station-fleet-") as tmp:
        try:
            server = LocalPostgres().start()
        except PostgresUnavailable as exc:
            raise UserError(f"the fleet demo needs a PostgreSQL server: {exc}") from None
        stations: list[tuple[Daemon, threading.Thread]] = []
        try:
            url = server.create_database("fleet")
            print(f"station demo: PostgreSQL server at {url}, {args.fleet} stations",
                  file=sys.stderr)
            for i in range(args.fleet):
                name = f"table-{i + 1}"
                stations.append(start_simulated_station(args, f"fleet-{name}-{id(args)}", {
                    "store": {"url": url, "work_dir": f"{tmp}/{name}/jobs"},
                    "control": {"socket": f"{tmp}/{name}/station.sock"},
                    "station": {"name": name},
                }, thread=name))
            store = JobStore(url)
            console = FleetConsole(store)
            for k in range(args.jobs):
                console.request("submit", "table-1" if k == 0 else None,
                                garment=str(garment.resolve()), fabric=None,
                                options={"units": args.units})
            ids = [j.id for j in store.jobs()]
            last = 0.0
            while not all(store.job(j).state in FINAL for j in ids):
                if time.monotonic() - last > 10:
                    last = time.monotonic()
                    _print_room(console, ids, time.monotonic() - t0)
                time.sleep(0.5)
            report = fleet_report(store, ids, {d.fleet.info.name: d for d, _ in stations})
            keep_job_files(report, out)
        finally:
            for daemon, _ in stations:
                daemon.shutdown()
            for daemon, worker in stations:
                worker.join(60)
                daemon.control.stop()
                daemon.store.close()
            server.close()
    report["summary"]["seconds"] = round(time.monotonic() - t0, 1)
    (out / "report.json").write_text(json.dumps(report, indent=2, default=float))
    print_summary(report, out)
    return 0 if report["summary"]["jobs_done"] == len(ids) else 1


def _print_room(console, ids: list[int], seconds: float) -> None:
    rows = [console.summary(j) for j in ids]
    done = sum(r["state"] == "done" for r in rows)
    running = ", ".join(f"{r['id']}@{r['owner']} {r['state']}" for r in rows
                        if r["owner"] and r["state"] not in ("done", "failed", "aborted"))
    print(f"station demo: {seconds:5.0f} s  {done}/{len(ids)} jobs done  {running}",
          file=sys.stderr)


def fleet_report(store, ids: list[int], daemons: dict[str, Any]) -> dict[str, Any]:
    """Each job's station, pieces and times; each station's jobs and machine work."""
    jobs = []
    for job_id in ids:
        job = store.job(job_id)
        events = store.events(job_id)
        claimed = next((e["at"] for e in events if e["kind"] == "claim"), None)
        ended = next((e["at"] for e in reversed(events) if e["kind"] == "state"
                      and e["message"].split(": ")[0].endswith(f"-> {job.state}")), None)
        pieces = store.pieces(job_id)
        plan = job.plan or {}
        fabric = read_json_or_empty(Path(plan["fabric"])) if plan.get("fabric") else {}
        jobs.append({
            "id": job_id, "station": job.owner, "state": job.state, "reason": job.reason,
            "requirements": job.requirements.to_dict(),
            "pieces_cut": sum(p["state"] == "cut" for p in pieces), "pieces_total": len(pieces),
            "submitted_at": job.submitted_at, "claimed_at": claimed, "finished_at": ended,
            "waited_s": None if claimed is None else round(claimed - job.submitted_at, 2),
            "ran_s": None if claimed is None or ended is None else round(ended - claimed, 2),
            "group_detected": fabric.get("group"), "layout": plan.get("layout"),
        })
    stations = {}
    for name, daemon in daemons.items():
        mine = [j for j in jobs if j["station"] == name]
        stations[name] = {"jobs": [j["id"] for j in mine],
                          "pieces_cut": sum(j["pieces_cut"] for j in mine),
                          "machine": daemon.fleet.info.tool,
                          "table_mm": list(daemon.fleet.info.table_mm),
                          **machine_work(daemon.config["serial"]["port"])}
    done = [j for j in jobs if j["state"] == "done"]
    return {"summary": {"stations": len(daemons), "jobs": len(jobs), "jobs_done": len(done),
                        "pieces_cut": sum(j["pieces_cut"] for j in jobs),
                        "pieces_total": sum(j["pieces_total"] for j in jobs),
                        "jobs_per_station": {n: len(s["jobs"]) for n, s in stations.items()}},
            "jobs": jobs, "stations": stations}


def machine_work(port: str) -> dict[str, Any]:
    """What a station's emulator really did: beam-on moves and millimetres cut."""
    machine = lookup(parse_qs(urlsplit(port).query)["name"][0])
    if machine is None:
        return {"beam_on_moves": 0, "beam_on_mm": 0.0}
    seg = np.array([[m.x0, m.y0, m.x1, m.y1] for m in machine.trace
                    if m.power > 0 and not m.rapid], float).reshape(-1, 4)
    return {"beam_on_moves": len(seg),
            "beam_on_mm": round(float(np.hypot(*(seg[:, 2:] - seg[:, :2]).T).sum()), 1)}


def keep_job_files(report: dict[str, Any], out: Path) -> None:
    """Copy each job's marker, G-code and print into DIR/job-N (the store's folders are
    temporary); the report names the copies."""
    for job in report["jobs"]:
        layout = job.pop("layout")
        if not layout:
            continue
        target = out / f"job-{job['id']}"
        target.mkdir(exist_ok=True)
        copied = copy_job_files(Path(layout).parent, target, (
            "layout.json", "job.nc", "fabric.json", "marker.png", "frame.png"))
        job["files"] = [f"{target.name}/{name}" for name in copied]


def print_summary(report: dict[str, Any], out: Path) -> None:
    s = report["summary"]
    lines = [f"station demo --fleet: {s['jobs_done']}/{s['jobs']} jobs done on "
             f"{s['stations']} stations, {s['pieces_cut']}/{s['pieces_total']} pieces cut, "
             f"{s['seconds']:.1f} s"]
    for j in report["jobs"]:
        ran = "n/a" if j["ran_s"] is None else f"{j['ran_s']:.1f} s"
        lines.append(f"  job {j['id']:>2}  {j['station'] or '-':<8} {j['state']:<8} "
                     f"{j['pieces_cut']}/{j['pieces_total']} pieces  print "
                     f"{j.get('group_detected') or '-':<4} ran {ran}"
                     + (f"  ({j['reason']})" if j["reason"] else ""))
    for name, st in report["stations"].items():
        lines.append(f"  {name:<9} {len(st['jobs'])} jobs, {st['pieces_cut']} pieces; its "
                     f"machine cut {st['beam_on_mm']:.0f} mm in {st['beam_on_moves']} moves")
    lines.append(f"  report in     {out}/report.json")
    print("\n".join(lines))
