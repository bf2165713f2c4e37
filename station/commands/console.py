"""The operator's console: `station jobs|status|pause|resume|abort|retry|log`.

Each command sends one request to the running daemon over its control socket and prints
the answer, for people or (``--json``) for programs. With ``--station NAME`` or
``--fleet`` the request goes through the shared job store instead, to whichever station
owns the job (`station.fleetconsole`). `station submit` (`station.commands.submit`)
shares the arguments and the way to the daemon from here.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from station.cliargs import add_config_argument, load_config_arg
from station.control import ControlError, request
from station.errors import UserError
from station.progress import garment_counts, step_label


def register(sub: argparse._SubParsersAction) -> None:
    for name, text in (("jobs", "list every job"), ("status", "state, pieces and progress")):
        p = sub.add_parser(name, help=text, description=text)
        if name == "status":
            p.add_argument("job", nargs="?", type=int)
        add_console_arguments(p, run_simple)
    for name, text in (("pause", "feed hold now (cutting) or after the current step"),
                       ("resume", "continue a paused or interrupted job"),
                       ("abort", "stop the job safely (feed hold, reset, laser off)"),
                       ("retry", "queue a failed or aborted job again")):
        p = sub.add_parser(name, help=text, description=text)
        p.add_argument("job", nargs="?" if name != "retry" else None, type=int)
        add_console_arguments(p, run_simple)
    p = sub.add_parser("log", help="the job store's event log", description="Events, oldest first.")
    p.add_argument("job", nargs="?", type=int)
    p.add_argument("--limit", type=int, default=200)
    add_console_arguments(p, run_simple)


def add_console_arguments(p: argparse.ArgumentParser, func: Callable[[argparse.Namespace], int]
                          ) -> None:
    """Where the request goes (the daemon's socket or the fleet's store) and how the
    answer is printed: every console command has these."""
    add_config_argument(p)
    p.add_argument("--socket", metavar="PATH", help="control socket (default: from the config)")
    p.add_argument("--json", action="store_true", help="print the daemon's answer as JSON")
    p.add_argument("--station", metavar="NAME", help="a station of the fleet: through the "
                   "shared job store, not the local socket")
    p.add_argument("--fleet", action="store_true", help="through the shared job store, to "
                   "the station that owns the job")
    p.add_argument("--store", metavar="URL", help="the shared job store (default: from the "
                   "config)")
    p.set_defaults(func=func)


def _socket(args: argparse.Namespace) -> Path:
    if args.socket:
        return Path(args.socket)
    config = load_config_arg(args)
    return config.resolve(config["control"]["socket"])


def ask(args: argparse.Namespace, cmd: str, *,
        before_fleet: Callable[[dict[str, Any]], None] | None = None, **fields: Any
        ) -> dict[str, Any]:
    """The daemon's answer to ``cmd`` (or the fleet's, with --station or --fleet);
    ``before_fleet`` checks the fields first where no daemon will (the fleet path)."""
    try:
        if getattr(args, "station", None) or getattr(args, "fleet", False):
            return _ask_fleet(args, cmd, before_fleet, **fields)
        return request(_socket(args), cmd, **fields)
    except ControlError as exc:
        raise UserError(str(exc)) from None


def _ask_fleet(args: argparse.Namespace, cmd: str,
               before_fleet: Callable[[dict[str, Any]], None] | None, **fields: Any
               ) -> dict[str, Any]:
    # Only a request through the fleet loads the shared store's stack (the job store, the
    # fleet, gcode.resume: 120 ms and 74 modules measured), not every `station status`.
    from station.fleetconsole import FleetConsole, open_fleet_store

    fields.pop("timeout", None)  # the socket's: the store answers at once
    fields.pop("on_wait", None)
    store = open_fleet_store(args)
    try:
        if before_fleet is not None:
            before_fleet(fields)
        return FleetConsole(store).request(cmd, args.station, **fields)
    finally:
        store.close()


def run_simple(args: argparse.Namespace) -> int:
    fields = {k: getattr(args, k) for k in ("job", "limit") if getattr(args, k, None) is not None}
    answer = ask(args, args.command, **fields)
    if args.json:
        print(json.dumps(answer))
    elif args.command == "jobs":
        for job in answer["jobs"]:
            print(_line(job))
        if not answer["jobs"]:
            print("no jobs")
    elif args.command == "status":
        print(_line(answer["job"]) if answer["job"] else "no jobs")
    elif args.command == "log":
        for e in answer["events"]:
            stamp = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(e["at"]))
            job = f"job {e['job_id']}" if e["job_id"] is not None else "station"
            print(f"{stamp}  {job:>8}  {e['kind']:<9} {e['message']}")
    else:
        where = f" (station {answer['station']})" if answer.get("station") else ""
        print(f"job {answer['job']}{where}: {answer['message']}")
    return 0


def _line(job: dict[str, Any]) -> str:
    p = job["pieces"]
    total = sum(p.values())
    text = f"job {job['id']:>3}  {job['state']:<10} {p['cut']}/{total} pieces cut  " \
           f"{Path(job['garment']).name}{garment_counts(job)}"
    if job.get("owner"):
        text += f"  @{job['owner']}"
    progress = job.get("progress") or {}
    if progress.get("bite"):
        text += f"  {step_label(progress)}"
    if "fraction" in progress:
        text += f"  {100 * progress['fraction']:.0f}%"
    if progress.get("seconds_left") is not None:
        text += f"  {progress['seconds_left']:.0f} s left"
    if job["reason"]:
        text += f"  ({job['reason']})"
    return text
