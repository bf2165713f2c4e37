"""Step 5 of a job: the program that cuts the marker.

The solver's marker (`solver.nest.layout.Layout`, fabric mm) becomes the machine's
(`gcode.layout.Layout`) in `machine_layout`, the one adapter between the two: inside a
process the marker goes on as an object; LAYOUT.json is read back, through `untrusted`
(`gcode.layout.load_layout`), only by a job resumed in another process and by
`station gcode`. `program_of` builds and checks the program of any machine layout, for
the daemon and the console alike.
"""

from __future__ import annotations

import numpy as np

from gcode.layout import Layout as MachineLayout
from gcode.layout import LayoutPiece, Notch, on_table
from gcode.machine import Machine, default_machine, load_machine
from gcode.program import Program, build_program
from gcode.toolpath import PieceToolpath, build_toolpaths
from solver.nest.bites import BitePlan
from solver.nest.layout import Layout, Placed
from station.config import Config
from station.steps.bites import RollTrack, save_bites

#: decimals LAYOUT.json keeps; the marker in memory is rounded alike, so that a job
#: resumed from the file cuts exactly the outlines of the one planned in memory
FILE_DECIMALS = 9


def station_machine(config: Config) -> Machine:
    """The configured machine profile with station.toml's [cut] (kerf, feed, power,
    passes) in force, checked against the profile's ranges; a refusal names the file
    and the key."""
    profile = config["machine"]["profile"]
    machine = load_machine(config.resolve(profile)) if profile else default_machine()
    cut = config["cut"]
    try:
        return machine.with_cut(kerf=float(cut["kerf_mm"]), feed=float(cut["feed_mm_min"]),
                                power=float(cut["power"]), passes=int(cut["passes"]))
    except ValueError as exc:
        where = config.path or "station.toml"
        detail = str(exc).split(": ", 1)[-1]
        raise ValueError(f"{where}: [cut] does not fit the machine profile "
                         f"{machine.source}: {detail}") from None


def fabric_origin(config: Config) -> tuple[float, float]:
    """Where the fabric's corner lies on the table (machine mm)."""
    ox, oy = config["machine"]["fabric_origin"]
    return float(ox), float(oy)


def machine_layout(layout: Layout, origin: tuple[float, float], source: str) -> MachineLayout:
    """The nested marker as the machine cuts it: the same pieces, the fabric at
    ``origin`` on the table. ``source`` names the marker in the program's refusals."""
    fabric = MachineLayout(pieces=[_machine_piece(p) for p in layout.pieces],
                           width=float(layout.width), length=float(layout.length),
                           gap=float(layout.gap), source=source)
    return on_table(fabric, origin)


def _machine_piece(piece: Placed) -> LayoutPiece:
    notches = []
    for at, direction, depth in piece.notches:
        d = _rounded(direction)
        norm = float(np.hypot(*d))
        notches.append(Notch(_rounded(at), d / norm if norm > 0 else d,
                             None if depth is None else round(float(depth), FILE_DECIMALS)))
    return LayoutPiece(
        id=str(piece.id), name=str(piece.name), outline=_ring(piece.outline),
        holes=[_ring(h) for h in piece.holes], notches=notches,
        marks=_rounded(piece.marks).reshape(-1, 2),
        grainline=None if piece.grainline is None or not len(piece.grainline)
        else _rounded(piece.grainline),
        transform=_rounded(piece.transform))


def _rounded(values) -> np.ndarray:
    return np.round(np.asarray(values, float), FILE_DECIMALS)


def _ring(points) -> np.ndarray:
    ring = _rounded(points)
    if len(ring) > 3 and np.allclose(ring[0], ring[-1]):
        ring = ring[:-1]  # the closing point repeated
    return ring


def program_of(layout: MachineLayout, machine: Machine, only: set[str] | None = None, *,
               title: str, source: str = "<program>") -> tuple[Program, list[PieceToolpath]]:
    """(the checked program of the pieces ``only`` (None: all) in cut order, their
    toolpaths)."""
    toolpaths = build_toolpaths(layout, machine, only=only)
    return build_program(toolpaths, machine, title=title, source=source), toolpaths


def planned_program(layout: Layout, bites: BitePlan | None, config: Config, machine: Machine,
                    workdir) -> tuple[MachineLayout, Program]:
    """(the marker the plan hands on, its checked program, written to job.nc): the whole
    marker, or, cut in bites, the first bite where it was planned (bites.json beside)."""
    if bites is not None:
        save_bites(bites, workdir / "bites.json")
        layout = RollTrack().bite_layout(bites, bites.bites[0])
    marker = machine_layout(layout, fabric_origin(config), str(workdir / "layout.json"))
    program, _ = program_of(marker, machine, title=f"station {workdir.name}")
    program.write(workdir / "job.nc")
    return marker, program
