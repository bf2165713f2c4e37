"""G-code programs for a GRBL laser or knife: typed blocks, per-piece sync points, markers.

The builder writes :class:`gcode.blocks.Block` s, never text; every program is checked
against the machine profile (:func:`gcode.check.validate`) before it is written or sent,
and rendered to text only at the edge (:meth:`Program.text`, :meth:`Program.write`, the
lines the streamer puts on the wire). A ``.nc`` file read from disk (:func:`load_program`)
is parsed into the same blocks and checked the same way.

Each piece is bracketed by comments ``(piece N begin ID NAME)`` / ``(piece N end)`` with a
``G4 P0.01`` sync block just before the end marker, so the streamer can recover the pieces
from the .nc file alone. GRBL's ``ok`` to a G4 comes only after every motion before it has
finished, which is what proves the piece was cut. With :class:`PieceMarkers` the builder
also brackets each piece's final move with the EEPROM markers of `gcode.recovery`.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

import untrusted
from gcode.arcs import CW, LINE, FittedPath
from gcode.blocks import Block, Sync, comment_block, marker_block, num, parse_lines, settle
from gcode.blocks import strip_comment as strip_comment
from gcode.check import MAX_LINE, Check, ProgramError, validate
from gcode.machine import POWER_MODES, Machine
from gcode.toolpath import PieceToolpath

__all__ = [
    "Check",
    "MAX_LINE",
    "PieceMarkers",
    "PieceRange",
    "Program",
    "ProgramError",
    "build_program",
    "load_program",
    "parse_pieces",
    "program_moves",
    "sanitize_comment",
    "STROKE_SYNC",
    "strip_comment",
    "validate",
]

SYNC = "G4 P0.01"
#: after every stroke: answered once the stroke has run, so the station knows exactly which
#: strokes of a piece are cut (gcode.resume); the piece's own SYNC stays its last G4
STROKE_SYNC = "G4 P0"
_ALLOWED = re.compile(r"[^A-Za-z0-9 _.,:#+/=-]")
_PIECE = re.compile(r"^piece (\d+) (begin|end)(?: (.*))?$")


def sanitize_comment(text: str, limit: int = 60) -> str:
    """Text safe inside a G-code comment: no newline, parentheses, $, %, ; nor GRBL's
    real-time characters (? ! ~ and control bytes act even inside comments)."""
    return _ALLOWED.sub("_", text)[:limit]


def _one_word(text: str) -> str:
    return re.sub(r"\s", "_", text)


@dataclass
class PieceRange:
    """Where one piece lives in the program (0-based block indexes into ``Program.blocks``)."""

    number: int  # 1-based position in the cut order
    id: str
    name: str
    first_line: int  # the "(piece N begin ...)" comment
    sync_line: int  # the G4 whose ok proves the piece is cut
    last_line: int  # the "(piece N end)" comment


@dataclass(frozen=True)
class PieceMarkers:
    """Ask the builder for the recovery markers (`gcode.recovery`): the job they name and
    each piece's index in the job store, by piece id."""

    job: int
    index: dict[str, int]


@dataclass
class Program:
    """Typed G-code blocks plus, per piece, its block range and sync block."""

    blocks: list[Block]
    pieces: list[PieceRange] = field(default_factory=list)
    check: Check | None = None
    warnings: list[str] = field(default_factory=list)

    @property
    def lines(self) -> list[str]:
        """The blocks rendered as text, one line each."""
        return [b.text for b in self.blocks]

    def text(self) -> str:
        return "\n".join(self.lines) + "\n"

    def write(self, path: str | Path) -> None:
        Path(path).write_text(self.text(), encoding="ascii")

    def summary(self) -> dict:
        c = self.check
        return {
            "lines": len(self.blocks),
            "pieces": len(self.pieces),
            "cut_length_mm": round(c.cut_length_mm, 3) if c else None,
            "travel_length_mm": round(c.travel_length_mm, 3) if c else None,
            "estimated_seconds": round(c.estimated_seconds, 2) if c else None,
        }


# ---------------------------------------------------------------- generation

