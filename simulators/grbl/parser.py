"""GRBL 1.1 G-code block parser.

A block is validated completely before anything changes, as GRBL's gc_execute_line does:
"Grbl did not recognize the command and did not execute anything inside that message"
(interface.md, `error:X`). The parser keeps GRBL's modal state (`$G`) and the parser position,
and turns a valid block into a list of actions that the machine executes in order
(planner moves, buffer syncs, dwells, spindle/coolant changes, program pause/end).

Like the firmware's gcode.c, a block goes through steps in a fixed order: its words are read
and sorted into modal groups, then one small step per modal group or word checks and applies
it (`_STEPS`), the non-modal commands through a table of their own (`_NON_MODAL`). The order of
the steps is the order in which errors are found, which a sender sees.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

import simulators.grbl.codes as C
from simulators.grbl.arc import arc_points
from simulators.grbl.parser_state import (
    MM_PER_INCH,
    GrblError,
    Move,
    Params,
    ParserState,
    work_offset,
)
from simulators.grbl.words import AXIS, Words, read_words


@dataclass
class _Block:
    """One block on its way through the steps: its words, the parser state before it, the
    state and parameters it makes, and the actions it asks of the machine."""

    words: Words
    old: ParserState
    new: ParserState
    params: Params
    settings: dict[int, float]
    jog: bool
    axis_words: dict[str, float]
    used: set[str]  # value letters some step consumed; any other is error:36
    axis_command: str | None
    unit: float = 1.0  # mm per unit of the block's numbers
    jog_feed: float = 0.0
    offset: np.ndarray = field(default_factory=lambda: np.zeros(3))  # work offset
    motion_target: np.ndarray | None = None
    pre: list[tuple] = field(default_factory=list)  # spindle, coolant, dwell: before motion
    actions: list[tuple] = field(default_factory=list)
    post: list[tuple] = field(default_factory=list)  # program pause or end

    @classmethod
    def start(cls, words: Words, state: ParserState, params: Params,
              settings: dict[int, float], jog: bool) -> _Block:
        axis_words = {k: v for k, v in words.values.items() if k in AXIS}
        axis_command = words.axis_command or ("motion" if axis_words else None)
        return cls(words=words, old=state, new=copy.deepcopy(state),
                   params=copy.deepcopy(params), settings=settings, jog=jog,
                   axis_words=axis_words, used=set("NFST") | set(axis_words),
                   axis_command=axis_command)

    @property
    def values(self) -> dict[str, float]:
        return self.words.values

    @property
    def nonmodal(self) -> tuple[int, int] | None:
        return self.words.g.get(0)

    def target(self, pos: np.ndarray, machine: bool = False) -> np.ndarray:
        """``pos`` moved by the block's axis words (machine mm): G53 machine coordinates,
        G91 increments, or G90 work coordinates."""
        t = pos.copy()
        for k, v in self.axis_words.items():
            i = AXIS[k]
            v *= self.unit
            if machine:
                t[i] = v
            elif self.new.incremental:
                t[i] = pos[i] + v
            else:
                t[i] = v + self.offset[i]
        return t


def _check_jog(b: _Block) -> None:
    """commands.md: only G20/G21, G90/G91 and G53 are allowed in a jog; F is required."""
    if not b.jog:
        return
    if b.words.m or set(b.words.g) - {0, 3, 6}:
        raise GrblError(C.E_INVALID_JOG_COMMAND)
    if 0 in b.words.g and b.words.g[0] != (53, 0):
        raise GrblError(C.E_INVALID_JOG_COMMAND)
    if set(b.values) - set("XYZFN"):
        raise GrblError(C.E_INVALID_JOG_COMMAND)
    if "F" not in b.values:
        raise GrblError(C.E_GCODE_UNDEFINED_FEED_RATE)


def _check_line_number(b: _Block) -> None:
    if b.values.get("N", 0) > C.MAX_LINE_NUMBER:
        raise GrblError(C.E_GCODE_INVALID_LINE_NUMBER)


def _set_reading_modes(b: _Block) -> None:
    """G20/G21, G90/G91, G93/G94 first: they change how the block's numbers are read."""
    g = b.words.g
    if 6 in g:
        b.new.inches = g[6][0] == 20
    if 3 in g:
        b.new.incremental = g[3][0] == 91
    if 5 in g and not b.jog:
        b.new.inverse_time = g[5][0] == 93
    b.unit = MM_PER_INCH if b.new.inches else 1.0


def _set_feed(b: _Block) -> None:
    if b.jog:
        b.jog_feed = b.values["F"] * b.unit
    elif "F" in b.values:
        if not b.new.inverse_time:  # an inverse-time F is per block, read with the motion
            b.new.feed = b.values["F"] * b.unit
    elif 5 in b.words.g and b.old.inverse_time and not b.new.inverse_time:
        b.new.feed = 0.0  # "Feed rate is not defined after switching to G94 from G93"


