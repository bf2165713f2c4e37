"""What the G-code parser keeps between blocks (GRBL's gc_state and its EEPROM parameters),
the move request it hands the planner, and how GRBL prints them (`$G`, numbers)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

MM_PER_INCH = 25.4


class GrblError(Exception):
    """A status code GRBL answers as `error:N`."""

    def __init__(self, code: int):
        super().__init__(f"error:{code}")
        self.code = code


@dataclass
class ParserState:
    """GRBL's gc_state: modal groups, T/F/S, parser position (machine mm) and offsets."""

    motion: str = "G0"  # G0 G1 G2 G3 G80
    coord_index: int = 0  # 0..5 -> G54..G59
    plane: int = 17
    inches: bool = False
    incremental: bool = False
    inverse_time: bool = False
    program: str = ""  # "M0", "M1" shown by $G while paused
    spindle: str = "M5"
    flood: bool = False
    tool: int = 0
    feed: float = 0.0  # mm/min (stored in mm as GRBL does)
    speed: float = 0.0
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    g92: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tlo: float = 0.0


@dataclass
class Params:
    """Non-volatile G-code parameters (EEPROM): G54..G59, G28, G30."""

    coord: np.ndarray = field(default_factory=lambda: np.zeros((6, 3)))
    g28: np.ndarray = field(default_factory=lambda: np.zeros(3))
    g30: np.ndarray = field(default_factory=lambda: np.zeros(3))


@dataclass
class Move:
    """One planner block request: target in machine mm, feed in mm/min (None = rapid)."""

    target: np.ndarray
    feed: float | None
    jog: bool = False
    spindle: str = "M5"
    speed: float = 0.0
    line_number: int = 0


def work_offset(state: ParserState, params: Params) -> np.ndarray:
    """Machine position minus work position: the selected G54..G59 origin, G92 and the tool
    length offset on Z (the `WCO:` of a status report)."""
    off = params.coord[state.coord_index] + state.g92
    off = off.copy()
    off[2] += state.tlo
    return off


def gc_report(state: ParserState) -> str:
    """The `$G` line, e.g. `[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]`."""
    parts = [
        state.motion,
        f"G{54 + state.coord_index}",
        f"G{state.plane}",
        "G20" if state.inches else "G21",
        "G91" if state.incremental else "G90",
        "G93" if state.inverse_time else "G94",
    ]
    if state.program:
        parts.append(state.program)
    parts.append(state.spindle)
    parts.append("M8" if state.flood else "M9")
    feed = state.feed / MM_PER_INCH if state.inches else state.feed
    parts += [f"T{state.tool}", f"F{fmt(feed, 0)}", f"S{fmt(state.speed, 0)}"]
    return "[GC:" + " ".join(parts) + "]"


def fmt(value: float, decimals: int) -> str:
    """GRBL's printFloat: fixed decimals, no decimal point when decimals == 0, no `-0`."""
    text = f"{value:.{decimals}f}"
    if text.startswith("-") and float(text) == 0.0:
        text = text[1:]
    return text