class _Writer:
    """Appends blocks; remembers where the head is and the last feed move written."""

    def __init__(self, machine: Machine):
        self.m = machine
        self.blocks: list[Block] = []
        self.pos: tuple[str, str] | None = None  # the head's X, Y as last written
        self.piece = 0  # the piece being written (0: none)
        self.last_move: int | None = None  # block of the last G1/G2/G3 of the piece

    def add(self, block: Block) -> int:
        if len(block.text) > MAX_LINE:
            raise ProgramError(f"generated line longer than {MAX_LINE} characters: "
                               f"{block.text!r}")
        self.blocks.append(block)
        return len(self.blocks) - 1

    def emit(self, *words: str, sync: Sync = Sync.NONE) -> int:
        k = self.add(Block(words, piece=self.piece, sync=sync))
        if words[0] in ("G1", "G2", "G3"):
            self.last_move = k
        return k

    def comment(self, text: str) -> int:
        return self.add(comment_block(text, self.piece))

    def rapid_to(self, p: np.ndarray) -> None:
        """G0 to ``p`` unless the head is already there."""
        xy = (num(p[0]), num(p[1]))
        if xy != self.pos:
            self.emit("G0", f"X{xy[0]}", f"Y{xy[1]}")
            self.pos = xy

    def moves(self, path: FittedPath, feed: float) -> None:
        prev = path.start
        for k, (kind, end, c) in enumerate(zip(path.kind, path.end, path.center, strict=True)):
            f = (f"F{num(feed)}",) if k == 0 else ()
            xy = (f"X{num(end[0])}", f"Y{num(end[1])}")
            if kind == LINE:
                self.emit("G1", *xy, *f)
            else:
                ij = c - prev
                self.emit("G2" if kind == CW else "G3", *xy, f"I{num(ij[0])}",
                          f"J{num(ij[1])}", *f)
            prev = end
        self.pos = (num(prev[0]), num(prev[1]))

    def bracket_final_move(self, markers: PieceMarkers, piece_id: str) -> None:
        """The recovery markers around the piece's final feed move (phase 1 before, 2 after)."""
        if self.last_move is None:
            return
        k = markers.index[piece_id]
        self.blocks.insert(self.last_move + 1, marker_block(markers.job, k, 2, self.piece))
        self.blocks.insert(self.last_move, marker_block(markers.job, k, 1, self.piece))


def _laser_stroke(w: _Writer, path: FittedPath, power: float, passes: int, closed: bool) -> None:
    m = w.m
    for k in range(passes):
        if k == 0 or not closed:
            w.rapid_to(path.start)
        w.emit(POWER_MODES[m.cut.power_mode], f"S{num(power)}")
        w.moves(path, m.cut.feed)
        if not closed or k == passes - 1:
            w.emit("M5")


def _knife_stroke(w: _Writer, path: FittedPath) -> None:
    kn = w.m.knife
    w.rapid_to(path.start)
    w.emit("G1", f"Z{num(kn.z_down)}", f"F{num(kn.plunge_feed)}")
    if len(path):
        w.moves(path, w.m.cut.feed)
    w.emit("G0", f"Z{num(kn.z_up)}")


def _piece(w: _Writer, number: int, tp: PieceToolpath, markers: PieceMarkers | None
           ) -> PieceRange:
    """One piece's blocks: its strokes, each followed by its stroke sync, then its sync."""
    m, c = w.m, w.m.cut
    w.piece, w.last_move = number, None
    # the id is one word (the reader takes the first): a DXF piece "REGULAR TEEFR" keeps
    # its spaces in the name, its id reads back as REGULAR_TEEFR, never as "REGULAR"
    first = w.comment(f"piece {number} begin {_one_word(sanitize_comment(tp.id, 30))} "
                      f"{sanitize_comment(tp.name, 20)}")
    for contour in tp.contours:
        for stroke in contour.strokes:
            if m.tool == "laser":
                is_mark = contour.kind == "mark"
                closed = contour.closed and len(contour.strokes) == 1 and np.allclose(
                    stroke.start, stroke.end[-1])
                _laser_stroke(w, stroke, c.mark_power if is_mark else c.power,
                              1 if is_mark else c.passes, closed)
            else:
                _knife_stroke(w, stroke)
            w.emit(*STROKE_SYNC.split(), sync=Sync.STROKE)
    if markers is not None:
        w.bracket_final_move(markers, tp.id)
    sync = w.emit(*SYNC.split(), sync=Sync.PIECE)
    last = w.comment(f"piece {number} end")
    w.piece = 0
    return PieceRange(number, tp.id, tp.name, first, sync, last)


def _head(w: _Writer, n_pieces: int, title: str) -> None:
    """The opening blocks (modes, tool off, air assist) for an empty writer."""
    m, laser = w.m, w.m.tool == "laser"
    w.comment(sanitize_comment(title))
    w.comment(f"machine {sanitize_comment(m.name)} tool {m.tool} pieces {n_pieces}")
    w.emit("G21", "G90", "G94", "G17")
    w.emit("M5")
    w.emit("M9")
    if not laser:
        w.emit("G0", f"Z{num(m.knife.z_up)}")
    if laser and m.cut.air_assist:
        w.emit("M8")


def _park(w: _Writer) -> None:
    """Tool and air off, knife up, head to the park position, end of program."""
    w.emit("M5")
    w.emit("M9")
    if w.m.tool != "laser":
        w.emit("G0", f"Z{num(w.m.knife.z_up)}")
    w.pos = None  # always park explicitly
    w.rapid_to(np.asarray(w.m.park))
    w.emit("M2")


def build_program(toolpaths: list[PieceToolpath], machine: Machine, *, title: str = "station job",
                  source: str = "<program>", markers: PieceMarkers | None = None) -> Program:
    """The G-code program for the toolpaths, validated against ``machine`` (ProgramError).

    With ``markers`` each piece's final move is bracketed by the EEPROM markers that let a
    restarted station know what the machine finished (`gcode.recovery`); they are checked
    with everything else. A refusal names ``source`` (the layout file), the program line
    and the piece it cuts.
    """
    missing = [tp.id for tp in toolpaths if markers is not None and tp.id not in markers.index]
    if missing:
        raise ValueError(f"{source}: the markers have no store index for piece(s) {missing}")
    w = _Writer(machine)
    _head(w, len(toolpaths), title)
    pieces = [_piece(w, number, tp, markers) for number, tp in enumerate(toolpaths, start=1)]
    _park(w)
    blocks = settle(w.blocks)
    prog = Program(blocks, pieces, warnings=[x for tp in toolpaths for x in tp.warnings])
    try:
        prog.check = validate(blocks, machine, source)
    except ProgramError as exc:
        raise _blamed(exc, blocks, pieces, source) from None
    return prog


