"""`station watch [JOB]`: progress bars for the job the daemon is running."""

from __future__ import annotations

import argparse

from station.cliargs import add_config_argument, load_config_arg
from station.control import ControlError, request
from station.errors import UserError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "watch", help="progress bars for a running job",
        description="Follow a job (default: the one running) with a progress bar per step "
        "(restarts, reshaping, nesting, streaming with its time left) until it is done, "
        "failed, aborted or paused.")
    p.add_argument("job", nargs="?", type=int)
    add_config_argument(p)
    p.add_argument("--socket", metavar="PATH", help="control socket (default: from the config)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from station.progress import follow

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
