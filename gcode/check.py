"""The program checker: a table of small handlers over typed blocks.

Every program is checked against the machine profile before it is written or sent: a move
outside the work area, a feed above the maximum, an S above the maximum, the laser on
during G0, a line GRBL would reject for length, a piece marker out of place, or anything
the checker does not understand makes it refuse. Each G word, M word and motion kind has
its handler (as Klipper's ``cmd_G1``); a block goes through the text handler, its G and M
words, its F and S words, then the handler of its motion.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from gcode.blocks import G_OF_MOTION, MARKER_SYSTEM, Block, Motion, parse_lines
from gcode.machine import POWER_MODES, Machine

__all__ = ["MAX_LINE", "Check", "ProgramError", "validate"]

MAX_LINE = 79  # GRBL's line buffer holds 79 characters plus the terminator
_FORBIDDEN = set("$%?!~") | {chr(c) for c in range(32)} | {chr(127)}
_EPS = 1e-6


class ProgramError(ValueError):
    """A program that must not be sent to the machine; the message names line and fault.
    ``line`` (0-based block) and ``detail`` (the fault alone) when a block is to blame."""

    def __init__(self, message: str, line: int | None = None, detail: str | None = None):
        super().__init__(message)
        self.line, self.detail = line, detail


@dataclass
class Check:
    """What :func:`validate` learned while checking: per-block time estimate and lengths."""

    seconds: np.ndarray  # (blocks,) float, estimated time per block
    cut_length_mm: float = 0.0
    travel_length_mm: float = 0.0
    bounds: tuple[float, float, float, float] | None = None  # x0, y0, x1, y1 of all motion
    path: np.ndarray | None = None  # (k,2) float, every XY motion sampled at most 1 mm apart
    path_line: np.ndarray | None = None  # (k,) int, the block of each path sample
    line_power: np.ndarray | None = None  # (blocks,) float, S of each beam-on move, else 0
    line_motion: np.ndarray | None = None  # (blocks,) int, 0-3 for G0-G3 moves, else -1
    line_on: np.ndarray | None = None  # (blocks,) bool, the beam or knife cuts along the move
    cut_feeds: tuple[float, ...] = ()  # every feed (mm/min) a beam-on move asks for
    cut_powers: tuple[float, ...] = ()  # every S a beam-on move asks for
    cut_pairs: tuple[tuple[float, float], ...] = ()  # every (S, F) a beam-on move asks for
    dynamic_power: bool = True  # the beam's S is scaled with the speed (M4), else constant

    @property
    def estimated_seconds(self) -> float:
        return float(self.seconds.sum())


def _move_time(length: float, feed_mm_min: float, accel: float) -> float:
    """Trapezoidal move from rest to rest: short moves never reach their feed."""
    if length <= 0:
        return 0.0
    v = feed_mm_min / 60.0
    if length >= v * v / accel:
        return length / v + v / accel
    return 2.0 * math.sqrt(length / accel)


def _arc_extent(s, e, c, cw: bool):
    """Sweep angle, radius and the axis-aligned extreme points of an arc."""
    r = math.hypot(s[0] - c[0], s[1] - c[1])
    a0 = math.atan2(s[1] - c[1], s[0] - c[0])
    a1 = math.atan2(e[1] - c[1], e[0] - c[0])
    sweep = -((a0 - a1) % (2 * math.pi)) if cw else (a1 - a0) % (2 * math.pi)
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
#: G words: refused with a reason, or the modal flag they set; the others pass (G0-G3 are
#: the motion, read by `gcode.blocks.settle`; G4 and G10 have their own handlers).
_G_REFUSED = {20.0: "G20 inches: the station works in millimetres",
              91.0: "G91 incremental moves are not accepted (absolute G90 only)"}
_G_SETS = {21.0: "units_mm", 90.0: "absolute"}
_G_PASS = {0.0, 1.0, 2.0, 3.0, 4.0, 10.0, 17.0, 94.0}
_M_PASS = {2.0, 8.0, 9.0, 30.0}
_LETTERS = set("XYZIJFSPN")
_MARKER_FORM = (f"G10 is accepted only as the station's piece marker G10 L2 P{MARKER_SYSTEM} "
                "X<job> Y<piece> Z<1|2>")


@dataclass
class _Tally:
    """What the checker adds up while it reads (per block arrays, lengths, samples)."""

    n: int
    seconds: np.ndarray = field(init=False)
    line_power: np.ndarray = field(init=False)
    line_motion: np.ndarray = field(init=False)
    line_on: np.ndarray = field(init=False)
    cut: float = 0.0
    travel: float = 0.0
    samples: list[np.ndarray] = field(default_factory=list)
    sample_lines: list[np.ndarray] = field(default_factory=list)
    box: list[float] = field(default_factory=lambda: [math.inf, math.inf, -math.inf, -math.inf])
    cut_pairs: set[tuple[float, float]] = field(default_factory=set)
    cut_feeds: set[float] = field(default_factory=set)

    def __post_init__(self) -> None:
        self.seconds = np.zeros(self.n)
        self.line_power = np.zeros(self.n)
        self.line_motion = np.full(self.n, -1, np.int8)
        self.line_on = np.zeros(self.n, bool)


class _Checker:
    """One pass over the blocks with the modal state GRBL would keep."""

    def __init__(self, blocks: Sequence[Block], machine: Machine, source: str, step: float):
        self.blocks, self.m, self.source, self.step = blocks, machine, source, step
        self.laser = machine.tool == "laser"
        self.laser_word = POWER_MODES[machine.cut.power_mode]
        self.pos: list[float | None] = [None, None, None]
        self.feed: float | None = None
        self.s_word = 0.0
        self.spindle = "M5"
        self.units_mm = self.absolute = False
        self.marker_open: tuple[int, int, int, int] | None = None  # job, piece, block, moves
        self.moves = 0  # feed moves read so far (a marker pair brackets exactly one)
        self.t = _Tally(len(blocks))
        self.motion_handlers: dict[Motion, Callable[[int, Block], None]] = {
            Motion.DWELL: self.dwell, Motion.OTHER: self.no_motion, Motion.RAPID: self.move,
            Motion.LINE: self.move, Motion.ARC_CW: self.move, Motion.ARC_CCW: self.move}

    def fail(self, i: int, msg: str):
        raise ProgramError(f"{self.source}:{i + 1}: {msg}: {self.blocks[i].text.strip()!r}",
                           i, msg)

    def run(self) -> Check:
        for i, b in enumerate(self.blocks):
            self.text(i, b)
            if not b.words:
                continue
            self.g_words(i, b)
            self.m_words(i, b)
            self.letters(i, b)
            self.motion_handlers[b.motion](i, b)
        if self.marker_open is not None:
            self.fail(self.marker_open[2], "piece marker phase 1 without its phase 2")
        return self.result()

    # ------------------------------------------------------------ words
    def text(self, i: int, b: Block) -> None:
        """What GRBL's line buffer and serial interrupt would refuse or act on."""
        line = b.text.rstrip("\r\n")
        if len(line) > MAX_LINE:
            self.fail(i, f"line longer than GRBL's {MAX_LINE} characters")
        bad = sorted({ch for ch in line if ch in _FORBIDDEN})
        if bad:
            self.fail(i, f"forbidden character(s) {bad!r} (system commands and real-time "
                         "bytes are never part of a program)")
        if b.fault:
            self.fail(i, b.fault)

    def g_words(self, i: int, b: Block) -> None:
        for g in b.g:
            if g in _G_REFUSED:
                self.fail(i, _G_REFUSED[g])
            if g in _G_SETS:
                setattr(self, _G_SETS[g], True)
            elif g not in _G_PASS:
                self.fail(i, f"G{g:g} is not accepted by the program checker")

    def m_words(self, i: int, b: Block) -> None:
        for mm in b.m:
            if mm in (3.0, 4.0, 5.0):
                self.spindle = f"M{int(mm)}"
                if self.laser and mm != 5 and self.spindle != self.laser_word:
                    self.fail(i, _POWER_MODE_FAULT[self.m.cut.power_mode])
            elif mm not in _M_PASS:
                self.fail(i, f"M{mm:g} is not accepted by the program checker")

    def letters(self, i: int, b: Block) -> None:
        """Only known letters; F and S within the machine's limits; no Z on a laser."""
        unknown = set(b.values) - _LETTERS - ({"L"} if 10.0 in b.g else set())
        if unknown:
            self.fail(i, f"word(s) {sorted(unknown)} not accepted by the program checker")
        f, s, m = b.feed, b.power, self.m
        if f is not None:
            if f <= 0:
                self.fail(i, "feed F must be positive")
            if f > m.max_feed + _EPS:
                self.fail(i, f"feed F{f:g} exceeds the machine's max_feed {m.max_feed:g}")
            self.feed = f
        if s is not None:
            if s < 0 or s > m.max_s + _EPS:
                self.fail(i, f"S{s:g} outside 0..{m.max_s:g} (the machine's max_s)")
            self.s_word = s
        if "Z" in b.values and self.laser and 10.0 not in b.g:
            self.fail(i, "Z move in a laser program")

    # ------------------------------------------------------------ blocks that do not move
    def dwell(self, i: int, b: Block) -> None:
        p = b.values.get("P")
        if p is None or p < 0:
            self.fail(i, "G4 dwell needs a non-negative P (seconds)")
        self.t.seconds[i] = p
        if any(k in b.values for k in "XYZIJ"):
            self.fail(i, "G4 with axis words")

    def no_motion(self, i: int, b: Block) -> None:
        if 10.0 in b.g:
            self.marker(i, b)
        elif b.target is not None:
            self.modes_set(i)
            self.fail(i, "axis words without a motion mode")
        elif any(k in b.values for k in "IJ"):
            self.fail(i, "arc offsets without a target")

    def marker(self, i: int, b: Block) -> None:
        """The piece marker pair: phase 1 just before a piece's final feed move, phase 2
        just after it, the same job and piece (see `gcode.recovery`)."""
        v = b.values
        fields = [v.get(k) for k in "LPXYZ"]
        if any(x is None or x != int(x) for x in fields) or fields[:2] != [2, MARKER_SYSTEM] \
                or fields[2] < 1 or fields[3] < 1 or fields[4] not in (1, 2):
            self.fail(i, _MARKER_FORM)
        job, piece, phase = int(v["X"]), int(v["Y"]), int(v["Z"])
        if phase == 1:
            if self.marker_open is not None:
                self.fail(i, "piece marker phase 1 before the last one's phase 2")
            self.marker_open = (job, piece, i, self.moves)
            return
        opened = self.marker_open
        if opened is None or opened[:2] != (job, piece) or self.moves != opened[3] + 1:
            self.fail(i, "piece marker phase 2 without its phase 1 one feed move before")
        self.marker_open = None

    # ------------------------------------------------------------ motion
    def modes_set(self, i: int) -> None:
        if not (self.units_mm and self.absolute):
            self.fail(i, "motion before G21 and G90 are set")

    def move(self, i: int, b: Block) -> None:
        """Any G0-G3 with axis words: resolve the target, keep it on the table, then the
        handler of its kind; the position follows."""
        self.modes_set(i)
        target = self.resolve(i, b)
        tool_on = self.tool_on(target)
        self.t.line_motion[i] = G_OF_MOTION[b.motion]
        self.t.line_on[i] = b.motion != Motion.RAPID and tool_on
        if b.motion == Motion.RAPID:
            self.rapid(i, b, target)
        else:
            self.feed_move(i, b, target, tool_on)
        self.pos = target

    def resolve(self, i: int, b: Block) -> list[float | None]:
        """The block's target with the axes it leaves out where the head is."""
        pos, kn, v = self.pos, self.m.knife, b.values
        target = [v.get("X", pos[0]), v.get("Y", pos[1]), v.get("Z", pos[2])]
        if (target[0] is None or target[1] is None) and (b.motion != Motion.RAPID
                                                         or "Z" not in v):
            self.fail(i, "motion before the head's X and Y are known (start with G0 X Y)")
        if target[2] is not None and not self.laser and not (
                min(kn.z_down, kn.z_up) - _EPS <= target[2] <= max(kn.z_down, kn.z_up) + _EPS):
            self.fail(i, f"Z{target[2]:g} outside the knife range {kn.z_down:g}..{kn.z_up:g}")
        if target[0] is not None and target[1] is not None:
            self.inside(i, target[0], target[1])
        return target

    def tool_on(self, target: list[float | None]) -> bool:
        """The beam on (M3/M4 with S > 0), or the knife down at both ends of the move."""
        if self.laser:
            return self.spindle in ("M3", "M4") and self.s_word > 0
        z0, z1 = self.pos[2], target[2]
        return z0 is not None and z1 is not None and max(z0, z1) <= self.m.knife.z_down + _EPS

    def inside(self, i: int, x: float, y: float) -> None:
        x0, y0, x1, y1 = self.m.work_area
        if not (x0 - _EPS <= x <= x1 + _EPS and y0 - _EPS <= y <= y1 + _EPS):
            self.fail(i, f"move to X{x:.3f} Y{y:.3f} outside the work area "
                         f"[{x0:g}..{x1:g}] x [{y0:g}..{y1:g}] of {self.m.name}")
        box = self.t.box
        box[0], box[1] = min(box[0], x), min(box[1], y)
        box[2], box[3] = max(box[2], x), max(box[3], y)

    def rapid(self, i: int, b: Block, target: list[float | None]) -> None:
        m, pos = self.m, self.pos
        if self.laser and self.tool_on(target):
            self.fail(i, "laser on (M4 with S>0) during a rapid G0 move")
        if not self.laser and target[2] is not None and target[2] < m.knife.z_up - _EPS \
                and any(k in b.values for k in "XY"):
            self.fail(i, "knife not raised during a rapid G0 move")
        if pos[0] is not None and target[0] is not None:
            d = math.hypot(target[0] - pos[0], target[1] - pos[1])
            self.t.travel += d
            self.sample_line(i, pos, target)
            self.t.seconds[i] = _move_time(max(d, abs((target[2] or 0) - (pos[2] or 0))),
                                           m.rapid_feed, m.acceleration)

    def feed_move(self, i: int, b: Block, target: list[float | None], tool_on: bool) -> None:
        pos, feed = self.pos, self.feed
        if feed is None:
            self.fail(i, "feed move before any F word")
        if pos[0] is None or pos[1] is None:
            self.fail(i, "feed move before the head's X and Y are known (start with G0 X Y)")
        if b.motion == Motion.LINE:
            d = math.hypot(target[0] - pos[0], target[1] - pos[1])
            length = max(d, abs((target[2] or 0) - (pos[2] or 0)))
            self.sample_line(i, pos, target)
        else:
            d = length = self.arc(i, b, target)
        self.moves += 1
        if tool_on:
            self.cutting(i, d)
        self.t.seconds[i] = _move_time(length, feed, self.m.acceleration)

    def arc(self, i: int, b: Block, target: list[float | None]) -> float:
        """Check an arc (I/J form, equal radii, every extreme on the table); its length."""
        v, pos = b.values, self.pos
        if "I" not in v and "J" not in v:
            self.fail(i, "G2/G3 without I/J centre offsets (R form is not accepted)")
        c = (pos[0] + v.get("I", 0.0), pos[1] + v.get("J", 0.0))
        sweep, r, extremes = _arc_extent(pos[:2], target[:2], c, b.motion == Motion.ARC_CW)
        r_end = math.hypot(target[0] - c[0], target[1] - c[1])
        if abs(r - r_end) > 0.005 and abs(r - r_end) > 0.001 * r:
            self.fail(i, f"arc start and end radii differ ({r:.4f} vs {r_end:.4f} mm)")
        for ex, ey in extremes:
            self.inside(i, ex, ey)
        self.sample_arc(i, pos, c, r, sweep)
        return abs(sweep) * r

    def cutting(self, i: int, d: float) -> None:
        """A feed move with the tool down: not slower than the beam allows, tallied."""
        m, feed, t = self.m, self.feed, self.t
        t.cut += d
        if self.laser and feed < m.min_cut_feed - _EPS:
            self.fail(i, f"beam on at F{feed:g}, below the machine's min_cut_feed "
                         f"{m.min_cut_feed:g} (a slow beam burns through)")
        t.cut_feeds.add(feed)
        if self.laser:
            t.cut_pairs.add((self.s_word, feed))
            t.line_power[i] = self.s_word

    # ------------------------------------------------------------ sampling
    def sample_line(self, i: int, a, b) -> None:
        k = max(1, int(math.ceil(math.hypot(b[0] - a[0], b[1] - a[1]) / self.step)))
        s = np.linspace(0.0, 1.0, k + 1)[:, None]
        self.t.samples.append(np.asarray(a[:2], float) * (1 - s)
                              + np.asarray(b[:2], float) * s)
        self.t.sample_lines.append(np.full(k + 1, i))

    def sample_arc(self, i: int, a, c, r: float, sweep: float) -> None:
        k = max(2, int(math.ceil(abs(sweep) * r / self.step)))
        ang = math.atan2(a[1] - c[1], a[0] - c[0]) + sweep * np.linspace(0.0, 1.0, k + 1)
        self.t.samples.append(np.c_[c[0] + r * np.cos(ang), c[1] + r * np.sin(ang)])
        self.t.sample_lines.append(np.full(k + 1, i))

    def result(self) -> Check:
        t = self.t
        bounds = None if math.isinf(t.box[0]) else tuple(t.box)
        return Check(seconds=t.seconds, cut_length_mm=t.cut, travel_length_mm=t.travel,
                     bounds=bounds,
                     path=np.vstack(t.samples) if t.samples else np.zeros((0, 2)),
                     path_line=(np.concatenate(t.sample_lines) if t.sample_lines
                                else np.zeros(0, int)),
                     line_power=t.line_power, line_motion=t.line_motion, line_on=t.line_on,
                     cut_feeds=tuple(sorted(t.cut_feeds)),
                     cut_powers=tuple(sorted({s for s, _ in t.cut_pairs})),
                     cut_pairs=tuple(sorted(t.cut_pairs)),
                     dynamic_power=self.laser_word == "M4")


def validate(blocks: Sequence[Block] | Sequence[str], machine: Machine,
             source: str = "<program>", path_step: float = 1.0) -> Check:
    """Check a program against the machine profile; raise ProgramError at the first fault.

    Only what this checker understands passes: G0 G1 G2 G3 G4 G17 G21 G90 G94, the piece
    marker G10 L2 P6, M2 M3 M4 M5 M8 M9 M30 and the words X Y Z I J F S P N. Everything
    else is refused, because a line the checker cannot follow could move the head
    somewhere it has not checked. Lines of text are read by `gcode.blocks.parse_lines`.
    """
    if blocks and isinstance(blocks[0], str):
        blocks = parse_lines(blocks)
    return _Checker(blocks, machine, source, path_step).run()
