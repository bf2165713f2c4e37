"""`station confirm JOB [--group G]`: accept or correct the print the camera found.

A job whose detected print is less certain than ``camera.confirm_below`` waits at
"confirm fabric"; the operator looks at its ``detection.png`` (lattice and symmetry
elements over the photograph, the likeliest groups) and confirms the group, or names
the right one.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from solver.wallpaper import GROUP_NAMES
from station.cliargs import add_config_argument, load_config_arg
from station.control import ControlError, request
from station.errors import UserError


def register(sub: argparse._SubParsersAction) -> None:
    text = "accept or correct the detected print of a job waiting at 'confirm fabric'"
    p = sub.add_parser("confirm", help=text, description=text)
    p.add_argument("job", type=int)
    p.add_argument("--group", choices=GROUP_NAMES,
                   help="the print's wallpaper group, when the detected one is wrong")
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
    try:
        answer = request(socket, "confirm", **fields)
    except ControlError as exc:
        raise UserError(str(exc)) from None
    print(json.dumps(answer) if args.json else f"job {answer['job']}: {answer['message']}")
    return 0
