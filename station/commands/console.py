"""The operator's console: `station submit|jobs|status|pause|resume|abort|retry|log`.

Each command sends one request to the running daemon over its control socket and prints
the answer, for people or (``--json``) for programs. With ``--station NAME`` or
``--fleet`` the request goes through the shared job store instead, to whichever station
owns the job (`station.fleetconsole`).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from station.cliargs import add_config_argument, load_config_arg
from station.control import ControlError, request
from station.errors import UserError
from station.progress import garment_counts


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("submit", help="queue a garment to be aligned, nested and cut",
                       description="Queue a job on the running daemon.")
    p.add_argument("garment", metavar="GARMENT")
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--fabric", metavar="FABRIC.json", help="the print, as measured")
    source.add_argument("--detect", action="store_true",
                        help="photograph the fabric and detect its print")
    p.add_argument("--units", choices=("m", "cm", "mm", "in"))
    p.add_argument("--size", help="the size of a graded DXF (default: its sample size)")
    p.add_argument("--reshape", action="store_true", help="nudge the pieces' shapes")
    p.add_argument("--method", choices=("paper", "global"))
    p.add_argument("--restarts", type=int)
    p.add_argument("--tool", choices=("laser", "knife"), help="only a station with this tool "
                   "may take the job (fleet)")
    p.add_argument("--min-table", metavar="XxY", type=_table,
                   help="only a station whose table travels at least X by Y mm (fleet)")
    p.add_argument("--grain-line", action="append", metavar="PIECE=DEG",
                   help="a piece's grain direction (pattern space, degrees); repeatable")
    p.add_argument("--bias", action="append", metavar="PIECE", help="cut this piece on the bias")
    p.add_argument("--pairs", metavar="P.json",
                   help="declare or veto left/right pairs for this job (sent by value)")
    p.add_argument("--symmetrise", action="store_true",
                   help="cut each near left/right pair as one pattern, the average of the two")
    p.add_argument("--no-symmetry", action="store_true",
                   help="align every piece on its own (default: pairs mirror the print)")
    p.add_argument("--no-stripe-matching", action="store_true",
                   help="on a stripe print, nest on the stripes' grain without matching the "
                   "stripes across the seams (default: matched, as a 1-D print)")
    p.add_argument("--seam-allowance", type=float, metavar="MM",
                   help="seam allowance for this job (default: station.toml)")
    p.add_argument("--allowance", metavar="A.json",
                   help="allowances per seam line or opening for this job (sent by value)")
    p.add_argument("--wait", type=float, default=600.0, metavar="SECONDS",
                   help="how long to wait while the daemon checks the garment (default 600)")
    _common(p, run_submit)

    for name, text in (("jobs", "list every job"), ("status", "state, pieces and progress")):
        p = sub.add_parser(name, help=text, description=text)
        if name == "status":
            p.add_argument("job", nargs="?", type=int)
        _common(p, run_simple)
    for name, text in (("pause", "feed hold now (cutting) or after the current step"),
                       ("resume", "continue a paused or interrupted job"),
                       ("abort", "stop the job safely (feed hold, reset, laser off)"),
                       ("retry", "queue a failed or aborted job again")):
        p = sub.add_parser(name, help=text, description=text)
        p.add_argument("job", nargs="?" if name != "retry" else None, type=int)
        _common(p, run_simple)
    p = sub.add_parser("log", help="the job store's event log", description="Events, oldest first.")
    p.add_argument("job", nargs="?", type=int)
    p.add_argument("--limit", type=int, default=200)
    _common(p, run_simple)


def _common(p: argparse.ArgumentParser, func) -> None:
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


def _table(text: str) -> tuple[float, float]:
    try:
        x, y = (float(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected XxY in mm, e.g. 1200x900"
                                         ) from None
    if x <= 0 or y <= 0:
        raise argparse.ArgumentTypeError(f"{text!r}: sizes must be positive")
    return x, y


def _socket(args: argparse.Namespace) -> Path:
    if args.socket:
        return Path(args.socket)
    config = load_config_arg(args)
    return config.resolve(config["control"]["socket"])


def _ask(args: argparse.Namespace, cmd: str, **fields: Any) -> dict[str, Any]:
    try:
        if getattr(args, "station", None) or getattr(args, "fleet", False):
            return _ask_fleet(args, cmd, **fields)
        return request(_socket(args), cmd, **fields)
    except ControlError as exc:
        raise UserError(str(exc)) from None


def _ask_fleet(args: argparse.Namespace, cmd: str, **fields: Any) -> dict[str, Any]:
    from station.fleetconsole import FleetConsole

    fields.pop("timeout", None)  # the socket's: the store answers at once
    fields.pop("on_wait", None)
    store = open_fleet_store(args)
    try:
        if cmd == "submit":
            _check_job(args, fields)
        return FleetConsole(store).request(cmd, args.station, **fields)
    finally:
        store.close()


def open_fleet_store(args: argparse.Namespace):
    """The shared job store named by ``--store`` or the configuration."""
    from station.fleet import open_store

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
    from station.storeengine import PASSWORD_ADVICE, holds_password, is_server_url

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


def _check_job(args: argparse.Namespace, fields: dict[str, Any]) -> None:
    """Refuse here what no station could run, as the daemon does before queueing."""
    from station.pipeline import StationPipeline

    for key in ("garment", "fabric"):
        if fields.get(key) is not None and not Path(fields[key]).is_file():
            raise UserError(f"{fields[key]}: no such {key} file")
    StationPipeline(load_config_arg(args)).check(fields["garment"], fields.get("fabric"),
                                                 fields.get("options") or {})


class _Patience:
    """Tells the operator, once and then every 10 s, that the daemon is still checking."""

    def __init__(self, garment: str) -> None:
        self.garment = garment
        self.next = 1.0

    def __call__(self, elapsed: float) -> None:
        if elapsed >= self.next:
            print(f"station submit: the daemon is checking {self.garment} "
                  f"({elapsed:.0f} s)...", file=sys.stderr, flush=True)
            self.next = elapsed + 10.0


def run_submit(args: argparse.Namespace) -> int:
    options = {k: v for k, v in (("units", args.units), ("size", args.size),
                                 ("reshape", args.reshape or None),
                                 ("method", args.method), ("restarts", args.restarts),
                                 ("seam_allowance", args.seam_allowance))
               if v is not None}
    fleet = {k: v for k, v in (("tool", args.tool), ("table_mm", args.min_table)) if v}
    if fleet and not (args.station or args.fleet):
        raise UserError("--tool and --min-table choose among the stations of a fleet: "
                        "add --fleet")
    if args.allowance:
        from station.cliargs import read_name_map

        options["allowance"] = {str(k): v for k, v in
                                read_name_map(args.allowance, "allowance").items()}
    if not args.wait > 0:
        raise UserError("--wait must be positive")
    if args.grain_line:
        from solver.garment.grain import parse_grain_lines

        options["grain_lines"] = parse_grain_lines(args.grain_line)
    if args.bias:
        options["bias"] = list(args.bias)
    if args.no_symmetry:
        options["symmetry"] = False
    if args.no_stripe_matching:
        options["match_stripes"] = False
    if args.symmetrise:
        options["symmetrise"] = True
    if args.pairs:
        from solver.jsonfile import read_json

        options["pairs"] = read_json(args.pairs)
    answer = _ask(args, "submit", garment=str(Path(args.garment).resolve()),
                  fabric=str(Path(args.fabric).resolve()) if args.fabric else None,
                  options=options, timeout=args.wait, on_wait=_Patience(args.garment),
                  **fleet)
    if args.json:
        print(json.dumps(answer))
    else:
        print(f"job {answer['job']['id']} submitted")
    return 0


def run_simple(args: argparse.Namespace) -> int:
    fields = {k: getattr(args, k) for k in ("job", "limit") if getattr(args, k, None) is not None}
    answer = _ask(args, args.command, **fields)
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
    if "fraction" in progress:
        text += f"  {100 * progress['fraction']:.0f}%"
    if progress.get("seconds_left") is not None:
        text += f"  {progress['seconds_left']:.0f} s left"
    if job["reason"]:
        text += f"  ({job['reason']})"
    return text