def _set_tool(b: _Block) -> None:
    if "T" in b.values:
        if b.values["T"] > C.MAX_TOOL_NUMBER:
            raise GrblError(C.E_GCODE_MAX_VALUE_EXCEEDED)
        b.new.tool = int(b.values["T"])


def _set_speed(b: _Block) -> None:
    if "S" in b.values and not b.jog:
        b.new.speed = b.values["S"]


def _check_dwell(b: _Block) -> None:
    if b.nonmodal and b.nonmodal[0] == 4:
        if "P" not in b.values:
            raise GrblError(C.E_GCODE_VALUE_WORD_MISSING)
        b.used.add("P")


def _set_plane(b: _Block) -> None:
    if 2 in b.words.g:
        b.new.plane = b.words.g[2][0]


def _set_tool_length(b: _Block) -> None:
    """G43.1 Z sets the dynamic tool length offset (its Z word is not a motion), G49
    cancels it."""
    if 8 not in b.words.g:
        return
    number, _ = b.words.g[8]
    if number == 43:
        if set(b.axis_words) != {"Z"}:
            raise GrblError(C.E_GCODE_G43_DYNAMIC_AXIS_ERROR)
        b.axis_command = "nonmodal"
    b.new.tlo = b.axis_words["Z"] * b.unit if number == 43 else 0.0


def _select_coordinates(b: _Block) -> None:
    if 12 in b.words.g:
        b.new.coord_index = b.words.g[12][0] - 54


def _set_motion_mode(b: _Block) -> None:
    if 1 in b.words.g and not b.jog:
        b.new.motion = f"G{b.words.g[1][0]}"


def _check_axis_words(b: _Block) -> None:
    """Axis words need a motion mode (not G80); G53 needs G0 or G1. The work offset that
    reads them is the one in force before this block's G10 or G92."""
    b.offset = work_offset(b.new, b.params)
    if b.new.motion == "G80" and b.axis_words and b.axis_command == "motion" and not b.jog:
        raise GrblError(C.E_GCODE_AXIS_WORDS_EXIST)
    if b.nonmodal == (53, 0) and not b.jog and b.new.motion not in ("G0", "G1"):
        raise GrblError(C.E_GCODE_G53_INVALID_MOTION_MODE)


def _set_coordinate_data(b: _Block) -> None:
    """G10 L2 Pn / G10 L20 Pn: store a work origin (L20: such that here is the given
    position) in EEPROM."""
    if not b.axis_words:
        raise GrblError(C.E_GCODE_NO_AXIS_WORDS)
    if "P" not in b.values or "L" not in b.values:
        raise GrblError(C.E_GCODE_VALUE_WORD_MISSING)
    b.used |= {"P", "L"}
    p = int(b.values["P"])
    if p > 6:
        raise GrblError(C.E_GCODE_UNSUPPORTED_COORD_SYS)
    idx = b.new.coord_index if p == 0 else p - 1
    l_value = int(b.values["L"])
    if l_value not in (2, 20):
        raise GrblError(C.E_GCODE_UNSUPPORTED_COMMAND)
    new = b.new
    for k, v in b.axis_words.items():
        i = AXIS[k]
        v *= b.unit
        if l_value == 20:
            v = new.position[i] - new.g92[i] - (new.tlo if i == 2 else 0.0) - v
        b.params.coord[idx, i] = v
    b.actions.append(("store_params",))


def _go_home(b: _Block) -> None:
    """G28 / G30: rapid through the given point (if any) to the stored position."""
    home = b.params.g28 if b.nonmodal[0] == 28 else b.params.g30
    if b.axis_words:
        b.actions.append(("move", Move(b.target(b.new.position), None)))
    final = home.copy()
    b.actions.append(("move", Move(final, None)))
    b.new.position = final


def _set_home(b: _Block) -> None:
    """G28.1 / G30.1: store the present position in EEPROM."""
    if b.nonmodal[0] == 28:
        b.params.g28 = b.new.position.copy()
    else:
        b.params.g30 = b.new.position.copy()
    b.actions.append(("store_params",))


def _set_g92(b: _Block) -> None:
    """G92: offset the work coordinates so that here reads as the given position."""
    if not b.axis_words:
        raise GrblError(C.E_GCODE_NO_AXIS_WORDS)
    new = b.new
    for k, v in b.axis_words.items():
        i = AXIS[k]
        new.g92[i] = new.position[i] - b.params.coord[new.coord_index, i] - v * b.unit
        if i == 2:
            new.g92[i] -= new.tlo
    b.actions.append(("wco",))


def _clear_g92(b: _Block) -> None:
    b.new.g92 = np.zeros(3)
    b.actions.append(("wco",))


_NON_MODAL: dict[tuple[int, int], Callable[[_Block], None]] = {
    (10, 0): _set_coordinate_data,
    (28, 0): _go_home,
    (30, 0): _go_home,
    (28, 10): _set_home,
    (30, 10): _set_home,
    (92, 0): _set_g92,
    (92, 10): _clear_g92,
}  # G4 and G53 act elsewhere (_check_dwell, _dwell, _motion)


