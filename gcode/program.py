"""G-code programs for a GRBL laser or knife, with per-piece sync points, and their checker.

Every program is checked against the machine profile by re-reading its own text
(:func:`validate`), independently of how it was generated, before it is written or sent:
a move outside the work area, a feed above the maximum, an S above the maximum, the laser
on during G0, a line GRBL would reject for length, or anything the checker does not
understand makes it refuse.

Each piece is bracketed by comments ``(piece N begin ID NAME)`` / ``(piece N end)`` with a
``G4 P0.01`` sync line just before the end marker, so the streamer can recover the pieces
from the .nc file alone. GRBL's ``ok`` to a G4 comes only after every motion before it has
finished, which is what proves the piece was cut.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

import untrusted
from gcode.arcs import CW, LINE, FittedPath
from gcode.machine import POWER_MODES, Machine
from gcode.toolpath import PieceToolpath

__all__ = [
    "Check",
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

MAX_LINE = 79  # GRBL's line buffer holds 79 characters plus the terminator
SYNC = "G4 P0.01"
#: after every stroke: answered once the stroke has run, so the station knows exactly which
#: strokes of a piece are cut (gcode.resume); the piece's own SYNC stays its last G4
STROKE_SYNC = "G4 P0"
_ALLOWED = re.compile(r"[^A-Za-z0-9 _.,:#+/=-]")
_PIECE = re.compile(r"^\(piece (\d+) (begin|end)(?: (.*))?\)$")


class ProgramError(ValueError):
    """A program that must not be sent to the machine; the message names line and fault."""


def sanitize_comment(text: str, limit: int = 60) -> str:
    """Text safe inside a G-code comment: no newline, parentheses, $, %, ; nor GRBL's
    real-time characters (? ! ~ and control bytes act even inside comments)."""
    return _ALLOWED.sub("_", text)[:limit]


def strip_comment(line: str) -> str:
    """The G-code of a line without ``(...)`` and ``;`` comments and outer spaces."""
    out = re.sub(r"\([^)]*\)", "", line)
    return out.split(";", 1)[0].strip()


def _num(v: float) -> str:
    s = f"{v:.3f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


@dataclass
class PieceRange:
    """Where one piece lives in the program (0-based line indexes into ``Program.lines``)."""

    number: int  # 1-based position in the cut order
    id: str
    name: str
    first_line: int  # the "(piece N begin ...)" comment
    sync_line: int  # the G4 whose ok proves the piece is cut
    last_line: int  # the "(piece N end)" comment


@dataclass
class Check:
    """What :func:`validate` learned while checking: per-line time estimate and lengths."""

    seconds: np.ndarray  # (lines,) float, estimated time per line
    cut_length_mm: float = 0.0
    travel_length_mm: float = 0.0
    bounds: tuple[float, float, float, float] | None = None  # x0, y0, x1, y1 of all motion
    path: np.ndarray | None = None  # (k,2) float, every XY motion sampled at most 1 mm apart
    path_line: np.ndarray | None = None  # (k,) int, the program line of each path sample
    line_power: np.ndarray | None = None  # (lines,) float, S of each beam-on move, else 0
    line_motion: np.ndarray | None = None  # (lines,) int, 0-3 for G0-G3 moves, else -1
    line_on: np.ndarray | None = None  # (lines,) bool, the beam or knife cuts along the move
    cut_feeds: tuple[float, ...] = ()  # every feed (mm/min) a beam-on move asks for
    cut_powers: tuple[float, ...] = ()  # every S a beam-on move asks for
    cut_pairs: tuple[tuple[float, float], ...] = ()  # every (S, F) a beam-on move asks for
    dynamic_power: bool = True  # the beam's S is scaled with the speed (M4), else constant

    @property
    def estimated_seconds(self) -> float:
        return float(self.seconds.sum())

    def moved(self, new_index: np.ndarray, n_lines: int) -> Check:
        """This check for the program with lines inserted: old line k is now line
        ``new_index[k]`` of ``n_lines``; inserted lines neither move nor take time."""
        def spread(per_line: np.ndarray | None, fill) -> np.ndarray | None:
            if per_line is None:
                return None
            out = np.full(n_lines, fill, dtype=per_line.dtype)
            out[new_index] = per_line
            return out

        return replace(self, seconds=spread(self.seconds, 0.0),
                       path_line=None if self.path_line is None else new_index[self.path_line],
                       line_power=spread(self.line_power, 0.0),
                       line_motion=spread(self.line_motion, -1),
                       line_on=spread(self.line_on, False))


@dataclass
class Program:
    """G-code lines plus, per piece, its line range and sync line."""

    lines: list[str]
    pieces: list[PieceRange] = field(default_factory=list)
    check: Check | None = None
    warnings: list[str] = field(default_factory=list)

    def text(self) -> str:
        return "\n".join(self.lines) + "\n"

    def write(self, path: str | Path) -> None:
        Path(path).write_text(self.text(), encoding="ascii")

    def summary(self) -> dict:
        c = self.check
        return {
            "lines": len(self.lines),
            "pieces": len(self.pieces),
            "cut_length_mm": round(c.cut_length_mm, 3) if c else None,
            "travel_length_mm": round(c.travel_length_mm, 3) if c else None,
            "estimated_seconds": round(c.estimated_seconds, 2) if c else None,
        }


# ---------------------------------------------------------------- generation

class _Writer:
    def __init__(self, machine: Machine):
        self.m = machine
        self.lines: list[str] = []
        self.pos: tuple[str, str] | None = None  # the head's X, Y as last written

    def rapid_to(self, p: np.ndarray) -> None:
        """G0 to ``p`` unless the head is already there."""
        xy = (_num(p[0]), _num(p[1]))
        if xy != self.pos:
            self.emit(f"G0 X{xy[0]} Y{xy[1]}")
            self.pos = xy

    def emit(self, line: str) -> int:
        if len(line) > MAX_LINE:
            raise ProgramError(f"generated line longer than {MAX_LINE} characters: {line!r}")
        self.lines.append(line)
        return len(self.lines) - 1

    def moves(self, path: FittedPath, feed: float) -> None:
        prev = path.start
        first = True
        for kind, end, c in zip(path.kind, path.end, path.center, strict=True):
            f = f" F{_num(feed)}" if first else ""
            if kind == LINE:
                self.emit(f"G1 X{_num(end[0])} Y{_num(end[1])}{f}")
            else:
                g = "G2" if kind == CW else "G3"
                ij = c - prev
                self.emit(f"{g} X{_num(end[0])} Y{_num(end[1])} I{_num(ij[0])} J{_num(ij[1])}{f}")
            prev = end
            first = False
        self.pos = (_num(prev[0]), _num(prev[1]))


def _laser_stroke(w: _Writer, path: FittedPath, power: float, passes: int, closed: bool) -> None:
    m = w.m
    for k in range(passes):
        if k == 0 or not closed:
            w.rapid_to(path.start)
        w.emit(f"{POWER_MODES[m.cut.power_mode]} S{_num(power)}")
        w.moves(path, m.cut.feed)
        if not closed or k == passes - 1:
            w.emit("M5")


def _knife_stroke(w: _Writer, path: FittedPath) -> None:
    kn = w.m.knife
    w.rapid_to(path.start)
    w.emit(f"G1 Z{_num(kn.z_down)} F{_num(kn.plunge_feed)}")
    if len(path):
        w.moves(path, w.m.cut.feed)
    w.emit(f"G0 Z{_num(kn.z_up)}")


def build_program(toolpaths: list[PieceToolpath], machine: Machine, *, title: str = "station job",
                  source: str = "<program>") -> Program:
    """The G-code program for the toolpaths, validated against ``machine`` (ProgramError).

    A refusal names ``source`` (the layout file), the program line and the piece it cuts.
    """
    w = _Writer(machine)
    c = machine.cut
    laser = machine.tool == "laser"
    w.emit(f"({sanitize_comment(title)})")
    w.emit(f"(machine {sanitize_comment(machine.name)} tool {machine.tool} "
           f"pieces {len(toolpaths)})")
    w.emit("G21 G90 G94 G17")
    w.emit("M5")
    w.emit("M9")
    if not laser:
        w.emit(f"G0 Z{_num(machine.knife.z_up)}")
    if laser and c.air_assist:
        w.emit("M8")
    pieces: list[PieceRange] = []
    warnings: list[str] = []
    for number, tp in enumerate(toolpaths, start=1):
        warnings.extend(tp.warnings)
        first = w.emit(f"(piece {number} begin {sanitize_comment(tp.id, 30)} "
                       f"{sanitize_comment(tp.name, 20)})")
        for contour in tp.contours:
            for stroke in contour.strokes:
                if laser:
                    is_mark = contour.kind == "mark"
                    closed = contour.closed and len(contour.strokes) == 1 and np.allclose(
                        stroke.start, stroke.end[-1])
                    _laser_stroke(w, stroke, c.mark_power if is_mark else c.power,
                                  1 if is_mark else c.passes, closed)
                else:
                    _knife_stroke(w, stroke)
                w.emit(STROKE_SYNC)
        sync = w.emit(SYNC)
        last = w.emit(f"(piece {number} end)")
        pieces.append(PieceRange(number, tp.id, tp.name, first, sync, last))
    w.emit("M5")
    w.emit("M9")
    if not laser:
        w.emit(f"G0 Z{_num(machine.knife.z_up)}")
    w.pos = None  # always park explicitly
    w.rapid_to(np.asarray(machine.park))
    w.emit("M2")
    prog = Program(w.lines, pieces, warnings=warnings)
    try:
        prog.check = validate(prog.lines, machine, f"{source}: program line")
    except ProgramError as exc:
        msg = str(exc).replace("program line:", "program line ", 1)
        line = int(re.match(r".*?program line (\d+):", msg).group(1)) - 1
        piece = next((p for p in pieces if p.first_line <= line <= p.last_line), None)
        if piece is not None:
            msg += f" (piece {piece.id})"
        if "outside the work area" in msg:
            msg += "; the layout's origin places the fabric on the table, leave room for " \
                   "the kerf and lead-ins"
        raise ProgramError(msg) from None
    return prog


# ---------------------------------------------------------------- reading back

def parse_pieces(lines: list[str], source: str = "<program>") -> list[PieceRange]:
    """Recover the per-piece ranges and sync lines from a program's comments."""
    out: list[PieceRange] = []
    open_: tuple[int, str, str, int] | None = None
    for i, line in enumerate(lines):
        m = _PIECE.match(line.strip())
        if not m:
            continue
        number, what, rest = int(m.group(1)), m.group(2), m.group(3) or ""
        if what == "begin":
            if open_ is not None:
                raise ProgramError(f"{source}:{i + 1}: piece {number} begins inside piece "
                                   f"{open_[0]}")
            pid, _, name = rest.partition(" ")
            open_ = (number, pid, name or pid, i)
        else:
            if open_ is None or open_[0] != number:
                raise ProgramError(f"{source}:{i + 1}: end of piece {number} without its begin")
            sync = next((k for k in range(i - 1, open_[3], -1)
                         if strip_comment(lines[k]).upper().startswith("G4")), None)
            if sync is None:
                raise ProgramError(f"{source}:{i + 1}: piece {number} has no G4 sync line "
                                   "before its end marker")
            out.append(PieceRange(number, open_[1], open_[2], open_[3], sync, i))
            open_ = None
    if open_ is not None:
        raise ProgramError(f"{source}: piece {open_[0]} has no end marker")
    return out


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
    prog = Program(lines, parse_pieces(lines, str(p)))
    prog.check = validate(lines, machine, str(p))
    return prog


