"""The emulated controller's memory and what reads it without changing the machine.

EEPROM (settings, G-code parameters, start-up lines, build info) survives resets and power
cuts; RAM (receive buffer, planner, the line waiting for it, parser state, overrides, the
spindle's output) is cleared by `MachineState._clear_ram`. A status report (`?`) and the
``FS:`` values are read from here; the executor (`executor.py`) and the system commands
(`system.py`) change it.
"""

from __future__ import annotations

import threading
from collections import deque

import numpy as np

import simulators.grbl.codes as C
from simulators.grbl.faults import Faults
from simulators.grbl.laser import segment_value, spindle_value
from simulators.grbl.motion import Block, Segment, speed_ahead
from simulators.grbl.parser_state import MM_PER_INCH, Params, ParserState, fmt, work_offset

_MOVING = ("Run", "Jog", "Hold")


class MachineState:
    """The machine's state, its output line and its status report (a base of `GrblEmulator`).

    Every method expects the caller to hold ``self._cond``'s lock.
    """

    def __init__(self, *, speed: float, faults: Faults | None, force_origin: bool,
                 settings: dict[int, float] | None):
        if not speed > 0:
            raise ValueError(f"speed must be > 0, got {speed!r}")
        self.speed = float(speed)  # simulated seconds per wall second (`$I` reports it)
        self.faults = faults or Faults()
        self.force_origin = force_origin  # build option HOMING_FORCE_SET_ORIGIN ('Z' in OPT)
        self._cond = threading.Condition(threading.RLock())
        # Non-volatile (EEPROM) data survives resets and power cuts.
        self.settings: dict[int, float] = dict(C.DEFAULT_SETTINGS)
        for key, value in (settings or {}).items():  # as if stored in EEPROM before power-up
            if key not in self.settings:
                raise ValueError(f"${key} is not a GRBL 1.1 setting")
            self.settings[key] = int(value) if key in C.INT_SETTINGS else float(value)
        self.params = Params()
        self.startup_lines = [""] * C.N_STARTUP_LINES
        self.build_info = ""
        # Observer records (not machine state).
        self.trace: list[Segment] = []
        self.lines_received = 0
        self.lines_executed = 0
        self.bytes_received = 0
        self.bytes_lost = 0
        self.bytes_sent = 0
        self.oks_sent = 0
        self.sim_time = 0.0
        # Connection.
        self._out = bytearray()
        self.connected = True
        self.generation = 0
        self._pos = np.zeros(3)
        self._state = "Idle"

    def _clear_ram(self) -> None:
        """What GRBL's main loop initialises after power-up or a soft reset (not the
        position, not the machine state)."""
        self._rx = bytearray()
        self._line = bytearray()
        self._planner: deque[Block] = deque()
        self._pending: deque[tuple] = deque()
        self._v = 0.0
        self._hold = False
        self._hold_complete = False
        self._jog_cancel = False
        self._critical = False
        self._dwell_until: float | None = None
        self._homing_until: float | None = None
        self._home_target: np.ndarray | None = None
        self._feed_ovr = 100.0
        self._rapid_ovr = 100.0
        self._spindle_ovr = 100.0
        self._spindle_stop = False
        self._spindle_out = ("M5", 0.0)
        self._flood = False
        self._gc = ParserState(position=self._pos.copy())
        self._wco_counter = 0
        self._ovr_counter = 0

    # ------------------------------------------------------------------ output
    def _emit(self, text: str) -> None:
        if not self.connected:
            return
        data = text.encode("latin-1") + b"\r\n"
        f = self.faults
        if text == "ok":
            self.oks_sent += 1
            if self.oks_sent in f.drop_ok_at:
                return
            data *= 2 if self.oks_sent in f.dup_ok_at else 1
        first = self.bytes_sent + 1
        self.bytes_sent += len(data)
        self._out += f.corrupt(data, first, f.out_drop_at, f.out_flip_at, f.out_dup_at,
                               f.out_insert_at)
        self._cond.notify_all()

    def _ok(self) -> None:
        self._emit("ok")
        self.lines_executed += 1

    # ------------------------------------------------------------------ status report
    def _state_text(self) -> str:
        if self._state == "Hold":
            return "Hold:0" if self._hold_complete else "Hold:1"
        return self._state

    def _wco(self) -> np.ndarray:
        return work_offset(self._gc, self.params)

    def _status_report(self) -> str:
        inches = bool(self.settings[13])
        scale, dec = (1.0 / MM_PER_INCH, 4) if inches else (1.0, 3)

        def axes(v: np.ndarray) -> str:
            return ",".join(fmt(x * scale, dec) for x in v)

        mask = int(self.settings[10])
        wco = self._wco()
        fields = [self._state_text()]
        fields.append(f"MPos:{axes(self._pos)}" if mask & 1 else f"WPos:{axes(self._pos - wco)}")
        if mask & 2:
            fields.append(f"Bf:{C.PLANNER_BLOCKS - len(self._planner)},"
                          f"{C.RX_BUFFER_SIZE - len(self._rx)}")
        speed, power = self._prepared()
        fields.append(f"FS:{fmt(speed * 60.0 * scale, 1 if inches else 0)},{fmt(power, 0)}")
        busy = self._state in ("Run", "Hold", "Jog", "Home")
        if self._wco_counter > 0:
            self._wco_counter -= 1
        else:
            self._wco_counter = (C.REPORT_WCO_REFRESH_BUSY if busy
                                 else C.REPORT_WCO_REFRESH_IDLE) - 1
            if self._ovr_counter == 0:
                self._ovr_counter = 1
            fields.append(f"WCO:{axes(wco)}")
        if self._ovr_counter > 0:
            self._ovr_counter -= 1
        else:
            self._ovr_counter = (C.REPORT_OVR_REFRESH_BUSY if busy
                                 else C.REPORT_OVR_REFRESH_IDLE) - 1
            fields += self._override_fields()
        return "<" + "|".join(fields) + ">"

    def _override_fields(self) -> list[str]:
        """``Ov:`` and, when anything is on, ``A:`` (S: spindle CW, C: CCW, F: flood)."""
        fields = [f"Ov:{self._feed_ovr:.0f},{self._rapid_ovr:.0f},{self._spindle_ovr:.0f}"]
        acc = {"M3": "S", "M4": "C"}.get(self._spindle_out[0], "")
        if self._flood:
            acc += "F"
        if acc:
            fields.append(f"A:{acc}")
        return fields

    def _spindle_rpm(self) -> float:
        state, s = self._spindle_out
        if state == "M5" or self._spindle_stop or self._state in ("Alarm", "Check"):
            return 0.0
        return spindle_value(s, self._spindle_ovr, self.settings)

    def _prepared(self) -> tuple[float, float]:
        """(speed mm/s, laser or spindle value) of the step segment prepared last, which is
        what ``FS:`` reports: up to SEGMENTS_AHEAD segments ahead of the head."""
        moving = self._planner and self._state in _MOVING
        if not moving:
            return (self._v if self._state in _MOVING else 0.0), self._spindle_rpm()
        lead = (C.SEGMENTS_AHEAD + 1) * C.DT_SEGMENT - self.sim_time % C.DT_SEGMENT
        v, k = speed_ahead(list(self._planner), self._v, lead, self._feed_ovr,
                           self._rapid_ovr, self._hold)
        b = self._planner[k]
        if self._spindle_stop or not self.settings[32]:
            return v, self._spindle_rpm()
        return v, segment_value(b, v, self._spindle_ovr, self.settings)
