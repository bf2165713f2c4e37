"""`station confirm JOB [--group G]`: accept or correct the print the camera found.

A job whose detected print is less certain than ``camera.confirm_below`` waits at
"confirm fabric"; the operator looks at its ``detection.png`` (lattice and symmetry
elements over the photograph) and confirms the group, or names the right one.
"""

from __future__ import annotations

import argparse
import json

from solver.wallpaper import GROUP_NAMES
from station.commands.console import _ask, _common


def register(sub: argparse._SubParsersAction) -> None:
    text = "accept or correct the detected print of a job waiting at 'confirm fabric'"
    p = sub.add_parser("confirm", help=text, description=text)
    p.add_argument("job", type=int)
    p.add_argument("--group", choices=GROUP_NAMES,
                   help="the print's wallpaper group, when the detected one is wrong")
    _common(p, run)


def run(args: argparse.Namespace) -> int:
    fields = {"job": args.job} | ({"group": args.group} if args.group else {})
    answer = _ask(args, "confirm", **fields)
    print(json.dumps(answer) if args.json else f"job {answer['job']}: {answer['message']}")
    return 0
