"""`station watch [JOB]`: progress bars for the job the daemon is running."""

from __future__ import annotations

import argparse

from station.cliargs import add_config_argument, load_config_arg
from station.control import ControlError, request
from station.errors import UserError
from station.fleetconsole import FleetConsole, open_fleet_store
from station.progress import follow


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "watch", help="progress bars for a running job",
        description="Follow a job (default: the one running) with a progress bar per step "
        "(restarts, reshaping, nesting, streaming with its time left) until it is done, "
        "failed, aborted or paused.")
    p.add_argument("job", nargs="?", type=int)
    add_config_argument(p)
    p.add_argument("--socket", metavar="PATH", help="control socket (default: from the config)")
    p.add_argument("--fleet", action="store_true", help="follow the job on whichever station "
                   "of the fleet runs it, through the shared job store")
    p.add_argument("--store", metavar="URL", help="the shared job store (default: from the "
                   "config)")
    p.set_defaults(func=run)


def _run_fleet(args: argparse.Namespace) -> int:
    if args.job is None:
        raise UserError("--fleet needs a job number")
    store = open_fleet_store(args)
    try:
        console = FleetConsole(store)
        final = follow(lambda job: console.summary(job), args.job)
    except ControlError as exc:
        raise UserError(str(exc)) from None
    finally:
        store.close()
    return 0 if final["state"] == "done" else 1


def run(args: argparse.Namespace) -> int:
    if args.fleet or args.store:
        return _run_fleet(args)
    if args.socket:
        sock = args.socket
    else:
        config = load_config_arg(args)
        sock = config.resolve(config["control"]["socket"])
    try:
        job = args.job
        if job is None:
            status = request(sock, "status")["job"]
            if status is None:
                raise UserError("no jobs")
            job = status["id"]
        final = follow(sock, job)
    except ControlError as exc:
        raise UserError(str(exc)) from None
    return 0 if final["state"] == "done" else 1
