"""GRBL 1.1 line pre-parser and G-code block parser.

A block is validated completely before anything changes, as GRBL's gc_execute_line does:
"Grbl did not recognize the command and did not execute anything inside that message"
(interface.md, `error:X`). The parser keeps GRBL's modal state (`$G`) and the parser position,
and turns a valid block into a list of actions that the machine executes in order
(planner moves, buffer syncs, dwells, spindle/coolant changes, program pause/end).
"""

from __future__ import annotations

import copy
import math
import re
from dataclasses import dataclass, field

import numpy as np

import simulators.grbl.codes as C

MM_PER_INCH = 25.4
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")


class GrblError(Exception):
    """A status code GRBL answers as `error:N`."""

    def __init__(self, code: int):
        super().__init__(f"error:{code}")
        self.code = code


def preparse(raw: bytes) -> tuple[str, bool]:
    """Strip a received line as GRBL's protocol loop does; return (line, overflowed).

    Whitespace and control characters are dropped, `(...)` and `;` comments removed, `/` block
    delete ignored, letters upper-cased, and more than LINE_BUFFER_SIZE-1 (79) significant
    characters flag a line overflow (error:11).
    """
    out: list[str] = []
    paren = semicolon = overflow = False
    for byte in raw:
        c = chr(byte)
        if paren or semicolon or overflow:
            if c == ")" and paren:
                paren = False
            continue
        if byte <= 0x20 or c == "/":
            continue
        if c == "(":
            paren = True
        elif c == ";":
            semicolon = True
        elif len(out) >= C.LINE_BUFFER_SIZE - 1:
            overflow = True
        else:
            out.append(c.upper() if "a" <= c <= "z" else c)
    return "".join(out), overflow


def split_words(line: str) -> list[tuple[str, float]]:
    """`G1X10.5F300` -> [("G",1.0),("X",10.5),("F",300.0)]; error:1 / error:2 on bad syntax."""
    words = []
    i = 0
    while i < len(line):
        letter = line[i]
        if not ("A" <= letter <= "Z"):
            raise GrblError(C.E_EXPECTED_COMMAND_LETTER)
        m = _NUMBER.match(line, i + 1)
        if m is None:
            raise GrblError(C.E_BAD_NUMBER_FORMAT)
        words.append((letter, float(m.group())))
        i = m.end()
    return words


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


# Modal groups of the G and M words GRBL 1.1 accepts (commands.md "Modal Group Meaning").
_G_GROUPS = {
    4: 0, 10: 0, 28: 0, 30: 0, 53: 0, 92: 0,
    0: 1, 1: 1, 2: 1, 3: 1, 80: 1,
    17: 2, 18: 2, 19: 2,
    90: 3, 91: 3,
    93: 5, 94: 5,
    20: 6, 21: 6,
    40: 7,
    43: 8, 49: 8,
    54: 12, 55: 12, 56: 12, 57: 12, 58: 12, 59: 12,
    61: 13,
}  # fmt: skip
_M_GROUPS = {0: 4, 1: 4, 2: 4, 30: 4, 3: 7, 4: 7, 5: 7, 8: 8, 9: 8}
_AXIS = {"X": 0, "Y": 1, "Z": 2}
_VALUE_LETTERS = set("FIJKLNPRSTXYZ")
_PLANES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}


@dataclass
class Move:
    """One planner block request: target in machine mm, feed in mm/min (None = rapid)."""

    target: np.ndarray
    feed: float | None
    jog: bool = False
    spindle: str = "M5"
    speed: float = 0.0
    line_number: int = 0


