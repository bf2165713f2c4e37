"""What a run of the streamer reports, and how it reads the program it streams.

The records (`PieceState`, `Progress`, `StreamResult`), the state a run is in
(`StreamState`), why it stops early (`Fault`), and the readings of the program's typed
blocks (`gcode.blocks.Block`) that a run needs: the code on the wire, which piece each
block belongs to and which sync proves it cut, where the head must stand before a block
turns the beam on.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from enum import Enum

import numpy as np

from gcode.program import Program
from gcode.session import StreamError
from gcode.watchdog import StopReason

__all__ = ["Fault", "PieceState", "Progress", "StreamResult", "StreamState", "piece_map",
           "stroke_starts", "wire_lines"]

class StreamState(str, Enum):
    """Where a run is: IDLE -> STREAMING (or CHECKING) -> DRAINING -> DONE, or from any
    of them -> STOPPING (the safe stop) -> STOPPED."""

    IDLE = "idle"
    CHECKING = "checking"
    STREAMING = "streaming"
    DRAINING = "draining"
    STOPPING = "stopping"
    DONE = "done"
    STOPPED = "stopped"




@dataclass
class PieceState:
    """The cut record of one piece; ``state`` is ``pending``, ``cutting`` or ``cut``."""

    number: int
    id: str
    name: str
    sync_line: int  # 0-based index into the program's lines
    state: str = "pending"


@dataclass
class Progress:
    lines_total: int
    lines_sent: int
    lines_acked: int
    fraction: float
    elapsed: float
    eta_seconds: float | None
    state: str | None  # last machine state reported
    pieces_cut: int


@dataclass
class StreamResult:
    """What happened: ``reason`` is a :class:`StopReason` (a ``str``: ``done``, ``checked``,
    ``error``, ``alarm``, ``reset``, ``garbled``, ``unmatched``, ``off_path``, ``feed``,
    ``power``, ``timeout``, ``hold``, ``disconnect``, ``stopped`` or ``interrupted``)."""

    completed: bool
    reason: StopReason | str
    lines_total: int
    lines_sent: int = 0
    lines_acked: int = 0
    errors: list[dict] = field(default_factory=list)
    alarms: list[dict] = field(default_factory=list)
    pieces: list[PieceState] = field(default_factory=list)
    fault: dict | None = None
    position: tuple[float, ...] | None = None
    seconds: float = 0.0
    check: bool = False
    messages: list[str] = field(default_factory=list)
    status_reports: int = 0  # reports the watchdog judged (its polling load)

    @property
    def pieces_cut(self) -> int:
        return sum(p.state == "cut" for p in self.pieces)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["pieces_cut"] = self.pieces_cut
        d["position"] = list(self.position) if self.position else None
        return d


class Fault(Exception):
    """A run stops early: why (`StopReason`), what was seen, the block to blame."""

    def __init__(self, reason: StopReason, detail: str, line: int | None = None):
        super().__init__(detail)
        self.reason, self.detail, self.line = reason, detail, line



def wire_lines(program: Program, budget: int, compact: bool = True,
               prefix: str = "") -> list[tuple[int, str]]:
    """(block index, code to send) of every block with code; refuses up front what must
    never reach the controller (real-time bytes, over-long lines)."""
    stream: list[tuple[int, str]] = []
    for i, block in enumerate(program.blocks):
        code = block.code.replace(" ", "") if compact else block.code
        if not code:
            continue
        bad = sorted({ch for ch in code if ch in "?!~" or not " " <= ch <= "~"})
        if bad:
            raise StreamError(f"{prefix}line {i + 1} holds real-time or non-ASCII "
                              f"character(s) {bad!r}: {code!r}")
        if len(code) > 79 or len(code) + 1 > budget:
            raise StreamError(f"{prefix}line {i + 1} is longer than GRBL accepts "
                              f"({len(code)} characters): {code!r}")
        stream.append((i, code))
    return stream


def piece_map(program: Program, stream: list[tuple[int, str]]
               ) -> tuple[list[PieceState], dict[int, int], np.ndarray]:
    """The pieces' records, stream position of each piece's sync -> piece, and the piece
    each stream position belongs to (-1: none, and none after its sync)."""
    pieces = [PieceState(p.number, p.id, p.name, p.sync_line) for p in program.pieces]
    by_number = {p.number: n for n, p in enumerate(program.pieces)}
    sync_at: dict[int, int] = {}
    piece_of = np.full(len(stream), -1)
    synced: set[int] = set()
    for k, (i, _) in enumerate(stream):
        n = by_number.get(program.blocks[i].piece)
        if n is None or n in synced:
            continue
        piece_of[k] = n
        if i == program.pieces[n].sync_line:
            sync_at[k] = n
            synced.add(n)
    return pieces, sync_at, piece_of


def stroke_starts(program: Program, lines: list[int]) -> dict[int, np.ndarray]:
    """Stream position -> the XY where the head must stand when that block (one turning
    the beam on) is sent: the end of the last move before it."""
    c = program.check
    if c is None or c.path is None or c.path_line is None or not len(c.path):
        return {}
    out: dict[int, np.ndarray] = {}
    for k, i in enumerate(lines):
        if program.blocks[i].turns_beam_on:
            j = int(np.searchsorted(c.path_line, i)) - 1  # path_line grows with the block
            out[k] = c.path[max(j, 0)]
    return out
