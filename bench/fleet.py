"""Claiming jobs from a shared store (issue 19): 10 stations on PostgreSQL vs one on SQLite.

Each station is its own process with its own connection, as on a shop floor. It claims
a job (`Fleet.claim`: one transaction, ``FOR UPDATE SKIP LOCKED`` on PostgreSQL), then
runs it through the store as a cut-free job does (capturing, planning, ready, cutting,
done: five more transactions), and claims again until the queue is empty. Measured:
jobs claimed per second over the whole run, and each claim's wall time (p50, p99). The
baseline, measured in the same run, is one station on an SQLite file (the embedded
engine's use). The PostgreSQL server is a private one started here (`station.localpg`).

Run: ``python -m bench fleet [--jobs 400]``.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

from station.fleet import Fleet, StationInfo
from station.jobstore import JobStore
from station.localpg import LocalPostgres


def _station(location: str, name: str, start_at: float, out) -> None:
    store = JobStore(location)
    fleet = Fleet(store)
    info = StationInfo(name, "laser", (1600.0, 1000.0))
    fleet.register(info)
    latencies = []
    while time.time() < start_at:
        time.sleep(0.001)
    while True:
        t = time.perf_counter()
        job = fleet.claim(info)
        latencies.append(time.perf_counter() - t)
        if job is None:
            break
        for state in ("capturing", "planning", "ready", "cutting", "done"):
            store.transition(job.id, state)
    store.close()
    out.put((name, latencies[:-1], time.time()))


def run(location: str, stations: int, jobs: int) -> dict:
    """Queue ``jobs``, let ``stations`` processes take them all; the figures."""
    store = JobStore(location)
    for _ in range(jobs):
        store.submit("bench.obj", None, {})
    ctx = multiprocessing.get_context("spawn")
    out = ctx.Queue()
    start_at = time.time() + 2.0 + 0.2 * stations  # every process connected first
    procs = [ctx.Process(target=_station, args=(location, f"s{i}", start_at, out))
             for i in range(stations)]
    for p in procs:
        p.start()
    results = [out.get(timeout=300) for _ in procs]
    for p in procs:
        p.join()
    done = store.jobs(("done",))
    claims = [e for e in store.events() if e["kind"] == "claim"]
    store.close()
    assert len(done) == jobs and len(claims) == jobs, "a job was lost or claimed twice"
    lat = np.concatenate([np.asarray(r[1]) for r in results]) * 1000.0
    seconds = max(r[2] for r in results) - start_at
    return {"stations": stations, "jobs": jobs, "seconds": seconds,
            "jobs_per_s": jobs / seconds, "p50_ms": float(np.percentile(lat, 50)),
            "p99_ms": float(np.percentile(lat, 99)),
            "per_station": sorted(len(r[1]) for r in results)}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m bench fleet")
    parser.add_argument("--jobs", type=int, default=400)
    args = parser.parse_args(argv or [])
    print(f"{time.strftime('%Y-%m-%d %H:%M')} {platform.machine()}, {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.1f}; {args.jobs} jobs, claim + 5 transitions "
          "each")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        rows.append(("SQLite, 1 station (baseline)",
                     run(str(Path(tmp) / "jobs.db"), 1, args.jobs)))
        with LocalPostgres() as pg:
            rows.append(("PostgreSQL, 1 station",
                         run(pg.create_database("one"), 1, args.jobs)))
            rows.append(("PostgreSQL, 10 stations",
                         run(pg.create_database("ten"), 10, args.jobs)))
    base = rows[0][1]["jobs_per_s"]
    print("| store | jobs/s | vs baseline | claim p50 ms | claim p99 ms | jobs per station |")
    print("| --- | --- | --- | --- | --- | --- |")
    for label, r in rows:
        spread = f"{r['per_station'][0]}-{r['per_station'][-1]}"
        print(f"| {label} | {r['jobs_per_s']:.0f} | {r['jobs_per_s'] / base:.2f}x | "
              f"{r['p50_ms']:.2f} | {r['p99_ms']:.2f} | {spread} |")


if __name__ == "__main__":
    main()