def parse_block(
    line: str,
    state: ParserState,
    params: Params,
    settings: dict[int, float],
    *,
    jog: bool = False,
) -> tuple[ParserState, Params, list[tuple]]:
    """Validate one block and return (new parser state, new params, actions); raise GrblError.

    Actions: ("move", Move), ("sync",), ("dwell", s), ("spindle", M, S), ("coolant", flood),
    ("wco",), ("pause", "M0"), ("end",), ("store_params",).
    """
    words = split_words(line)
    g_groups: dict[int, tuple[int, int]] = {}
    m_groups: dict[int, int] = {}
    values: dict[str, float] = {}
    axis_command: str | None = None  # "nonmodal" | "motion"
    for letter, value in words:
        if letter == "G":
            ival = int(value)
            mant = int(round(100 * (value - ival)))
            if ival == 38:
                raise GrblError(C.E_GCODE_UNSUPPORTED_COMMAND)  # no probe on a cutter
            if ival not in _G_GROUPS:
                raise GrblError(C.E_GCODE_UNSUPPORTED_COMMAND)
            allowed_mant = {28: {0, 10}, 30: {0, 10}, 92: {0, 10}, 91: {0, 10}, 43: {10}}
            if mant not in allowed_mant.get(ival, {0}):
                if ival == 90 or (ival == 43 and mant == 0):
                    raise GrblError(C.E_GCODE_UNSUPPORTED_COMMAND)
                raise GrblError(C.E_GCODE_COMMAND_VALUE_NOT_INTEGER)
            group = _G_GROUPS[ival]
            if ival == 91 and mant == 10:
                group = 4  # G91.1 arc IJK distance mode
            if group == 0 and ival in (10, 28, 30, 92) and mant == 0:
                if axis_command:
                    raise GrblError(C.E_GCODE_AXIS_COMMAND_CONFLICT)
                axis_command = "nonmodal"
            elif group == 1:
                if axis_command:
                    raise GrblError(C.E_GCODE_AXIS_COMMAND_CONFLICT)
                axis_command = "motion"
            if group in g_groups:
                raise GrblError(C.E_GCODE_MODAL_GROUP_VIOLATION)
            g_groups[group] = (ival, mant)
        elif letter == "M":
            ival = int(value)
            if value != ival:
                raise GrblError(C.E_GCODE_COMMAND_VALUE_NOT_INTEGER)
            if ival not in _M_GROUPS:
                raise GrblError(C.E_GCODE_UNSUPPORTED_COMMAND)  # M7 needs ENABLE_M7
            group = _M_GROUPS[ival]
            if group in m_groups:
                raise GrblError(C.E_GCODE_MODAL_GROUP_VIOLATION)
            m_groups[group] = ival
        elif letter in _VALUE_LETTERS:
            if letter in values:
                raise GrblError(C.E_GCODE_WORD_REPEATED)
            if letter in "FNPST" and value < 0:
                raise GrblError(C.E_NEGATIVE_VALUE)
            values[letter] = value
        else:
            raise GrblError(C.E_GCODE_UNSUPPORTED_COMMAND)

    new = copy.deepcopy(state)
    par = copy.deepcopy(params)
    actions: list[tuple] = []
    axis_words = {k: v for k, v in values.items() if k in _AXIS}
    used = set("NFST") | set(axis_words)
    if axis_words and axis_command is None:
        axis_command = "motion"

    if jog:
        # commands.md: only G20/G21, G90/G91 and G53 are allowed in a jog; F is required.
        if m_groups or set(g_groups) - {0, 3, 6}:
            raise GrblError(C.E_INVALID_JOG_COMMAND)
        if 0 in g_groups and g_groups[0] != (53, 0):
            raise GrblError(C.E_INVALID_JOG_COMMAND)
        if set(values) - set("XYZFN"):
            raise GrblError(C.E_INVALID_JOG_COMMAND)
        if "F" not in values:
            raise GrblError(C.E_GCODE_UNDEFINED_FEED_RATE)

    if values.get("N", 0) > C.MAX_LINE_NUMBER:
        raise GrblError(C.E_GCODE_INVALID_LINE_NUMBER)
    # Modal words that change how values are read come first.
    if 6 in g_groups:
        new.inches = g_groups[6][0] == 20
    if 3 in g_groups:
        new.incremental = g_groups[3][0] == 91
    if 5 in g_groups and not jog:
        new.inverse_time = g_groups[5][0] == 93
    unit = MM_PER_INCH if new.inches else 1.0
    if jog:
        jog_feed = values["F"] * unit
    elif "F" in values:
        if new.inverse_time:
            pass  # inverse-time F is per block, handled with the motion
        else:
            new.feed = values["F"] * unit
    elif 5 in g_groups and state.inverse_time and not new.inverse_time:
        new.feed = 0.0  # "Feed rate is not defined after switching to G94 from G93"
    if "T" in values:
        if values["T"] > C.MAX_TOOL_NUMBER:
            raise GrblError(C.E_GCODE_MAX_VALUE_EXCEEDED)
        new.tool = int(values["T"])
    if "S" in values and not jog:
        new.speed = values["S"]

    nonmodal = g_groups.get(0)
    if nonmodal and nonmodal[0] == 4:
        if "P" not in values:
            raise GrblError(C.E_GCODE_VALUE_WORD_MISSING)
        used.add("P")
    if 2 in g_groups:
        new.plane = g_groups[2][0]
    if 8 in g_groups:
        ival, _ = g_groups[8]
        if ival == 43:
            if set(axis_words) != {"Z"}:
                raise GrblError(C.E_GCODE_G43_DYNAMIC_AXIS_ERROR)
            axis_command = "nonmodal"
        new.tlo = axis_words["Z"] * unit if ival == 43 else 0.0
    if 12 in g_groups:
        new.coord_index = g_groups[12][0] - 54
    if 1 in g_groups and not jog:
        new.motion = f"G{g_groups[1][0]}"

    def wco(s: ParserState, p: Params) -> np.ndarray:
        off = p.coord[s.coord_index] + s.g92
        off = off.copy()
        off[2] += s.tlo
        return off

    offset = wco(new, par)
    if new.motion == "G80" and axis_words and axis_command == "motion" and not jog:
        raise GrblError(C.E_GCODE_AXIS_WORDS_EXIST)

    absolute_override = nonmodal == (53, 0)
    if absolute_override and not jog and new.motion not in ("G0", "G1"):
        raise GrblError(C.E_GCODE_G53_INVALID_MOTION_MODE)

    def target_of(pos: np.ndarray, machine: bool = False) -> np.ndarray:
        t = pos.copy()
        for k, v in axis_words.items():
            i = _AXIS[k]
            v *= unit
            if machine:
                t[i] = v
            elif new.incremental:
                t[i] = pos[i] + v
            else:
                t[i] = v + offset[i]
        return t

    # Non-modal actions (G10, G28, G30, G92, G92.1, G28.1, G30.1).
    if nonmodal and nonmodal[0] == 10:
        if not axis_words:
            raise GrblError(C.E_GCODE_NO_AXIS_WORDS)
        if "P" not in values or "L" not in values:
            raise GrblError(C.E_GCODE_VALUE_WORD_MISSING)
        used |= {"P", "L"}
        p = int(values["P"])
        if p > 6:
            raise GrblError(C.E_GCODE_UNSUPPORTED_COORD_SYS)
        idx = new.coord_index if p == 0 else p - 1
        lval = int(values["L"])
        if lval not in (2, 20):
            raise GrblError(C.E_GCODE_UNSUPPORTED_COMMAND)
        for k, v in axis_words.items():
            i = _AXIS[k]
            v *= unit
            if lval == 20:
                v = new.position[i] - new.g92[i] - (new.tlo if i == 2 else 0.0) - v
            par.coord[idx, i] = v
        actions.append(("store_params",))
    elif nonmodal and nonmodal[0] in (28, 30):
        if nonmodal[1] == 10:
            if nonmodal[0] == 28:
                par.g28 = new.position.copy()
            else:
                par.g30 = new.position.copy()
            actions.append(("store_params",))
        else:
            home = par.g28 if nonmodal[0] == 28 else par.g30
            if axis_words:  # "G28 X.. Y..": rapid to the intermediate point first
                actions.append(("move", Move(target_of(new.position), None)))
            final = home.copy()
            actions.append(("move", Move(final, None)))
            new.position = final
    elif nonmodal and nonmodal[0] == 92:
        if nonmodal[1] == 10:
            new.g92 = np.zeros(3)
        else:
            if not axis_words:
                raise GrblError(C.E_GCODE_NO_AXIS_WORDS)
            for k, v in axis_words.items():
                i = _AXIS[k]
                new.g92[i] = new.position[i] - par.coord[new.coord_index, i] - v * unit
                if i == 2:
                    new.g92[i] -= new.tlo
        actions.append(("wco",))
    if (
        12 in g_groups
        or 8 in g_groups
        or (nonmodal and nonmodal[0] == 10 and (int(values["P"]) in (0, new.coord_index + 1)))
    ):
        actions.append(("wco",))

    # Motion.
    motion_target = None
    if axis_command == "motion" and (new.motion != "G80" or jog):
        mode = "G1" if jog else new.motion
        if mode in ("G1", "G2", "G3") and not jog:
            if new.inverse_time:
                if "F" not in values:
                    raise GrblError(C.E_GCODE_UNDEFINED_FEED_RATE)
            elif new.feed == 0.0:
                raise GrblError(C.E_GCODE_UNDEFINED_FEED_RATE)
        if mode in ("G2", "G3") and not axis_words:
            raise GrblError(C.E_GCODE_NO_AXIS_WORDS)
        if axis_words:
            target = target_of(new.position, machine=absolute_override)
            feed = jog_feed if jog else (None if mode == "G0" else new.feed)
            if mode in ("G2", "G3"):
                points, used_words = _arc(new, values, target, mode == "G2", settings, unit)
                used |= used_words
                length = float(np.sum(np.linalg.norm(np.diff(
                    np.vstack([new.position, points]), axis=0), axis=1)))
                if new.inverse_time:
                    feed = length * values["F"]
                for pt in points:
                    actions.append(("move", Move(pt, feed, spindle=new.spindle, speed=new.speed)))
            else:
                if new.inverse_time and feed is not None and not jog:
                    feed = float(np.linalg.norm(target - new.position)) * values["F"]
                actions.append(("move", Move(target, feed, jog=jog, spindle=new.spindle,
                                             speed=new.speed,
                                             line_number=int(values.get("N", 0)))))
            motion_target = target
    elif axis_words and axis_command == "nonmodal":
        pass
    if motion_target is not None:
        new.position = motion_target

    unused = set(values) - used
    if unused:
        raise GrblError(C.E_GCODE_UNUSED_WORDS)

    # Spindle / coolant / dwell / program flow, in GRBL's execution order. Motion entries in
    # `actions` carry the new spindle state; the spindle change itself is applied before them.
    pre: list[tuple] = []
    if 7 in m_groups:
        new.spindle = f"M{m_groups[7]}"
        for kind, *rest in actions:
            if kind == "move":
                rest[0].spindle = new.spindle
    spindle_changed = new.spindle != state.spindle
    speed_changed = "S" in values and new.speed != state.speed
    if spindle_changed or speed_changed:
        pre.append(("spindle", new.spindle, new.speed, spindle_changed, motion_target is None))
    if 8 in m_groups:
        new.flood = m_groups[8] == 8
        pre.append(("coolant", new.flood))
    if nonmodal and nonmodal[0] == 4:
        pre.append(("dwell", values["P"]))
    post: list[tuple] = []
    if 4 in m_groups:
        stop = m_groups[4]
        if stop in (0, 1):
            new.program = f"M{stop}"
            post.append(("pause", f"M{stop}"))
        else:
            post.append(("end",))
    return new, par, pre + actions + post