# ---------------------------------------------------------------- checking

_WORD = re.compile(r"([A-Z])([-+]?(?:\d+\.?\d*|\.\d+))")
_FORBIDDEN = set("$%?!~") | {chr(c) for c in range(32)} | {chr(127)}


def _move_time(length: float, feed_mm_min: float, accel: float) -> float:
    """Trapezoidal move from rest to rest: short moves never reach their feed."""
    if length <= 0:
        return 0.0
    v = feed_mm_min / 60.0
    if length >= v * v / accel:
        return length / v + v / accel
    return 2.0 * math.sqrt(length / accel)


def _arc_extent(s, e, c, cw: bool):
    """Sweep angle and the axis-aligned extreme points of an arc."""
    r = math.hypot(s[0] - c[0], s[1] - c[1])
    a0 = math.atan2(s[1] - c[1], s[0] - c[0])
    a1 = math.atan2(e[1] - c[1], e[0] - c[0])
    sweep = a1 - a0
    if cw:
        sweep = -((-sweep) % (2 * math.pi))
    else:
        sweep = sweep % (2 * math.pi)
    if abs(e[0] - s[0]) < 1e-9 and abs(e[1] - s[1]) < 1e-9:
        sweep = -2 * math.pi if cw else 2 * math.pi
    pts = [s, e]
    for k in range(-8, 9):
        ang = k * math.pi / 2
        rel = (ang - a0) if not cw else (a0 - ang)
        if 0 < rel % (2 * math.pi) < abs(sweep) or (abs(sweep) >= 2 * math.pi - 1e-12):
            pts.append((c[0] + r * math.cos(ang), c[1] + r * math.sin(ang)))
    return sweep, r, pts


