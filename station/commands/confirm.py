"""`station confirm JOB [--group G | --seams S.json]`: accept or correct what a job asks.

A job whose detected print is less certain than ``camera.confirm_below`` waits at
"confirm fabric"; the operator looks at its ``detection.png`` (lattice and symmetry
elements over the photograph, the likeliest groups) and confirms the group, or names
the right one. A job whose CAD pattern has a seam less certain than
``seams.confirm_below`` waits at "confirm seams"; the operator looks at its ``seams.png``
(every seam numbered in its own colour on both pieces) and confirms them, or sends a
corrected ``seams.json`` (the ``--seams`` form `station inspect` takes).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import untrusted
from solver.wallpaper import GROUP_NAMES
from station.cliargs import add_config_argument, load_config_arg
from station.control import ControlError, request
from station.errors import UserError
from untrusted.limits import MAX_REQUEST_BYTES


def register(sub: argparse._SubParsersAction) -> None:
    text = ("accept or correct the detected print of a job waiting at 'confirm fabric', or "
            "the inferred seams of one waiting at 'confirm seams'")
    p = sub.add_parser("confirm", help=text, description=text)
    p.add_argument("job", type=int)
    p.add_argument("--group", choices=GROUP_NAMES,
                   help="the print's wallpaper group, when the detected one is wrong")
    p.add_argument("--seams", metavar="S.json",
                   help="the seams, when the inferred ones are wrong: the job's seams.json "
                   "corrected (sent by value)")
    add_config_argument(p)
    p.add_argument("--socket", metavar="PATH", help="control socket (default: from the config)")
    p.add_argument("--json", action="store_true", help="print the daemon's answer as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.socket:
        socket = Path(args.socket)
    else:
        config = load_config_arg(args)
        socket = config.resolve(config["control"]["socket"])
    fields = {"job": args.job} | ({"group": args.group} if args.group else {})
    if args.seams:
        fields["seams"] = untrusted.read_json(args.seams, what="seams file",
                                              max_bytes=MAX_REQUEST_BYTES // 2)
    try:
        answer = request(socket, "confirm", **fields)
    except ControlError as exc:
        raise UserError(str(exc)) from None
    print(json.dumps(answer) if args.json else f"job {answer['job']}: {answer['message']}")
    return 0
