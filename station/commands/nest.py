"""`station nest`: place the pieces on the roll (plain or printed fabric) -> LAYOUT.json."""

from __future__ import annotations

import json
import sys
import time

import numpy as np

from solver.nest.budget import Deadline
from solver.nest.layout import verify_layout
from solver.nest.plain import stderr_progress
from solver.nest.regions import load_keepouts
from solver.nest.solve import nest
from solver.nest.sources import load_problem
from solver.wallpaper import Wallpaper
from station import order_commands as order_command
from station.cliargs import (
    add_allowance_arguments,
    add_config_argument,
    load_config_arg,
    picture_path,
)
from station.cliload import allowance_rules
from station.errors import UserError
from station.render import draw_marker


def register(sub) -> None:
    p = sub.add_parser(
        "nest", help="nest pieces on the fabric roll (LAYOUT.json)",
        description="Nest pieces on a roll of fabric. INPUT is a PLACEMENT.json (garment and "
        "print), a DXF-AAMA/ASTM pattern file, or a strip-packing instance JSON (its "
        "strip_height is the width). With a print (--fabric, or the placement's), every "
        "piece moves only by symmetries of the print, so the alignment is kept. The layout "
        "is verified independently before it is written.")
    p.add_argument("inputs", nargs="+", metavar="INPUT",
                   help="PLACEMENT.json, DXF or instance JSON (several: one marker), or an "
                   "ORDER.toml (or what `align ORDER` wrote): every garment of it in one marker")
    p.add_argument("-o", "--output", required=True, metavar="LAYOUT.json")
    p.add_argument("--fabric", metavar="FABRIC.json", help="the print under the pieces")
    p.add_argument("--plain", action="store_true",
                   help="nest the same pieces as on plain cloth, ignoring any print: pieces "
                   "stay on grain and turn only as the grain rule allows (the baseline "
                   "for a printed marker's density)")
    p.add_argument("--width", type=float, help="fabric width in mm (across the roll; default: "
                   "the input's, else station.toml [nest] width_mm)")
    p.add_argument("--length", type=float, help="usable length in mm (the table window)")
    p.add_argument("--gap", type=float, default=0.0, help="minimum gap between pieces and "
                   "to the fabric edge, mm (default 0)")
    p.add_argument("--time", type=float, default=30.0, metavar="SECONDS",
                   help="time from start to a verified layout, kept within about 10 %% "
                   "(default 30)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--keepout", metavar="FLAWS.json",
                   help="keep-out polygons on the fabric: {\"keepouts\": [[[x, y], ...], ...]}")
    p.add_argument("--size", help="sizes to cut from a graded DXF, comma-separated")
    p.add_argument("--units", help="units of a DXF or garment file that does not say "
                   "(mm, cm, m, in)")
    p.add_argument("--quantity", type=int, default=1, help="markers' worth of each piece")
    p.add_argument("--pairs", action="store_true",
                   help="cut every piece also mirrored (left and right)")
    p.add_argument("--method", default="auto",
                   choices=("auto", "resnap", "resnap-margin", "fill", "repair", "joint",
                            "coset", "naive"),
                   help="search on a print (default auto: joint (sparrow's nests snapped "
                   "jointly to the print), fill, then coset shrinks the best; naive first "
                   "when the time is short)")
    p.add_argument("--nap", action="store_true",
                   help="one-way print or napped fabric: no piece turns by 180 degrees")
    p.add_argument("--grain", choices=("on", "off"),
                   help="on: turn pieces only by 0 or 180 degrees, off: turn freely "
                   "(default: what each input says; a placement keeps its grain rule)")
    add_allowance_arguments(p)
    add_config_argument(p)
    p.add_argument("--json", action="store_true", help="print a JSON summary on stdout")
    p.add_argument("--png", metavar="OUT.png", type=picture_path, help="draw the marker")
    p.set_defaults(func=run)


