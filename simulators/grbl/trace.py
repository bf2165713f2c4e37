"""The emulator's executed motion as CSV, in the program's work coordinates.

What the machine did, not what the sender believed: operators compare it with what was
planned, and tests check the machine against the program with it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from simulators.grbl.emulator import GrblEmulator

__all__ = ["TRACE_HEADER", "trace_rows", "write_trace"]

TRACE_HEADER = "x0,y0,x1,y1,feed,power,rapid"


def trace_rows(emulator: GrblEmulator) -> np.ndarray:
    """(n, 7) float array: x0, y0, x1, y1 (work mm), feed (mm/min), power (S), rapid (0/1).

    The trace is kept in machine coordinates; the work offset in force now (G54 + G92 of
    the active system) takes it back to the program's coordinates.
    """
    rows = np.array([(s.x0, s.y0, s.x1, s.y1, s.feed, s.power, float(s.rapid))
                     for s in emulator.trace], float).reshape(-1, 7)
    offset = (emulator.mpos - emulator.wpos)[:2]
    rows[:, 0:4] -= np.tile(offset, 2)
    return rows


def write_trace(emulator: GrblEmulator, path: str | Path) -> int:
    """Write the trace CSV (header line, one segment a line); returns the segment count."""
    rows = trace_rows(emulator)
    np.savetxt(path, rows, fmt=["%.4f"] * 4 + ["%.1f", "%.1f", "%d"], delimiter=",",
               header=TRACE_HEADER, comments="")
    return len(rows)
