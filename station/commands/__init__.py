"""One module per group of `station` subcommands, and the table that names them.

Each module defines ``register(subparsers)``, which adds its parsers and sets ``func`` to
a callable ``(args) -> int``. `COMMANDS` names every command, its module and its one-line
help, so that `station --help` lists them all without importing one module (a test keeps
the table equal to what the modules register). Adding a command means adding its module
here and a line to the table.
"""

from __future__ import annotations

from typing import NamedTuple


class Command(NamedTuple):
    module: str  # in this package
    help: str  # the one line `station --help` shows, as the module's register() gives it


COMMANDS: dict[str, Command] = {
    "align": Command("align", "align the print across the seams (paper Sec. 4, or the global "
                     "method)"),
    "calibrate": Command("calibrate", "calibrate the camera to the table with a ChArUco board"),
    "confirm": Command("confirm", "accept or correct the detected print of a job waiting at "
                       "'confirm fabric', or the inferred seams of one waiting at "
                       "'confirm seams'"),
    "submit": Command("submit", "queue a garment to be aligned, nested and cut"),
    "jobs": Command("console", "list every job"),
    "status": Command("console", "state, pieces and progress"),
    "pause": Command("console", "feed hold now (cutting) or after the current step"),
    "resume": Command("console", "continue a paused or interrupted job"),
    "abort": Command("console", "stop the job safely (feed hold, reset, laser off)"),
    "retry": Command("console", "queue a failed or aborted job again"),
    "log": Command("console", "the job store's event log"),
    "demo": Command("demo", "run one whole job on the simulated station"),
    "detect": Command("detect", "find the print's lattice, wallpaper group and origin in a "
                      "photo"),
    "fit": Command("fit", "measure how well the print matches across the seams (paper Eq. 1)"),
    "fleet": Command("fleet", "the stations sharing the job store"),
    "reassign": Command("fleet", "give an interrupted job to another station"),
    "gcode": Command("gcode", "make the G-code program that cuts a layout"),
    "inspect": Command("inspect", "show a garment's pieces, seam lines, seam edges, units and "
                       "piece sizes"),
    "nest": Command("nest", "nest pieces on the fabric roll (LAYOUT.json)"),
    "preview": Command("preview", "picture of a job's marker on the fabric"),
    "reshape": Command("reshape", "deform the pattern so the print fits perfectly along the "
                       "seams (paper Sec. 5)"),
    "serve": Command("serve", "run the station daemon"),
    "sim-grbl": Command("sim_grbl", "serve the GRBL 1.1 emulator on a pseudo-terminal"),
    "simulate-camera": Command("simulate_camera", "photograph simulated fabric or a ChArUco "
                               "board, with truth"),
    "simulate-calibration": Command("simulate_calibration", "calibrate the synthetic camera "
                                    "from rendered ChArUco views"),
    "simulate-fabric": Command("simulate_fabric", "render a print of a chosen wallpaper group, "
                               "with its truth"),
    "simulate-stream": Command("simulate_stream", "stream a program to the GRBL emulator, "
                               "tracing its motion"),
    "stream": Command("stream", "stream a program to a GRBL controller (serial port, pty or "
                      "pyserial URL)"),
    "watch": Command("watch", "progress bars for a running job"),
}