def _arc(
    state: ParserState,
    values: dict[str, float],
    target: np.ndarray,
    clockwise: bool,
    settings: dict[int, float],
    unit: float,
) -> tuple[np.ndarray, set[str]]:
    """Segment a G2/G3 arc into chords within the `$12` arc tolerance; (k,3) points."""
    a0, a1, lin = _PLANES[state.plane]
    pos = state.position
    if not any(k in values for k in ("XYZ"[a0], "XYZ"[a1])):
        raise GrblError(C.E_GCODE_NO_AXIS_WORDS_IN_PLANE)
    dx, dy = target[a0] - pos[a0], target[a1] - pos[a1]
    if "R" in values:
        used = {"R"}
        if np.allclose(pos, target):
            raise GrblError(C.E_GCODE_INVALID_TARGET)
        r = values["R"] * unit
        h2 = 4.0 * r * r - dx * dx - dy * dy
        if h2 < 0:
            raise GrblError(C.E_GCODE_ARC_RADIUS_ERROR)
        h = -math.sqrt(h2) / math.hypot(dx, dy)
        if not clockwise:
            h = -h
        if r < 0:
            h, r = -h, -r
        i_off, j_off = 0.5 * (dx - dy * h), 0.5 * (dy + dx * h)
    else:
        names = ("IJK"[a0], "IJK"[a1])
        if not any(n in values for n in names):
            raise GrblError(C.E_GCODE_NO_OFFSETS_IN_PLANE)
        used = {n for n in "IJK" if n in values}
        i_off = values.get(names[0], 0.0) * unit
        j_off = values.get(names[1], 0.0) * unit
        r = math.hypot(i_off, j_off)
        r_end = math.hypot(dx - i_off, dy - j_off)
        delta = abs(r_end - r)
        if delta > 0.005 and (delta > 0.5 or delta > 0.001 * r):
            raise GrblError(C.E_GCODE_INVALID_TARGET)
    cx, cy = pos[a0] + i_off, pos[a1] + j_off
    start = math.atan2(pos[a1] - cy, pos[a0] - cx)
    end = math.atan2(target[a1] - cy, target[a0] - cx)
    travel = end - start
    eps = 5e-7
    if clockwise:
        if travel >= -eps:
            travel -= 2 * math.pi
    elif travel <= eps:
        travel += 2 * math.pi
    tol = float(settings[12])
    n = int(abs(0.5 * travel * r) / math.sqrt(tol * (2 * r - tol))) if r > tol else 0
    n = max(n, 1)
    t = np.arange(1, n + 1) / n
    ang = start + travel * t
    pts = np.repeat(pos[None, :], n, axis=0).astype(float)
    pts[:, a0] = cx + r * np.cos(ang)
    pts[:, a1] = cy + r * np.sin(ang)
    pts[:, lin] = pos[lin] + (target[lin] - pos[lin]) * t
    pts[-1] = target
    return pts, used


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
