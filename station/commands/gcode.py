"""`station gcode`: G-code for a layout, checked against the machine profile before writing.

A job the station cuts in bites (issue 35) keeps bites.json beside its layout.json: the
marker is longer than the table, so its program is one bite's, chosen with ``--bite K``,
the bite placed where the planned advances leave it (the station measures the real ones
from the print, and cuts where the cloth really lies).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from gcode.layout import Layout as MachineLayout
from gcode.layout import load_layout
from gcode.machine import default_machine, load_machine
from solver.nest.bites import BitePlan
from solver.nest.layout import Layout
from station.errors import UserError
from station.steps.bites import ROLL_MARGIN_MM, RollTrack, load_bites
from station.steps.program import machine_layout, program_of

BITES_FILE = "bites.json"  # beside a layout.json the station cuts in bites


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "gcode",
        help="make the G-code program that cuts a layout",
        description="Toolpaths (kerf offset, notches, marks, inner contours first, short travel, "
        "G2/G3 arcs) and a GRBL program for a laser or knife, with a sync point after each "
        "piece. The program is checked against the machine profile (work area, feed, power, "
        "no laser during rapid moves) and is not written if any check fails.",
    )
    p.add_argument("layout", metavar="LAYOUT.json", help="the nested pieces (fabric mm)")
    p.add_argument("--machine", metavar="MACHINE.toml",
                   help="machine profile (default: built-in 1600 x 1000 mm GRBL laser table)")
    p.add_argument("-o", "--output", required=True, metavar="JOB.nc", help="program to write")
    p.add_argument("--pieces", metavar="ID,ID,...",
                   help="cut only these piece ids (e.g. the ones not cut yet)")
    p.add_argument("--bite", type=int, metavar="K",
                   help="a marker cut in bites (bites.json beside it): the program of bite K "
                   "(1 = the first), placed where the planned advances leave it")
    p.add_argument("--no-arcs", action="store_true", help="straight lines only (no G2/G3)")
    p.add_argument("--kerf", type=float, help="override the profile's kerf (mm)")
    p.add_argument("--passes", type=int, help="override the profile's passes")
    p.add_argument("--lead-in", type=float, help="override the profile's lead-in (mm)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    start = time.perf_counter()
    machine = load_machine(args.machine) if args.machine else default_machine()
    changes = {}
    if args.no_arcs:
        changes["arcs"] = False
    if args.kerf is not None:
        changes["kerf"] = args.kerf
    if args.passes is not None:
        changes["passes"] = args.passes
    if args.lead_in is not None:
        changes["lead_in"] = args.lead_in
    for name, value, most in (("--kerf", args.kerf, 20.0), ("--lead-in", args.lead_in, 1000.0)):
        if value is not None and not 0 <= value <= most:  # also refuses NaN
            raise ValueError(f"{name} must be 0 to {most:g} mm, got {value}")
    if changes:
        machine = machine.with_cut(**changes)
    layout = load_layout(args.layout)
    bite = chosen_bite(layout, Path(args.layout), args.bite)
    if bite is not None:
        layout, label = bite
    only = {s.strip() for s in args.pieces.split(",") if s.strip()} if args.pieces else None
    program, _ = program_of(layout, machine, only, title=f"station job {layout.source}",
                            source=str(args.layout))
    program.write(args.output)
    summary = program.summary()
    summary.update({
        "output": args.output,
        "machine": machine.name,
        "bytes": len(program.text()),
        "arcs": sum(ln.startswith(("G2 ", "G3 ")) for ln in program.lines),
        "warnings": program.warnings,
        "seconds": round(time.perf_counter() - start, 3),
        **({"bite": label} if bite is not None else {}),
    })
    if args.json:
        print(json.dumps(summary))
    else:
        for w in program.warnings:
            print(f"station gcode: warning: {w}", file=sys.stderr)
        print(f"{args.output}: {f'bite {label}, ' if bite is not None else ''}"
              f"{summary['lines']} lines, {summary['pieces']} pieces, "
              f"cut {summary['cut_length_mm'] / 1000:.2f} m, travel "
              f"{summary['travel_length_mm'] / 1000:.2f} m, about "
              f"{summary['estimated_seconds'] / 60:.1f} min on {machine.name}")
    return 0


def chosen_bite(marker: MachineLayout, path: Path, bite: int | None
                ) -> tuple[MachineLayout, str] | None:
    """(bite ``bite``'s marker, "K of N") of a marker cut in bites; None for a marker cut
    whole. A marker in bites without ``--bite`` is refused in one line saying how many."""
    plan = bites_beside(path)
    if plan is None:
        if bite is not None:
            raise UserError(f"{path}: --bite is for a marker cut in bites, and there is no "
                            f"{BITES_FILE} beside it")
        return None
    n = len(plan.bites)
    if bite is None or not 1 <= bite <= n:
        raise UserError(f"{path}: the marker is cut in {n} bites ({BITES_FILE} beside it, "
                        f"{plan.window_mm:g} mm of the table each): choose one with --bite 1 "
                        f"to {n}" + ("" if bite is None else f", not {bite}"))
    chosen = plan.bites[bite - 1]
    # the first bite lies where it was planned; each later one, after the planned advance
    # with no slip, begins ROLL_MARGIN_MM into the window (`RollTrack.advance_for`)
    shift = 0.0 if chosen.index == 0 else ROLL_MARGIN_MM - chosen.start_mm
    track = RollTrack(np.array([[1.0, 0.0, shift], [0.0, 1.0, 0.0]]))
    return (machine_layout(track.bite_layout(plan, chosen), marker.origin, str(path)),
            f"{bite} of {n}")


def bites_beside(path: Path) -> BitePlan | None:
    """The bites of the marker ``path`` (its bites.json), None for a marker cut whole."""
    beside = path.parent / BITES_FILE
    return load_bites(Layout.load(path), beside) if beside.is_file() else None
