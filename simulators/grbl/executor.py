"""The emulated controller's executor: the actions of parsed lines, the planner and the motion.

A parsed line becomes a queue of actions (`parser.parse_block`); `Executor._run_pending`
runs them in order through one small handler per kind (`Executor._ACTIONS`) and stops where
GRBL would block: the planner full, a buffer sync, a dwell. `_motion_step` moves the head
block through its acceleration phases in simulated time and traces what ran; alarms stop the
motion where it is.
"""

from __future__ import annotations

import copy
from collections import deque
from collections.abc import Callable

import numpy as np

import simulators.grbl.codes as C
from simulators.grbl.laser import is_dynamic, power_pieces, segment_value
from simulators.grbl.motion import Block, Segment, exit_speed, make_block, phase
from simulators.grbl.parser import parse_block
from simulators.grbl.parser_state import GrblError, Move
from simulators.grbl.state import MachineState


class Executor(MachineState):
    """Runs parsed lines on the planner and moves the machine (a base of `GrblEmulator`)."""

    # ------------------------------------------------------------------ parsed lines
    def _gcode(self, line: str, jog: bool = False) -> list[tuple]:
        """Parse a block, commit parser state, and return the machine actions it needs."""
        gc, params, actions = parse_block(line, self._gc, self.params, self.settings, jog=jog)
        if jog:  # "Jog commands are completely independent of the g-code parser state"
            position, gc = gc.position, copy.deepcopy(self._gc)
            gc.position = position
        out: list[tuple] = []
        for act in actions:
            if act[0] == "move":
                target = act[1].target
                if self.settings[20] and self._outside(target):
                    if jog:
                        raise GrblError(C.E_TRAVEL_EXCEEDED)
                    out.append(("softlimit",))
                    out.append(("softlimit_ok",))
                    break
            out.append(act)
        self._gc = gc
        if self._state != "Check":  # check mode never writes EEPROM (G10, G28.1, G30.1)
            self.params = params
        return out

    def _outside(self, target: np.ndarray) -> bool:
        travel = np.array([self.settings[130], self.settings[131], self.settings[132]], float)
        mask = int(self.settings[23])
        for i in range(3):
            if self.force_origin and mask & (1 << i):
                lo, hi = 0.0, travel[i]
            else:
                lo, hi = -travel[i], 0.0
            if target[i] < lo - 1e-9 or target[i] > hi + 1e-9:
                return True
        return False

    def _queue_line(self, actions: list[tuple]) -> None:
        """Queue a line's actions and its `ok`, and run as much of it as can run now."""
        self._pending.extend(actions)
        self._pending.append(("emit", "ok", True))
        self._run_pending()

    def _run_pending(self) -> bool:
        """Execute queued actions of the current line; False while blocked (planner full,
        waiting for a sync or a dwell)."""
        while self._pending:
            act = self._pending[0]
            if not self._ACTIONS[act[0]](self, act):
                return False
            self._pending.popleft()
        return True

    # Each handler runs one action and says whether it is done (False: blocked, run it again
    # later). Check mode (`$C`) parses everything and runs nothing.
    def _do_move(self, act: tuple) -> bool:
        if self._state == "Check":
            return True
        if len(self._planner) >= C.PLANNER_BLOCKS:
            return False
        self._plan(act[1])
        return True

    def _do_sync(self, act: tuple) -> bool:
        """A buffer sync; also an EEPROM write, which forces one."""
        return not (self._planner and self._state != "Check")

    def _do_dwell(self, act: tuple) -> bool:
        if self._state == "Check":
            return True
        if self._planner:
            return False
        if self._dwell_until is None:
            self._dwell_until = self.sim_time + float(act[1])
        if self.sim_time < self._dwell_until - 1e-12:
            return False
        self._dwell_until = None
        return True

    def _do_spindle(self, act: tuple) -> bool:
        """In laser mode a new S between moves changes the power without a sync; a change of
        M3/M4/M5, or M3 without motion, syncs the planner."""
        _, state, speed, state_changed, no_motion = act
        if self._state == "Check":
            return True
        laser = bool(self.settings[32])
        needs_sync = state_changed or not laser or (state == "M3" and no_motion)
        if needs_sync and self._planner:
            return False
        if not laser or state_changed or no_motion:
            self._spindle_out = (state, speed)
            self._ovr_counter = 0
        return True

    def _do_coolant(self, act: tuple) -> bool:
        if self._state == "Check":
            return True
        if self._planner:
            return False
        self._flood = act[1]
        self._ovr_counter = 0
        return True

    def _do_wco(self, act: tuple) -> bool:
        self._wco_counter = 0
        return True

    def _do_pause(self, act: tuple) -> bool:
        if self._state == "Check":
            return True
        if self._planner:
            return False
        self._state = "Hold"
        self._hold = True
        self._hold_complete = True
        return True

    def _do_end(self, act: tuple) -> bool:
        if self._planner and self._state != "Check":
            return False
        self._program_end()
        return True

    def _do_soft_limit(self, act: tuple) -> bool:
        if self._state == "Run" and self._v > 0:
            self._hold = True  # come to a controlled stop first
            return False
        self._soft_limit_alarm()
        return False

    def _do_soft_limit_ok(self, act: tuple) -> bool:
        return False  # answered after the reset (see _soft_reset)

    def _do_emit(self, act: tuple) -> bool:
        self._emit(act[1])
        if act[2]:
            self.lines_executed += 1
        return True

    _ACTIONS: dict[str, Callable[[Executor, tuple], bool]] = {
        "move": _do_move,
        "sync": _do_sync,
        "store_params": _do_sync,
        "dwell": _do_dwell,
        "spindle": _do_spindle,
        "coolant": _do_coolant,
        "wco": _do_wco,
        "pause": _do_pause,
        "end": _do_end,
        "softlimit": _do_soft_limit,
        "softlimit_ok": _do_soft_limit_ok,
        "emit": _do_emit,
    }

    def _program_end(self) -> None:
        """M2/M30: restore parser defaults as GRBL does and report `[MSG:Pgm End]`."""
        gc = self._gc
        gc.motion, gc.plane, gc.incremental, gc.inverse_time = "G1", 17, False, False
        gc.coord_index, gc.spindle, gc.flood, gc.program = 0, "M5", False, ""
        self._spindle_out = ("M5", gc.speed)
        self._flood = False
        self._feed_ovr = self._rapid_ovr = self._spindle_ovr = 100.0
        self._wco_counter = 0
        if self._state != "Check":
            self._emit(C.MSG_PGM_END)

    def _plan(self, move: Move) -> None:
        previous = self._planner[-1] if self._planner else None
        start = previous.end if previous is not None else self._pos
        block = make_block(start, move.target, move.feed, self.settings, previous,
                           jog=move.jog, spindle=move.spindle, speed=move.speed,
                           line_number=move.line_number)
        if block is None:
            return
        self._planner.append(block)
        if self._state == "Idle":
            self._state = "Jog" if move.jog else "Run"

    # ------------------------------------------------------------------ motion
    def _motion_step(self, end: float) -> None:
        """Move the head block to the end of its present phase (accelerate, cruise, brake)
        or to simulated time ``end``, whichever comes first."""
        b = self._planner[0]
        if self._state == "Idle":
            self._state = "Jog" if b.jog else "Run"
        if self.settings[32]:  # laser mode: power follows each block without stopping
            self._spindle_out = (b.spindle, b.speed)
        vn = b.nominal(self._feed_ovr, self._rapid_ovr)
        ve = exit_speed(list(self._planner), self._feed_ovr, self._rapid_ovr)
        d = b.remaining
        acc, duration = phase(self._v, d, vn, ve, b.accel, self._hold)
        tt = min(end - self.sim_time, duration)
        s = self._move_along(b, acc, tt, duration, min(ve, vn))
        if b.remaining <= 1e-7 or (tt >= duration and d - s <= 1e-7):
            self._complete_block(b)
        else:
            self._pos = b.start + b.unit * b.done
        self._after_step(b, vn, duration, s)

    def _move_along(self, b: Block, acc: float, tt: float, duration: float,
                    v_exit: float) -> float:
        """Integrate ``tt`` seconds of the phase on block ``b`` (speed, distance, simulated
        time, the block's speed record); the distance run. A brake that ends the block lands
        on the exit speed exactly."""
        d = b.remaining
        v_old = self._v
        s = min(max(v_old * tt + 0.5 * acc * tt * tt, 0.0), d)
        v_new = max(v_old + acc * tt, 0.0)
        if tt >= duration and acc < 0 and (not self._hold) and duration > 0:
            v_new = v_exit if d - s < 1e-7 else v_new
        self._v = v_new
        if tt > 0:
            b.chunks.append((b.elapsed, b.done, tt, v_old, acc, v_new))
        b.done += s
        b.elapsed += tt
        self.sim_time += tt
        return s

    def _complete_block(self, b: Block) -> None:
        b.done = b.length
        self._pos = b.end.copy()
        self._trace_block(b, b.start, b.end, complete=True)
        self._planner.popleft()
        if not self._planner:
            self._v = 0.0

    def _after_step(self, b: Block, vn: float, duration: float, s: float) -> None:
        """A hold that has stopped completes (and ends a jog cancel); an empty planner is
        idle."""
        if self._hold and self._v <= 1e-9:
            self._v = 0.0
            self._hold_complete = True
            self._finish_jog_cancel_if_stopped()
        if not self._planner and not self._hold:
            if self._state in ("Run", "Jog"):
                self._state = "Idle"
            self._v = 0.0
        if duration <= 0.0 and s <= 0.0 and self._v <= 0.0 and not self._hold:
            # Degenerate phase (zero speed, zero time): nudge to avoid stalling.
            self._v = min(vn, b.accel * 1e-3)

    def _start_jog_cancel(self) -> None:
        self._jog_cancel = True
        self._hold = True
        self._hold_complete = self._v <= 0.0
        self._finish_jog_cancel_if_stopped()

    def _finish_jog_cancel_if_stopped(self) -> None:
        if self._jog_cancel and self._v <= 0.0:
            self._record_partial()
            self._planner.clear()
            # "automatically flushing any remaining jog commands": also a jog line that waits
            # for planner room.
            self._pending = deque(a for a in self._pending if not (a[0] == "move" and a[1].jog))
            self._jog_cancel = self._hold = self._hold_complete = False
            self._gc.position = self._pos.copy()
            self._state = "Idle"

    # ------------------------------------------------------------------ alarms
    def _alarm(self, code: int) -> None:
        self._stop_motion()
        self._pending.clear()
        self._state = "Alarm"
        self._emit(f"ALARM:{code}")
        if code in C.CRITICAL_ALARMS:
            self._emit(C.MSG_RESET_TO_CONTINUE)
            self._critical = True

    def _soft_limit_alarm(self) -> None:
        """Soft limit: stop (position kept), ALARM:2 and lock until reset (limits_soft_check)."""
        self._stop_motion()
        remaining = [a for a in self._pending if a[0] == "softlimit_ok"]
        self._pending.clear()
        self._pending.extend(remaining)
        self._state = "Alarm"
        self._emit(f"ALARM:{C.A_SOFT_LIMIT}")
        self._emit(C.MSG_RESET_TO_CONTINUE)
        self._critical = True

    def _stop_motion(self) -> None:
        self._record_partial()
        self._planner.clear()
        self._v = 0.0
        self._hold = self._hold_complete = self._jog_cancel = False
        self._dwell_until = None
        self._homing_until = None
        self._gc.position = self._pos.copy()

    # ------------------------------------------------------------------ trace
    def _record_partial(self) -> None:
        if self._planner and self._planner[0].done > 1e-9:
            b = self._planner[0]
            self._trace_block(b, b.start, self._pos.copy(), complete=False)

    def _trace_block(self, b: Block, p0: np.ndarray, p1: np.ndarray, complete: bool) -> None:
        """Trace the block from ``p0`` (or where it was last traced) to ``p1``: one segment,
        or under M4 one per step segment whose laser power differs from the one before."""
        if b.traced_to is not None:  # the part before a mid-block power change is traced
            p0 = b.traced_to
        feed = b.nominal(self._feed_ovr, self._rapid_ovr) * 60.0
        z0, z1 = float(p0[2]), float(p1[2])
        if self._spindle_stop or not is_dynamic(b, bool(self.settings[32])):
            power = 0.0 if self._spindle_stop else self._block_power(b)
            pieces = [(p0, p1, power)]
        else:
            pieces = power_pieces(b, p0, p1, self._spindle_ovr, self.settings)
        b.chunks.clear()
        for q0, q1, power in pieces:
            self.trace.append(Segment(float(q0[0]), float(q0[1]), float(q1[0]), float(q1[1]),
                                      feed, power, b.feed is None, z0, z1, b.jog, complete))

    def _split_trace(self) -> None:
        """Trace the running block up to here: the power is about to change mid-block (the
        spindle stop override during a feed hold turns the laser off while it brakes)."""
        if self._planner and self._planner[0].done > 1e-9:
            b = self._planner[0]
            self._trace_block(b, b.start, self._pos.copy(), complete=False)
            b.traced_to = self._pos.copy()

    def _block_power(self, b: Block) -> float:
        """The constant power along a block (M3, a rapid, or outside laser mode)."""
        if self.settings[32]:
            return segment_value(b, b.nominal(self._feed_ovr, self._rapid_ovr),
                                 self._spindle_ovr, self.settings)
        return self._spindle_rpm()