#: Why a laser program's spindle word disagrees with the profile's ``[cut] power_mode``.
_POWER_MODE_FAULT = {
    "dynamic": "M3 constant laser power burns while the head slows and stops; the profile's "
               "power_mode is dynamic (M4)",
    "constant": "M4 dynamic laser power, but the profile's power_mode is constant (M3): the "
                "watchdog would judge the power the machine reports by the wrong rule",
}


def validate(lines: list[str], machine: Machine, source: str = "<program>",
             path_step: float = 1.0) -> Check:
    """Check a program against the machine profile; raise ProgramError at the first fault.

    Only what this checker understands passes: G0 G1 G2 G3 G4 G17 G21 G90 G94, M2 M3 M4 M5
    M8 M9 M30 and the words X Y Z I J F S P N. Everything else is refused, because a line the
    checker cannot follow could move the head somewhere it has not checked.
    """
    x0, y0, x1, y1 = machine.work_area
    eps = 1e-6
    laser = machine.tool == "laser"
    laser_word = POWER_MODES[machine.cut.power_mode]
    pos: list[float | None] = [None, None, None]
    motion = None
    feed: float | None = None
    s_word = 0.0
    spindle = "M5"
    units_mm = False
    absolute = False
    seconds = np.zeros(len(lines))
    cut = travel = 0.0
    samples: list[np.ndarray] = []
    sample_lines: list[np.ndarray] = []
    current = [0]  # the line being read (for the samples' line numbers)
    cut_feeds: set[float] = set()
    cut_powers: set[float] = set()
    cut_pairs: set[tuple[float, float]] = set()
    line_power = np.zeros(len(lines))
    line_motion = np.full(len(lines), -1, np.int8)
    line_on = np.zeros(len(lines), bool)

    def sample_line(a, b) -> None:
        k = max(1, int(math.ceil(math.hypot(b[0] - a[0], b[1] - a[1]) / path_step)))
        t = np.linspace(0.0, 1.0, k + 1)[:, None]
        samples.append(np.asarray(a[:2], float) * (1 - t) + np.asarray(b[:2], float) * t)
        sample_lines.append(np.full(k + 1, current[0]))

    def sample_arc(a, c, r, sweep) -> None:
        k = max(2, int(math.ceil(abs(sweep) * r / path_step)))
        ang = math.atan2(a[1] - c[1], a[0] - c[0]) + sweep * np.linspace(0.0, 1.0, k + 1)
        samples.append(np.c_[c[0] + r * np.cos(ang), c[1] + r * np.sin(ang)])
        sample_lines.append(np.full(k + 1, current[0]))
    bx = [math.inf, math.inf, -math.inf, -math.inf]

    def fail(i: int, msg: str):
        raise ProgramError(f"{source}:{i + 1}: {msg}: {lines[i].strip()!r}")

    def inside(i: int, x: float, y: float) -> None:
        if not (x0 - eps <= x <= x1 + eps and y0 - eps <= y <= y1 + eps):
            fail(i, f"move to X{x:.3f} Y{y:.3f} outside the work area "
                    f"[{x0:g}..{x1:g}] x [{y0:g}..{y1:g}] of {machine.name}")
        bx[0], bx[1] = min(bx[0], x), min(bx[1], y)
        bx[2], bx[3] = max(bx[2], x), max(bx[3], y)

    for i, raw in enumerate(lines):
        current[0] = i
        if len(raw.rstrip("\r\n")) > MAX_LINE:
            fail(i, f"line longer than GRBL's {MAX_LINE} characters")
        if any(ch in _FORBIDDEN for ch in raw.rstrip("\r\n")):
            bad = sorted({ch for ch in raw if ch in _FORBIDDEN})
            fail(i, f"forbidden character(s) {bad!r} (system commands and real-time bytes "
                    "are never part of a program)")
        if raw.count("(") != raw.count(")"):
            fail(i, "unbalanced comment parentheses")
        code = strip_comment(raw).upper().replace(" ", "")
        if not code:
            continue
        words = _WORD.findall(code)
        if "".join(a + b for a, b in words) != code:
            fail(i, "cannot parse this line")
        gs: list[float] = []
        ms: list[float] = []
        vals: dict[str, float] = {}
        for letter, num in words:
            v = float(num)
            if letter == "G":
                gs.append(v)
            elif letter == "M":
                ms.append(v)
            elif letter in vals:
                fail(i, f"word {letter} repeated")
            else:
                vals[letter] = v
        for g in gs:
            if g in (0, 1, 2, 3):
                motion = int(g)
            elif g == 21:
                units_mm = True
            elif g == 90:
                absolute = True
            elif g in (4, 17, 94):
                pass
            elif g == 20:
                fail(i, "G20 inches: the station works in millimetres")
            elif g == 91:
                fail(i, "G91 incremental moves are not accepted (absolute G90 only)")
            else:
                fail(i, f"G{g:g} is not accepted by the program checker")
        for mm in ms:
            if mm in (3, 4, 5):
                spindle = f"M{int(mm)}"
                if laser and mm != 5 and spindle != laser_word:
                    fail(i, _POWER_MODE_FAULT[machine.cut.power_mode])
            elif mm in (8, 9, 2, 30):
                pass
            else:
                fail(i, f"M{mm:g} is not accepted by the program checker")
        unknown = set(vals) - set("XYZIJFSPN")
        if unknown:
            fail(i, f"word(s) {sorted(unknown)} not accepted by the program checker")
        if "F" in vals:
            if vals["F"] <= 0:
                fail(i, "feed F must be positive")
            if vals["F"] > machine.max_feed + eps:
                fail(i, f"feed F{vals['F']:g} exceeds the machine's max_feed {machine.max_feed:g}")
            feed = vals["F"]
        if "S" in vals:
            if vals["S"] < 0 or vals["S"] > machine.max_s + eps:
                fail(i, f"S{vals['S']:g} outside 0..{machine.max_s:g} (the machine's max_s)")
            s_word = vals["S"]
        beam_on = spindle in ("M3", "M4") and s_word > 0
        if "Z" in vals and laser:
            fail(i, "Z move in a laser program")
        if 4 in gs:
            if "P" not in vals or vals["P"] < 0:
                fail(i, "G4 dwell needs a non-negative P (seconds)")
            seconds[i] = vals["P"]
            if any(k in vals for k in "XYZIJ"):
                fail(i, "G4 with axis words")
            continue
        has_axes = any(k in vals for k in "XYZ")
        if not has_axes:
            if any(k in vals for k in "IJ"):
                fail(i, "arc offsets without a target")
            continue
        if not (units_mm and absolute):
            fail(i, "motion before G21 and G90 are set")
        if motion is None:
            fail(i, "axis words without a motion mode")
        target = [vals.get("X", pos[0]), vals.get("Y", pos[1]), vals.get("Z", pos[2])]
        if target[0] is None or target[1] is None:
            if motion != 0 or "Z" not in vals:
                fail(i, "motion before the head's X and Y are known (start with G0 X Y)")
        if target[2] is not None and not laser:
            kn = machine.knife
            if not (min(kn.z_down, kn.z_up) - eps <= target[2] <= max(kn.z_down, kn.z_up) + eps):
                fail(i, f"Z{target[2]:g} outside the knife range {kn.z_down:g}..{kn.z_up:g}")
        if target[0] is not None and target[1] is not None:
            inside(i, target[0], target[1])
        tool_on = beam_on if laser else (pos[2] is not None and target[2] is not None
                                         and max(pos[2], target[2]) <= machine.knife.z_down + eps)
        line_motion[i] = motion
        line_on[i] = motion != 0 and tool_on
        if motion == 0:
            if laser and beam_on:
                fail(i, "laser on (M4 with S>0) during a rapid G0 move")
            if not laser and target[2] is not None and target[2] < machine.knife.z_up - eps \
                    and any(k in vals for k in "XY"):
                fail(i, "knife not raised during a rapid G0 move")
            if pos[0] is not None and target[0] is not None:
                d = math.hypot(target[0] - pos[0], target[1] - pos[1])
                travel += d
                sample_line(pos, target)
                seconds[i] = _move_time(max(d, abs((target[2] or 0) - (pos[2] or 0))),
                                        machine.rapid_feed, machine.acceleration)
        else:
            if feed is None:
                fail(i, "feed move before any F word")
            if pos[0] is None or pos[1] is None:
                fail(i, "feed move before the head's X and Y are known (start with G0 X Y)")
            if motion == 1:
                d = math.hypot(target[0] - pos[0], target[1] - pos[1])
                dz = abs((target[2] or 0) - (pos[2] or 0))
                length = max(d, dz)
                sample_line(pos, target)
            else:
                if "I" not in vals and "J" not in vals:
                    fail(i, "G2/G3 without I/J centre offsets (R form is not accepted)")
                c = (pos[0] + vals.get("I", 0.0), pos[1] + vals.get("J", 0.0))
                sweep, r, extremes = _arc_extent(pos[:2], target[:2], c, motion == 2)
                r_end = math.hypot(target[0] - c[0], target[1] - c[1])
                if abs(r - r_end) > 0.005 and abs(r - r_end) > 0.001 * r:
                    fail(i, f"arc start and end radii differ ({r:.4f} vs {r_end:.4f} mm)")
                for ex, ey in extremes:
                    inside(i, ex, ey)
                length = abs(sweep) * r
                d = length
                sample_arc(pos, c, r, sweep)
            if tool_on:
                cut += d
                if laser and feed < machine.min_cut_feed - eps:
                    fail(i, f"beam on at F{feed:g}, below the machine's min_cut_feed "
                            f"{machine.min_cut_feed:g} (a slow beam burns through)")
                cut_feeds.add(feed)
                if laser:
                    cut_powers.add(s_word)
                    cut_pairs.add((s_word, feed))
                    line_power[i] = s_word
            seconds[i] = _move_time(length, feed, machine.acceleration)
        pos = target
    bounds = None if math.isinf(bx[0]) else (bx[0], bx[1], bx[2], bx[3])
    path = np.vstack(samples) if samples else np.zeros((0, 2))
    path_line = np.concatenate(sample_lines) if sample_lines else np.zeros(0, int)
    return Check(seconds=seconds, cut_length_mm=cut, travel_length_mm=travel, bounds=bounds,
                 path=path, path_line=path_line, line_power=line_power,
                 line_motion=line_motion, line_on=line_on,
                 cut_feeds=tuple(sorted(cut_feeds)), cut_powers=tuple(sorted(cut_powers)),
                 cut_pairs=tuple(sorted(cut_pairs)), dynamic_power=laser_word == "M4")


def program_moves(program: Program) -> list[tuple[int, bool, int, np.ndarray]]:
    """Every move of a checked program as (line, cutting, piece number or 0, (k, 2) points),
    read from what :func:`validate` interpreted (arcs sampled 1 mm apart): the one reading
    of the G-code that the pictures and the crash recovery share with the checker."""
    c = program.check
    if c is None or c.path is None or c.path_line is None or c.line_on is None:
        raise ProgramError("program_moves needs a validated program (Program.check)")
    piece_at = np.zeros(len(program.lines), int)
    for r in program.pieces:
        piece_at[r.first_line:r.last_line + 1] = r.number
    lines, starts = np.unique(c.path_line, return_index=True)
    ends = np.r_[starts[1:], len(c.path_line)]
    return [(int(k), bool(c.line_on[k]), int(piece_at[k]), c.path[a:b])
            for k, a, b in zip(lines, starts, ends, strict=True) if k >= 0]
