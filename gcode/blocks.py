"""The typed G-code block: what a program is made of, from the builder to the wire.

A program is a list of :class:`Block`; text exists only at the edges: rendered when a
program is written or sent (:attr:`Block.text`, :attr:`Block.code`), parsed when a ``.nc``
file is read (:func:`parse_lines`, the one text parser of ``gcode``). The checker, the
sync markers, recovery, resume, the pictures and the streamer all read the same blocks'
attributes, so they cannot disagree about what a line does.

Words are kept as written (``"X12.5"``) so that a program renders byte for byte as it was
built, and a block read from a file keeps its line (``raw``) so it goes out as it came in.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from enum import Enum

__all__ = ["MARKER_SYSTEM", "Block", "Motion", "Sync", "comment_block", "marker_block", "num",
           "parse_line", "parse_lines", "settle", "strip_comment"]

#: The work coordinate system (G54 + n - 1) the station writes its piece markers into:
#: programs run in G54 and never select G59, so its offsets are free for bookkeeping.
MARKER_SYSTEM = 6


class Motion(str, Enum):
    """What a block makes the head do (G-code's modal motion resolved)."""

    RAPID = "rapid"  # G0
    LINE = "line"  # G1
    ARC_CW = "arc_cw"  # G2
    ARC_CCW = "arc_ccw"  # G3
    DWELL = "dwell"  # G4: waits; GRBL answers it only once every move before it ran
    OTHER = "other"  # no motion (modes, spindle, comments, G10 offsets)


#: G word -> the modal motion it selects; and each motion's G number (-1: none).
MOTION_OF_G = {0.0: Motion.RAPID, 1.0: Motion.LINE, 2.0: Motion.ARC_CW, 3.0: Motion.ARC_CCW}
G_OF_MOTION = {m: int(g) for g, m in MOTION_OF_G.items()}


class Sync(str, Enum):
    """The role of a block whose answer proves something was done."""

    NONE = ""
    STROKE = "stroke"  # G4 P0 after every stroke: its ok proves the stroke cut (gcode.resume)
    PIECE = "piece"  # G4 P0.01, the piece's last G4: its ok proves the piece cut
    MARKER = "marker"  # G10 L2 P6 X<job> Y<piece + 1> Z<phase>: progress kept in EEPROM


_WORD = re.compile(r"([A-Z])([-+]?(?:\d+\.?\d*|\.\d+))")
_COMMENT = re.compile(r"\(([^)]*)\)")
_ALONE_G = (28.1, 30.1)  # set home positions: EEPROM writes, like G10 L


def num(v: float) -> str:
    """A coordinate as the program writes it: at most 3 decimals, no trailing zeros."""
    s = f"{v:.3f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def strip_comment(line: str) -> str:
    """The G-code of a line without ``(...)`` and ``;`` comments and outer spaces."""
    return _COMMENT.sub("", line).split(";", 1)[0].strip()


@dataclass(frozen=True)
class Block:
    """One line of a program.

    ``words`` are the G-code words as sent (``("G1", "X10", "Y5", "F600")``); ``motion``
    and ``beam`` (the laser on after this block: M3/M4 with S > 0 in force) follow from the
    words by G-code's modal rules (:func:`settle`); ``piece`` is the 1-based piece the block
    belongs to (0: none); ``raw`` is the line as read from a file; ``fault`` says why the
    parser could not read it (the checker refuses it in its turn).
    """

    words: tuple[str, ...] = ()
    comment: str | None = None
    motion: Motion = Motion.OTHER
    beam: bool = False
    piece: int = 0
    sync: Sync = Sync.NONE
    raw: str | None = None
    fault: str | None = None

    # derived from the fields once, when the block is made (read many times: checker,
    # streamer loop, pictures), never set by hand
    text: str = field(init=False, repr=False, compare=False)  # the line as written to a file
    code: str = field(init=False, repr=False, compare=False)  # what goes on the wire
    g: tuple[float, ...] = field(init=False, repr=False, compare=False)
    m: tuple[float, ...] = field(init=False, repr=False, compare=False)
    values: dict[str, float] = field(init=False, repr=False, compare=False)  # not G, M

    def __post_init__(self) -> None:
        if self.raw is not None:
            text, code = self.raw, strip_comment(self.raw)
        else:
            code = " ".join(self.words)
            text = code if self.comment is None else (
                f"{code} ({self.comment})" if code else f"({self.comment})")
        for name, value in (
                ("text", text), ("code", code),
                ("g", tuple(float(w[1:]) for w in self.words if w[0] == "G")),
                ("m", tuple(float(w[1:]) for w in self.words if w[0] == "M")),
                ("values", {w[0]: float(w[1:]) for w in self.words if w[0] not in "GM"})):
            object.__setattr__(self, name, value)

    @property
    def target(self) -> tuple[float | None, float | None, float | None] | None:
        """The X, Y, Z words (None each where absent); None without any axis word."""
        v = self.values
        if not any(k in v for k in "XYZ"):
            return None
        return v.get("X"), v.get("Y"), v.get("Z")

    @property
    def feed(self) -> float | None:
        return self.values.get("F")

    @property
    def power(self) -> float | None:
        return self.values.get("S")

    @property
    def turns_beam_on(self) -> bool:
        """M3 or M4: sent only once every line before it is answered ``ok``.

        WHY: GRBL goes on after an ``error``. Were the travel to a cut's start rejected (a
        corrupted byte), the cut would begin wherever the head stands, beam on, before the
        host could react; waiting for the travel's ``ok`` costs one round trip per stroke.
        """
        return any(m in (3.0, 4.0) for m in self.m)

    @property
    def alone(self) -> bool:
        """A ``$`` system command or an EEPROM write (G10 L, G28.1, G30.1): GRBL must
        execute it alone, since the write stalls its serial interrupt and the lines behind
        it depend on it."""
        g = self.g
        return (self.code.startswith("$") or (10.0 in g and "L" in self.values)
                or any(a in g for a in _ALONE_G))

    @property
    def is_move(self) -> bool:
        """A feed move (G1, G2, G3) with a target: what cuts when the tool is down."""
        return self.motion in (Motion.LINE, Motion.ARC_CW, Motion.ARC_CCW)


def comment_block(text: str, piece: int = 0) -> Block:
    return Block(comment=text, piece=piece)


def marker_block(job: int, piece: int, phase: int, at_piece: int = 0) -> Block:
    """``G10 L2 P6 X<job> Y<piece + 1> Z<phase>``: see `gcode.recovery`."""
    return Block(("G10", "L2", f"P{MARKER_SYSTEM}", f"X{job}", f"Y{piece + 1}", f"Z{phase}"),
                 piece=at_piece, sync=Sync.MARKER)


# ---------------------------------------------------------------- the edge: text in

def parse_line(raw: str) -> Block:
    """One line of text as a block (modal motion and beam not yet settled); a line it
    cannot read comes back with ``fault`` set, for the checker to refuse in its turn."""
    line = raw.rstrip("\r\n")
    comments = _COMMENT.findall(line)
    comment = comments[0] if comments else None
    if line.count("(") != line.count(")"):
        return Block(comment=comment, raw=line, fault="unbalanced comment parentheses")
    code = strip_comment(line).upper().replace(" ", "")
    found = _WORD.findall(code)
    words = tuple(a + b for a, b in found)
    if "".join(words) != code:
        return Block(comment=comment, raw=line, fault="cannot parse this line")
    letters = [w[0] for w in words if w[0] not in "GM"]
    repeated = next((c for k, c in enumerate(letters) if c in letters[:k]), None)
    if repeated is not None:
        return Block(words, comment, raw=line, fault=f"word {repeated} repeated")
    return Block(words, comment, raw=line, sync=_sync_role(words))


def _sync_role(words: tuple[str, ...]) -> Sync:
    """The sync role a block read from a file shows by its words alone (a piece's own
    sync is the last dwell before its end marker: see `gcode.program.parse_pieces`)."""
    if words[:3] == ("G10", "L2", f"P{MARKER_SYSTEM}"):
        return Sync.MARKER
    if words in (("G4", "P0"),):
        return Sync.STROKE
    return Sync.NONE


def parse_lines(lines: Iterable[str]) -> list[Block]:
    """Lines of text as settled blocks (see `parse_line` and `settle`)."""
    return settle(parse_line(line) for line in lines)


def settle(blocks: Iterable[Block]) -> list[Block]:
    """Each block with the motion it makes and the beam after it, by G-code's modal rules:
    the last G0-G3 stays in force, G4 dwells, G10 takes its axis words as offsets; the
    beam is on while M3/M4 is in force with a non-zero S. The one reading of modal state
    that the builder and the file reader share."""
    out: list[Block] = []
    mode: Motion | None = None
    spindle_on = False
    s_word = 0.0
    for b in blocks:
        for g in b.g:
            mode = MOTION_OF_G.get(g, mode)
        for m in b.m:
            spindle_on = m in (3.0, 4.0) if m in (3.0, 4.0, 5.0) else spindle_on
        if b.power is not None:
            s_word = b.power
        if 4.0 in b.g:
            motion = Motion.DWELL
        elif 10.0 in b.g or b.target is None or mode is None:
            motion = Motion.OTHER
        else:
            motion = mode
        beam = spindle_on and s_word > 0
        out.append(b if (b.motion, b.beam) == (motion, beam) else
                   replace(b, motion=motion, beam=beam))
    return out