def run(args) -> int:
    if not 0 < args.time <= 3600:  # also refuses NaN; sparrow cannot take more than an hour
        raise UserError("--time must be above 0 and at most 3600 seconds")
    if args.gap < 0:
        raise UserError("--gap must not be negative")
    if args.plain and args.fabric:
        raise UserError("--plain nests without a print: drop --fabric")
    config = load_config_arg(args)
    if any(order_command.is_order_input(p) for p in args.inputs):
        return order_command.run_nest(args, config)
    t0 = time.monotonic()
    deadline = Deadline(args.time)  # loading the pieces counts too
    fabric = Wallpaper.load(args.fabric) if args.fabric else None
    problem = load_problem(
        args.inputs, width=args.width, length=args.length, gap=args.gap, fabric=fabric,
        sizes=args.size.split(",") if args.size else None, units=args.units,
        quantity=args.quantity, pairs=args.pairs,
        keepouts=load_keepouts(args.keepout) if args.keepout else None,
        allowance=allowance_rules(args, config), default_width=config["nest"]["width_mm"],
        plain=args.plain)
    if args.nap or args.grain:
        turns = (0.0,) if args.nap else None if args.grain == "off" else (0.0, 180.0)
        for piece in problem.pieces:
            piece.orientations = turns
    startup = 0.0
    if problem.fabric is not None:  # one-off process start-up, not search: numba's
        # compiled closest-point kernel loads from its cache (1-2 s on a loaded machine)
        t = time.monotonic()
        problem.fabric.lattice_residual(np.zeros((1, 2)))
        startup = time.monotonic() - t
        deadline = deadline.later(startup)
    progress = stderr_progress
    try:
        layout = nest(problem, time_limit=deadline, seed=args.seed, progress=progress,
                      method=args.method)
    except ValueError as exc:  # e.g. a piece wider than the fabric: name the input
        raise UserError(f"{', '.join(map(str, args.inputs))}: {exc}") from None
    faults = verify_layout(layout, problem)
    seconds = time.monotonic() - t0 - startup
    if faults:
        raise UserError(f"the layout failed verification: {faults[0]} "
                        f"({len(faults)} faults); nothing written")
    layout.save(args.output)
    _warn_past_table(layout.length, args.length, config["nest"]["length_mm"])
    if layout.width > config["nest"]["width_mm"] + 1e-9:  # issue 35: say it now, not at cut
        print(f"station nest: warning: the marker is {layout.width:g} mm wide but the table "
              f"window is {config['nest']['width_mm']:g} mm across (station.toml [nest] "
              "width_mm): station gcode will refuse it", file=sys.stderr)
    if args.png:
        draw_marker(layout, args.png)
    summary = {"length": round(layout.length, 6), "width": layout.width,
               "density": round(layout.density, 6), "pieces": len(layout.pieces),
               "seconds": round(seconds, 3), "startup_seconds": round(startup, 3),
               "printed": problem.fabric is not None,
               "output": str(args.output), "allowance": layout.allowance}
    if args.json:
        print(json.dumps(summary))
    else:
        a = layout.allowance
        cut = (f", cut lines with {a['seam_mm']:g} mm seams, {a['hem_mm']:g} mm hems"
               if a else "")
        print(f"{summary['pieces']} pieces, length {layout.length:.1f} mm, "
              f"density {layout.density:.1%}{cut}, {seconds:.1f} s -> {args.output}")
    return 0


def _warn_past_table(length: float, asked: float | None, table: float) -> None:
    """Say now, not at `station gcode`, when an unbounded marker is longer than the table
    window (station.toml [nest] length_mm): the table cannot cut it in one job."""
    if asked is None and length > table + 1e-9:
        print(f"station nest: warning: the marker is {length:.1f} mm long but the table "
              f"window is {table:g} mm (station.toml [nest] length_mm): station gcode will "
              f"refuse it; nest with --length {table:g} or cut fewer pieces per marker",
              file=sys.stderr)