def _blamed(exc: ProgramError, blocks: Sequence[Block], pieces: list[PieceRange],
            source: str) -> ProgramError:
    """The checker's refusal of a built program, naming the piece and what to do."""
    i = exc.line if exc.line is not None else 0
    msg = f"{source}: program line {i + 1}: {exc.detail}: {blocks[i].text.strip()!r}"
    piece = next((p for p in pieces if p.first_line <= i <= p.last_line), None)
    if piece is not None:
        msg += f" (piece {piece.id})"
    if "outside the work area" in msg:
        msg += "; the layout's origin places the fabric on the table, leave room for " \
               "the kerf and lead-ins"
    return ProgramError(msg, i, exc.detail)


# ---------------------------------------------------------------- reading back

def _piece_comment(b: Block) -> re.Match | None:
    return None if b.words or b.comment is None else _PIECE.match(b.comment.strip())


def parse_pieces(blocks: Sequence[Block] | Sequence[str], source: str = "<program>"
                 ) -> list[PieceRange]:
    """Recover the per-piece ranges and sync blocks from a program's comments."""
    if blocks and isinstance(blocks[0], str):
        blocks = parse_lines(blocks)
    out: list[PieceRange] = []
    open_: tuple[int, str, str, int] | None = None
    for i, b in enumerate(blocks):
        m = _piece_comment(b)
        if not m:
            continue
        number, what, rest = int(m.group(1)), m.group(2), m.group(3) or ""
        if what == "begin":
            if open_ is not None:
                raise ProgramError(f"{source}:{i + 1}: piece {number} begins inside piece "
                                   f"{open_[0]}")
            pid, _, name = rest.partition(" ")
            open_ = (number, pid, name or pid, i)
            continue
        if open_ is None or open_[0] != number:
            raise ProgramError(f"{source}:{i + 1}: end of piece {number} without its begin")
        sync = next((k for k in range(i - 1, open_[3], -1) if 4.0 in blocks[k].g), None)
        if sync is None:
            raise ProgramError(f"{source}:{i + 1}: piece {number} has no G4 sync line "
                               "before its end marker")
        out.append(PieceRange(number, open_[1], open_[2], open_[3], sync, i))
        open_ = None
    if open_ is not None:
        raise ProgramError(f"{source}: piece {open_[0]} has no end marker")
    return out


def _with_pieces(blocks: list[Block], pieces: list[PieceRange]) -> list[Block]:
    """The blocks with their piece numbers and each piece's sync block marked."""
    out = list(blocks)
    for r in pieces:
        for k in range(r.first_line, r.last_line + 1):
            out[k] = replace(out[k], piece=r.number,
                             sync=Sync.PIECE if k == r.sync_line else out[k].sync)
    return out


def program_from_lines(lines: Sequence[str], source: str = "<program>") -> Program:
    """A program read from lines of text (not yet checked): its blocks and pieces."""
    blocks = parse_lines(lines)
    pieces = parse_pieces(blocks, source)
    return Program(_with_pieces(blocks, pieces), pieces)


def load_program(path: str | Path, machine: Machine) -> Program:
    """Read a .nc file, recover its pieces and validate it against ``machine``."""
    p = Path(path)
    raw = untrusted.read_bytes(p, what="program", max_bytes=untrusted.limits.MAX_GCODE_BYTES)
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError as exc:
        raise ProgramError(f"{p}: non-ASCII byte at offset {exc.start}") from None
    lines = text.splitlines()
    if not any(strip_comment(line).strip() for line in lines):
        raise ProgramError(f"{p}: no G-code in the program (empty file?)")
    prog = program_from_lines(lines, str(p))
    prog.check = validate(prog.blocks, machine, str(p))
    return prog


def program_moves(program: Program) -> list[tuple[int, bool, int, np.ndarray]]:
    """Every move of a checked program as (block, cutting, piece number or 0, (k, 2) points),
    read from what :func:`validate` interpreted (arcs sampled 1 mm apart): the one reading
    of the G-code that the pictures and the crash recovery share with the checker."""
    c = program.check
    if c is None or c.path is None or c.path_line is None or c.line_on is None:
        raise ProgramError("program_moves needs a validated program (Program.check)")
    piece_at = np.array([b.piece for b in program.blocks], int)
    lines, starts = np.unique(c.path_line, return_index=True)
    ends = np.r_[starts[1:], len(c.path_line)]
    return [(int(k), bool(c.line_on[k]), int(piece_at[k]), c.path[a:b])
            for k, a, b in zip(lines, starts, ends, strict=True) if k >= 0]
