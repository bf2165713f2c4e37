"""`station submit GARMENT`: queue a garment on the running daemon (or the fleet).

The daemon checks the garment before it answers; through the fleet (``--station`` or
``--fleet``) no daemon has it yet, so the same checks run here first.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from solver.garment.grain import parse_grain_lines
from solver.jsonfile import read_json
from station.cliargs import load_config_arg
from station.cliload import read_name_map
from station.commands.console import add_console_arguments, ask
from station.errors import UserError
from station.steps.submission import check_job


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
    p.add_argument("--seams", metavar="S.json",
                   help="a DXF pattern's seams, declared or vetoed as `station inspect "
                   "--seams` takes them (sent by value): the job does not ask to confirm them")
    p.add_argument("--symmetrise", action="store_true",
                   help="cut each near left/right pair as one pattern, the average of the two")
    p.add_argument("--no-symmetry", action="store_true",
                   help="align every piece on its own (default: pairs mirror the print)")
    p.add_argument("--no-stripe-matching", action="store_true",
                   help="on a stripe print, nest on the stripes' grain without matching the "
                   "stripes across the seams (default: matched, as a 1-D print)")
    p.add_argument("--match-notches", action="store_true",
                   help="on a print, put the balance notches where its lattice lines cross "
                   "each seam (the plaid's match points), not every ~200 mm")
    p.add_argument("--seam-allowance", type=float, metavar="MM",
                   help="seam allowance for this job (default: station.toml)")
    p.add_argument("--allowance", metavar="A.json",
                   help="allowances per seam line or opening for this job (sent by value)")
    p.add_argument("--wait", type=float, default=600.0, metavar="SECONDS",
                   help="how long to wait while the daemon checks the garment (default 600)")
    add_console_arguments(p, run)


def _table(text: str) -> tuple[float, float]:
    try:
        x, y = (float(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected XxY in mm, e.g. 1200x900"
                                         ) from None
    if x <= 0 or y <= 0:
        raise argparse.ArgumentTypeError(f"{text!r}: sizes must be positive")
    return x, y


def _check_job(args: argparse.Namespace, fields: dict[str, Any]) -> None:
    """Refuse here what no station could run, with the daemon's own submission step."""
    for key in ("garment", "fabric"):
        if fields.get(key) is not None and not Path(fields[key]).is_file():
            raise UserError(f"{fields[key]}: no such {key} file")
    check_job(fields["garment"], fields.get("fabric"), fields.get("options") or {},
              load_config_arg(args))


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


def run(args: argparse.Namespace) -> int:
    fleet = {k: v for k, v in (("tool", args.tool), ("table_mm", args.min_table)) if v}
    if fleet and not (args.station or args.fleet):
        raise UserError("--tool and --min-table choose among the stations of a fleet: "
                        "add --fleet")
    if not args.wait > 0:
        raise UserError("--wait must be positive")
    answer = ask(args, "submit", before_fleet=lambda fields: _check_job(args, fields),
                 garment=str(Path(args.garment).resolve()),
                 fabric=str(Path(args.fabric).resolve()) if args.fabric else None,
                 options=_options(args), timeout=args.wait, on_wait=_Patience(args.garment),
                 **fleet)
    if args.json:
        print(json.dumps(answer))
    else:
        print(f"job {answer['job']['id']} submitted")
    return 0


def _options(args: argparse.Namespace) -> dict[str, Any]:
    """The job's options as the daemon takes them: only those the operator gave."""
    options = {k: v for k, v in (("units", args.units), ("size", args.size),
                                 ("reshape", args.reshape or None),
                                 ("method", args.method), ("restarts", args.restarts),
                                 ("seam_allowance", args.seam_allowance))
               if v is not None}
    if args.allowance:
        options["allowance"] = {str(k): v for k, v in
                                read_name_map(args.allowance, "allowance").items()}
    if args.grain_line:
        options["grain_lines"] = parse_grain_lines(args.grain_line)
    if args.bias:
        options["bias"] = list(args.bias)
    if args.no_symmetry:
        options["symmetry"] = False
    if args.no_stripe_matching:
        options["match_stripes"] = False
    if args.symmetrise:
        options["symmetrise"] = True
    if args.match_notches:
        options["match_notches"] = True
    if args.pairs:
        options["pairs"] = read_json(args.pairs)
    if args.seams:
        options["seams"] = read_json(args.seams)
    return options