def _non_modal(b: _Block) -> None:
    handler = _NON_MODAL.get(b.nonmodal) if b.nonmodal else None
    if handler is not None:
        handler(b)


def _report_offsets(b: _Block) -> None:
    """A new work offset is reported (`WCO:`) in the next status report."""
    g = b.words.g
    active_g10 = (b.nonmodal and b.nonmodal[0] == 10
                  and int(b.values["P"]) in (0, b.new.coord_index + 1))
    if 12 in g or 8 in g or active_g10:
        b.actions.append(("wco",))


def _check_feed_defined(b: _Block, mode: str) -> None:
    if mode not in ("G1", "G2", "G3") or b.jog:
        return
    if b.new.inverse_time:
        if "F" not in b.values:
            raise GrblError(C.E_GCODE_UNDEFINED_FEED_RATE)
    elif b.new.feed == 0.0:
        raise GrblError(C.E_GCODE_UNDEFINED_FEED_RATE)


def _motion(b: _Block) -> None:
    """The block's motion in the modal motion mode (a jog is always G1)."""
    if b.axis_command != "motion" or (b.new.motion == "G80" and not b.jog):
        return
    mode = "G1" if b.jog else b.new.motion
    _check_feed_defined(b, mode)
    if mode in ("G2", "G3") and not b.axis_words:
        raise GrblError(C.E_GCODE_NO_AXIS_WORDS)
    if not b.axis_words:
        return
    target = b.target(b.new.position, machine=b.nonmodal == (53, 0))
    feed = b.jog_feed if b.jog else (None if mode == "G0" else b.new.feed)
    if mode in ("G2", "G3"):
        _arc_moves(b, target, feed, clockwise=mode == "G2")
    else:
        _line_move(b, target, feed)
    b.motion_target = target
    b.new.position = target


def _arc_moves(b: _Block, target: np.ndarray, feed: float | None, clockwise: bool) -> None:
    points, used = arc_points(b.new, b.values, target, clockwise, b.settings, b.unit)
    b.used |= used
    if b.new.inverse_time:  # F is 1/minutes for the whole arc
        length = float(np.sum(np.linalg.norm(np.diff(
            np.vstack([b.new.position, points]), axis=0), axis=1)))
        feed = length * b.values["F"]
    for pt in points:
        b.actions.append(("move", Move(pt, feed, spindle=b.new.spindle, speed=b.new.speed)))


def _line_move(b: _Block, target: np.ndarray, feed: float | None) -> None:
    if b.new.inverse_time and feed is not None and not b.jog:
        feed = float(np.linalg.norm(target - b.new.position)) * b.values["F"]
    b.actions.append(("move", Move(target, feed, jog=b.jog, spindle=b.new.spindle,
                                   speed=b.new.speed, line_number=int(b.values.get("N", 0)))))


def _check_unused(b: _Block) -> None:
    if set(b.values) - b.used:
        raise GrblError(C.E_GCODE_UNUSED_WORDS)


def _spindle(b: _Block) -> None:
    """M3/M4/M5 and S, applied before the block's motion; the moves carry the new state."""
    if 7 in b.words.m:
        b.new.spindle = f"M{b.words.m[7]}"
        for kind, *rest in b.actions:
            if kind == "move":
                rest[0].spindle = b.new.spindle
    spindle_changed = b.new.spindle != b.old.spindle
    speed_changed = "S" in b.values and b.new.speed != b.old.speed
    if spindle_changed or speed_changed:
        b.pre.append(("spindle", b.new.spindle, b.new.speed, spindle_changed,
                      b.motion_target is None))


def _coolant(b: _Block) -> None:
    if 8 in b.words.m:
        b.new.flood = b.words.m[8] == 8
        b.pre.append(("coolant", b.new.flood))


def _dwell(b: _Block) -> None:
    if b.nonmodal and b.nonmodal[0] == 4:
        b.pre.append(("dwell", b.values["P"]))


def _program_flow(b: _Block) -> None:
    """M0/M1 pause after the block, M2/M30 end the program."""
    if 4 not in b.words.m:
        return
    stop = b.words.m[4]
    if stop in (0, 1):
        b.new.program = f"M{stop}"
        b.post.append(("pause", f"M{stop}"))
    else:
        b.post.append(("end",))


#: The steps of a block, in GRBL's order (gcode.c's "STEP 3" checks then "STEP 4" execution).
_STEPS: tuple[Callable[[_Block], None], ...] = (
    _check_jog,
    _check_line_number,
    _set_reading_modes,
    _set_feed,
    _set_tool,
    _set_speed,
    _check_dwell,
    _set_plane,
    _set_tool_length,
    _select_coordinates,
    _set_motion_mode,
    _check_axis_words,
    _non_modal,
    _report_offsets,
    _motion,
    _check_unused,
    _spindle,
    _coolant,
    _dwell,
    _program_flow,
)


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
    block = _Block.start(read_words(line), state, params, settings, jog)
    for step in _STEPS:
        step(block)
    return block.new, block.params, block.pre + block.actions + block.post
