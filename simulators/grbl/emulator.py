"""The emulated GRBL 1.1h machine: serial RX buffer, protocol, settings, planner and motion.

Behaviour follows the GRBL 1.1 documentation (gnea/grbl wiki and doc/markdown): bytes beyond the
128-byte receive buffer are lost, real-time bytes are picked off on arrival, a line is answered
`ok` once it is parsed into the 15-block planner (not when it has run), motion takes simulated
time (sim seconds = wall seconds x `speed`), and alarms lock the parser as on the controller.
A background thread advances simulated time; every public method takes the machine's lock.

What a sender sees, as GRBL 1.1h does it (checked against gnea/grbl's source):

* status reports: ``FS:`` is the speed and the spindle/laser value of the step segment
  prepared last, 40-50 ms ahead of the head (``st_get_realtime_rate``,
  ``sys.spindle_speed``); both agree with each other, MPos is the head's own. ``WCO:`` comes
  every 30th report while busy (10th idle) and at once after a change; ``Ov:`` every 20th
  (10th idle) and at once after an override or spindle change; ``Bf:`` with ``$10`` bit 2;
* laser mode (``$32=1``): the beam is on only in G1/G2/G3 motion; M4 scales S by speed /
  programmed F for every 10 ms step segment, from the speed at the segment's end (so the
  segment that brakes to a stop runs dark); M3 holds S; spindle state changes sync the
  planner, a new S between moves does not; at rest the programmed S is reported, beam off;
* the planner: 15 blocks, junction deviation ``$11`` at every corner, acceleration and
  rates per axis (``$110``-``$122``), the last block planned to stop, overrides; feed hold
  brakes at the acceleration and a resume continues the block; soft limits, homing,
  alarms, check mode, the 128-byte receive buffer and the real-time bytes.

Not modelled: the segment buffer's own timing (a feed hold brakes at once, not after the
segments already prepared), step quantisation and AMASS, ``$12`` arc tolerance beyond
splitting arcs into segments, the spindle PWM's 8-bit resolution, probing, the safety
door, parking, sleep's power-down, tool length offsets beyond G43.1, and the EEPROM's
write time. The trace records what ran: one segment per block, or under M4 one per run of
step segments of equal power.
"""

from __future__ import annotations

import copy
import logging
import threading
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

import simulators.grbl.codes as C
from simulators.grbl.laser import is_dynamic, power_pieces, segment_value, spindle_value
from simulators.grbl.motion import (
    Block,
    Segment,
    exit_speed,
    make_block,
    phase,
    speed_ahead,
)
from simulators.grbl.parser import (
    MM_PER_INCH,
    GrblError,
    Params,
    ParserState,
    fmt,
    gc_report,
    parse_block,
    preparse,
)

log = logging.getLogger("simulators.grbl")


@dataclass
class Faults:
    """Faults to inject. Lines count from 1 over every line the machine receives (including `$`
    commands and empty lines); bytes count from 1 over every byte written to it."""

    error_at: dict[int, int] = field(default_factory=dict)  # line -> error code
    alarm_at: dict[int, int] = field(default_factory=dict)  # line -> alarm code
    drop_byte_at: set[int] = field(default_factory=set)
    flip_byte_at: set[int] = field(default_factory=set)  # XOR 0x01 (e.g. '1' <-> '0')
    reset_at: set[int] = field(default_factory=set)
    disconnect_at: set[int] = field(default_factory=set)
    power_cut_at: set[int] = field(default_factory=set)
    dup_byte_at: set[int] = field(default_factory=set)  # the byte arrives twice
    insert_at: dict[int, bytes] = field(default_factory=dict)  # a burst before byte N
    # The controller's transmit line (GRBL -> host): bytes count from 1 over every byte it
    # sends; and its answers: `ok`s count from 1 over every `ok` it sends.
    out_drop_at: set[int] = field(default_factory=set)
    out_flip_at: set[int] = field(default_factory=set)
    out_dup_at: set[int] = field(default_factory=set)
    out_insert_at: dict[int, bytes] = field(default_factory=dict)
    drop_ok_at: set[int] = field(default_factory=set)
    dup_ok_at: set[int] = field(default_factory=set)

    def corrupt(self, data: bytes, first: int, drop: set[int], flip: set[int],
                dup: set[int], insert: dict[int, bytes]) -> bytes:
        """``data`` as a faulty line delivers it, its first byte being number ``first``.
        WHY one routine: both directions of the wire fail the same ways."""
        last = first + len(data)
        if not any(first <= n < last for f in (drop, flip, dup, insert) for n in f):
            return data
        out = bytearray()
        for n, byte in enumerate(data, first):
            out += insert.get(n, b"")
            if n in drop:
                continue
            byte ^= 0x01 if n in flip else 0
            out += bytes([byte, byte]) if n in dup else bytes([byte])
        return bytes(out)


class GrblEmulator:
    """A GRBL 1.1h controller with its machine, in simulated time.

    Inspect `trace` (executed `Segment`s), `lines_received`, `lines_executed` (lines answered
    `ok`), `state`, `mpos`, `wpos`, `settings`; drive faults with `inject_reset()`,
    `disconnect()`, `power_cut()`. With `realtime=False` no thread runs and simulated time
    moves only through `advance(dt)` (deterministic tests).
    """

    def __init__(self, *, speed: float = 1.0, faults: Faults | None = None,
                 force_origin: bool = False, name: str | None = None,
                 settings: dict[int, float] | None = None, realtime: bool = True,
                 paced: bool = True):
        if not speed > 0:
            raise ValueError(f"speed must be > 0, got {speed!r}")
        self.speed = float(speed)
        self.name = name
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
        with self._cond:
            self._power_on()
        self._stopped = False
        self.realtime = realtime
        self.paced = paced  # see HOST_STEP
        self._wall = time.monotonic()  # the wall instant simulated time was last brought to
        self._host_wall = -1e9  # when the host last wrote
        if realtime:  # else the caller drives simulated time with advance(dt)
            self._thread = threading.Thread(target=self._run, daemon=True,
                                            name=f"grblsim-{name or id(self)}")
            self._thread.start()

    # ------------------------------------------------------------------ public API
    @property
    def state(self) -> str:
        with self._cond:
            return self._state_text()

    @property
    def mpos(self) -> np.ndarray:
        with self._cond:
            return self._pos.copy()

    @property
    def wpos(self) -> np.ndarray:
        with self._cond:
            return self._pos - self._wco()

    @property
    def parser_state(self) -> ParserState:
        with self._cond:
            return copy.deepcopy(self._gc)

    @property
    def planner_blocks(self) -> int:
        with self._cond:
            return len(self._planner)

    @property
    def rx_used(self) -> int:
        with self._cond:
            return len(self._rx)

    def receive(self, data: bytes) -> None:
        """Bytes arriving on the controller's serial RX line."""
        with self._cond:
            self._host_wall = time.monotonic()
            # a real GRBL moves continuously: answer `?` for this instant
            self._catch_up(self.HOST_STEP / self.speed if self.paced else self.THREAD_STEP)
            busy_from = time.monotonic()
            self._receive(data)
            # The emulator's own parsing is not the machine's time: GRBL parses a line in
            # microseconds on its own CPU, while this Python parser takes the host's CPU
            # for a millisecond, which at speed 50 would be 50 ms of unseen motion.
            self._wall += time.monotonic() - busy_from

    def _receive(self, data: bytes) -> None:
        f = self.faults
        first = self.bytes_received + 1
        self.bytes_received += len(data)
        self.bytes_lost += sum(first <= n < first + len(data) for n in f.drop_byte_at)
        for byte in f.corrupt(bytes(data), first, f.drop_byte_at, f.flip_byte_at,
                              f.dup_byte_at, f.insert_at):
            if self._realtime(byte):
                continue
            if byte > 0x7F:
                continue  # unknown extended-ASCII bytes are thrown away
            if len(self._rx) >= C.RX_BUFFER_SIZE:
                self._service()  # GRBL pulls a line out if it is free to
            if len(self._rx) >= C.RX_BUFFER_SIZE:
                self.bytes_lost += 1  # "Write data to buffer unless it is full."
                continue
            self._rx.append(byte)
            if byte in (0x0A, 0x0D):
                self._service()  # GRBL parses a line as soon as its EOL arrives
        self._service()
        self._cond.notify_all()

    def take_output(self, size: int | None = None) -> bytes:
        with self._cond:
            n = len(self._out) if size is None else min(size, len(self._out))
            data = bytes(self._out[:n])
            del self._out[:n]
            return data

    def output_waiting(self) -> int:
        with self._cond:
            return len(self._out)

    def wait_output(self, timeout: float | None) -> None:
        with self._cond:
            if not self._out:
                self._cond.wait(timeout)

    def wake_readers(self) -> None:
        with self._cond:
            self._cond.notify_all()

    def inject_reset(self) -> None:
        """As if 0x18 arrived (or the reset pin was pressed)."""
        with self._cond:
            self._soft_reset()
            self._cond.notify_all()

    def disconnect(self) -> None:
        """The port disappears (USB unplugged); the machine keeps running what it holds."""
        with self._cond:
            self.connected = False
            self.generation += 1
            self._out.clear()
            self._cond.notify_all()

    def connect(self) -> int:
        """A host opens the port again; returns the connection generation."""
        with self._cond:
            self.connected = True
            self.generation += 1
            self._out.clear()
            return self.generation

    def power_cut(self) -> None:
        """Power lost and restored: motion stops dead, position and RAM state are lost,
        EEPROM settings and offsets are kept, and GRBL boots again with its banner."""
        with self._cond:
            self._stop_motion()
            self._power_on()
            self._cond.notify_all()

    def wait_idle(self, timeout: float = 10.0) -> bool:
        """Block until nothing is queued or moving (wall-clock timeout); True if idle."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while time.monotonic() < deadline:
                if not self._planner and not self._pending and not self._rx and (
                    self._state in ("Idle", "Alarm", "Check")
                ):
                    return True
                self._cond.wait(0.005)
        return False

    def close(self) -> None:
        self._stopped = True
        self.wake_readers()

    # ------------------------------------------------------------------ boot / reset
    def _power_on(self) -> None:
        self._pos = np.zeros(3)
        self._state = "Idle"
        if self.settings[22]:
            self._state = "Alarm"  # homing enabled: position unknown at power-up
        self._reinit()

    def _reinit(self) -> None:
        """GRBL's main-loop initialisation after power-up or soft reset."""
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
        self._emit("")
        self._emit(C.BANNER)
        if self._state in ("Alarm", "Sleep"):
            self._state = "Alarm"
            self._emit(C.MSG_UNLOCK)
        else:
            self._state = "Idle"
            self._run_startup_lines()

    def _run_startup_lines(self) -> None:
        for line in self.startup_lines:
            if line:
                try:
                    actions = self._gcode(line)
                except GrblError as exc:
                    self._emit(f">{line}:error:{exc.code}")
                else:
                    self._pending.extend(actions)
                    self._pending.append(("emit", f">{line}:ok", False))

    def _soft_reset(self) -> None:
        moving = (self._state in ("Run", "Jog", "Home")
                  or (self._state == "Hold" and not self._hold_complete))
        ok_first = any(a[0] == "softlimit_ok" for a in self._pending)
        if moving:
            code = C.A_HOMING_FAIL_RESET if self._state == "Home" else C.A_ABORT_CYCLE
            self._stop_motion()
            self._state = "Alarm"
            self._emit(f"ALARM:{code}")
        else:
            self._stop_motion()
        if self._state in ("Check", "Hold", "Run", "Jog"):
            self._state = "Idle"
        if ok_first:
            # The line that hit the soft limit returns from the parser after the reset and
            # reports its `ok` before GRBL re-initialises (protocol_main_loop order).
            self._emit("ok")
        self._reinit()

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

    # ------------------------------------------------------------------ real-time bytes
    def _realtime(self, byte: int) -> bool:
        """Handle a real-time command byte; True if it was one (never enters the buffer)."""
        if byte == C.RT_RESET:
            self._soft_reset()
        elif byte == C.RT_STATUS:
            if not self._critical and self._state != "Home":
                self._emit(self._status_report())
        elif byte == C.RT_FEED_HOLD:
            if self._state == "Jog":
                self._start_jog_cancel()
            elif self._state in ("Idle", "Run"):
                self._state = "Hold"
                self._hold = True
                self._hold_complete = self._v <= 0.0
        elif byte == C.RT_CYCLE_START:
            if self._state == "Hold" and self._hold_complete:
                self._resume()
        elif byte == C.RT_JOG_CANCEL:
            if self._state == "Jog" and not self._jog_cancel:
                self._start_jog_cancel()
        elif byte in _FEED_OVR:
            self._feed_ovr = _FEED_OVR[byte](self._feed_ovr)
            self._ovr_counter = 0
        elif byte in _RAPID_OVR:
            self._rapid_ovr = _RAPID_OVR[byte]
            self._ovr_counter = 0
        elif byte in _SPINDLE_OVR:
            self._spindle_ovr = _SPINDLE_OVR[byte](self._spindle_ovr)
            self._ovr_counter = 0
        elif byte == C.RT_SPINDLE_OVR_STOP:
            if self._state == "Hold":
                self._split_trace()  # the beam changes here, mid-block
                self._spindle_stop = not self._spindle_stop
        elif byte == C.RT_COOLANT_FLOOD_OVR_TOGGLE:
            if self._state in ("Idle", "Run", "Hold"):
                self._flood = not self._flood
                self._gc.flood = self._flood
                self._ovr_counter = 0
        elif byte in (C.RT_SAFETY_DOOR, C.RT_COOLANT_MIST_OVR_TOGGLE):
            pass  # no door switch and no M7 in this build: ignored
        else:
            return False
        return True

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

    def _resume(self) -> None:
        self._hold = False
        self._hold_complete = False
        self._spindle_stop = False
        self._gc.program = ""
        self._state = "Run" if self._planner else "Idle"

    # ------------------------------------------------------------------ status report
    def _state_text(self) -> str:
        if self._state == "Hold":
            return "Hold:0" if self._hold_complete else "Hold:1"
        return self._state

    def _wco(self) -> np.ndarray:
        off = self.params.coord[self._gc.coord_index] + self._gc.g92
        off = off.copy()
        off[2] += self._gc.tlo
        return off

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
            fields.append(f"Ov:{self._feed_ovr:.0f},{self._rapid_ovr:.0f},"
                          f"{self._spindle_ovr:.0f}")
            acc = ""
            sp = self._spindle_out[0]
            if sp == "M3":
                acc += "S"
            elif sp == "M4":
                acc += "C"
            if self._flood:
                acc += "F"
            if acc:
                fields.append(f"A:{acc}")
        return "<" + "|".join(fields) + ">"

    def _spindle_rpm(self) -> float:
        state, s = self._spindle_out
        if state == "M5" or self._spindle_stop or self._state in ("Alarm", "Check"):
            return 0.0
        return spindle_value(s, self._spindle_ovr, self.settings)

    # ------------------------------------------------------------------ line processing
    def _take_line(self) -> bytes | None:
        """Move received bytes into the line being read (GRBL reads characters out of the RX
        ring as they come whenever its main loop is free); return the line at its EOL."""
        for i, b in enumerate(self._rx):
            if b in (0x0A, 0x0D):
                line = bytes(self._line + self._rx[:i])
                del self._rx[: i + 1]
                self._line.clear()
                return line
        self._line += self._rx
        self._rx.clear()
        return None

    def _service(self) -> None:
        """GRBL's main loop: finish the blocked line, then read and execute further lines."""
        for _ in range(10_000):
            if self._critical or self._state in ("Sleep", "Home"):
                return
            if not self._run_pending():
                return
            raw = self._take_line()
            if raw is None:
                return
            self._handle_line(raw)
        log.warning("grblsim: service loop limit reached")

    def _handle_line(self, raw: bytes) -> None:
        self.lines_received += 1
        n = self.lines_received
        f = self.faults
        if n in f.power_cut_at:
            self.power_cut()
            return
        if n in f.reset_at:
            self._soft_reset()
            return
        if n in f.disconnect_at:
            self.disconnect()
        if n in f.error_at:
            self._emit(f"error:{f.error_at[n]}")
            return
        if n in f.alarm_at:
            self._alarm(f.alarm_at[n])
            return
        line, overflow = preparse(raw)
        try:
            if overflow:
                raise GrblError(C.E_OVERFLOW)
            if not line:
                self._ok()
            elif line[0] == "$":
                self._system(line)
            elif self._state in ("Alarm", "Jog"):
                raise GrblError(C.E_SYSTEM_GC_LOCK)
            else:
                self._pending.extend(self._gcode(line))
                self._pending.append(("emit", "ok", True))
                self._run_pending()
        except GrblError as exc:
            self._emit(f"error:{exc.code}")

    def _ok(self) -> None:
        self._emit("ok")
        self.lines_executed += 1

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

    def _run_pending(self) -> bool:
        """Execute queued actions of the current line; False while blocked (planner full,
        waiting for a sync or a dwell)."""
        while self._pending:
            act = self._pending[0]
            kind = act[0]
            if kind == "move":
                if self._state == "Check":
                    pass
                elif len(self._planner) >= C.PLANNER_BLOCKS:
                    return False
                else:
                    self._plan(act[1])
            elif kind == "sync":
                if self._planner and self._state != "Check":
                    return False
            elif kind == "dwell":
                if self._state != "Check":
                    if self._planner:
                        return False
                    if self._dwell_until is None:
                        self._dwell_until = self.sim_time + float(act[1])
                    if self.sim_time < self._dwell_until - 1e-12:
                        return False
                    self._dwell_until = None
            elif kind == "spindle":
                _, state, speed, state_changed, no_motion = act
                laser = bool(self.settings[32])
                needs_sync = state_changed or not laser or (state == "M3" and no_motion)
                if self._state != "Check":
                    if needs_sync and self._planner:
                        return False
                    if not laser or state_changed or no_motion:
                        self._spindle_out = (state, speed)
                        self._ovr_counter = 0
            elif kind == "coolant":
                if self._state != "Check":
                    if self._planner:
                        return False
                    self._flood = act[1]
                    self._ovr_counter = 0
            elif kind == "wco":
                self._wco_counter = 0
            elif kind == "store_params":
                if self._planner and self._state != "Check":
                    return False  # EEPROM writes force a sync
            elif kind == "pause":
                if self._state != "Check":
                    if self._planner:
                        return False
                    self._state = "Hold"
                    self._hold = True
                    self._hold_complete = True
            elif kind == "end":
                if self._planner and self._state != "Check":
                    return False
                self._program_end()
            elif kind == "softlimit":
                if self._state == "Run" and self._v > 0:
                    self._hold = True  # come to a controlled stop first
                    return False
                self._soft_limit_alarm()
                return False
            elif kind == "softlimit_ok":
                return False  # answered after the reset (see _soft_reset)
            elif kind == "emit":
                self._emit(act[1])
                if act[2]:
                    self.lines_executed += 1
            self._pending.popleft()
        return True

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

    def _plan(self, move) -> None:
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

    def _prepared(self) -> tuple[float, float]:
        """(speed mm/s, laser or spindle value) of the step segment prepared last, which is
        what ``FS:`` reports: up to SEGMENTS_AHEAD segments ahead of the head."""
        moving = self._planner and self._state in ("Run", "Jog", "Hold")
        if not moving:
            return (self._v if self._state in ("Run", "Jog", "Hold") else 0.0), \
                self._spindle_rpm()
        lead = (C.SEGMENTS_AHEAD + 1) * C.DT_SEGMENT - self.sim_time % C.DT_SEGMENT
        v, k = speed_ahead(list(self._planner), self._v, lead, self._feed_ovr,
                           self._rapid_ovr, self._hold)
        b = self._planner[k]
        if self._spindle_stop or not self.settings[32]:
            return v, self._spindle_rpm()
        return v, segment_value(b, v, self._spindle_ovr, self.settings)

    # ------------------------------------------------------------------ system commands
    def _system(self, line: str) -> None:
        state = self._state
        if line == "$":
            self._emit(C.HELP)
            return self._ok()
        cmd = line[1]
        if cmd == "J":
            if state not in ("Idle", "Jog"):
                raise GrblError(C.E_IDLE_ERROR)
            if len(line) < 3 or line[2] != "=":
                raise GrblError(C.E_INVALID_STATEMENT)
            self._pending.extend(self._gcode(line[3:], jog=True))
            self._pending.append(("emit", "ok", True))
            self._run_pending()
            return None
        if cmd in "$GCX":
            if len(line) != 2:
                raise GrblError(C.E_INVALID_STATEMENT)
            if cmd == "$":
                if state in ("Run", "Hold"):
                    raise GrblError(C.E_IDLE_ERROR)
                for key, value in self.settings.items():
                    self._emit(f"${key}={self._format_setting(key, value)}")
            elif cmd == "G":
                self._emit(gc_report(self._gc))
            elif cmd == "C":
                if state == "Check":
                    self._emit(C.MSG_DISABLED)
                    self._ok()
                    # "When toggled off, Grbl will perform an automatic soft-reset"
                    self._soft_reset()
                    return None
                if state != "Idle":
                    raise GrblError(C.E_IDLE_ERROR)
                self._state = "Check"
                self._emit(C.MSG_ENABLED)
            elif cmd == "X":
                if state == "Alarm":
                    self._emit(C.MSG_UNLOCKED)
                    self._state = "Idle"
            return self._ok()
        if state not in ("Idle", "Alarm"):
            raise GrblError(C.E_IDLE_ERROR)
        if cmd == "#":
            if len(line) != 2:
                raise GrblError(C.E_INVALID_STATEMENT)
            self._report_params()
            return self._ok()
        if cmd == "H":
            if not self.settings[22]:
                raise GrblError(C.E_SETTING_DISABLED)
            self._start_homing()
            return None
        if cmd == "S":
            if line != "$SLP":
                raise GrblError(C.E_INVALID_STATEMENT)
            self._ok()
            self._state = "Sleep"
            self._emit(C.MSG_SLEEPING)
            return None
        if cmd == "I":
            if line == "$I":
                opts = "V" + ("Z" if self.force_origin else "")
                # the build info (what `$I=` stored) ends with the simulator's time scale,
                # which a sender on a pty can learn no other way (gcode.grbl.time_scale_of)
                info = " ".join(filter(None, (self.build_info, f"grblsim speed={self.speed:g}")))
                self._emit(f"[VER:{C.VERSION}.{C.BUILD_DATE}:{info}]")
                self._emit(f"[OPT:{opts},{C.PLANNER_BLOCKS},{C.RX_BUFFER_SIZE}]")
            elif line.startswith("$I="):
                self.build_info = line[3:]
            else:
                raise GrblError(C.E_INVALID_STATEMENT)
            return self._ok()
        if cmd == "R":
            what = {"$RST=$": "$", "$RST=#": "#", "$RST=*": "*"}.get(line)
            if what is None:
                raise GrblError(C.E_INVALID_STATEMENT)
            if what in "$*":
                self.settings = dict(C.DEFAULT_SETTINGS)
            if what in "#*":
                self.params = Params()
            if what == "*":
                self.startup_lines = [""] * C.N_STARTUP_LINES
                self.build_info = ""
            self._emit(C.MSG_RESTORING)
            self._ok()
            self._soft_reset()
            return None
        if cmd == "N":
            if line == "$N":
                for i, text in enumerate(self.startup_lines):
                    self._emit(f"$N{i}={text}")
                return self._ok()
            rest = line[2:]
            idx_text, eq, text = rest.partition("=")
            if not eq or not idx_text.isdigit():
                raise GrblError(C.E_INVALID_STATEMENT)
            idx = int(idx_text)
            if idx >= C.N_STARTUP_LINES:
                raise GrblError(C.E_INVALID_STATEMENT)
            if text:
                self._pending.extend(self._gcode(text))  # checked (and run) before storing
            self.startup_lines[idx] = text
            self._pending.append(("emit", "ok", True))
            self._run_pending()
            return None
        # $x=val
        key_text, eq, value_text = line[1:].partition("=")
        try:
            key = float(key_text)
        except ValueError:
            raise GrblError(C.E_BAD_NUMBER_FORMAT) from None
        if not eq:
            raise GrblError(C.E_INVALID_STATEMENT)
        try:
            value = float(value_text)
        except ValueError:
            raise GrblError(C.E_BAD_NUMBER_FORMAT) from None
        self._store_setting(int(key), value)
        self._pending.append(("store_params",))  # EEPROM write forces a sync
        self._pending.append(("emit", "ok", True))
        self._run_pending()
        return None

    def _store_setting(self, key: int, value: float) -> None:
        if value < 0:
            raise GrblError(C.E_NEGATIVE_VALUE)
        if key > 255 or key not in self.settings:
            raise GrblError(C.E_INVALID_STATEMENT)
        if key in (100, 101, 102) and value * self.settings[key + 10] > C.MAX_STEP_RATE_HZ * 60:
            raise GrblError(C.E_MAX_STEP_RATE_EXCEEDED)
        if key in (110, 111, 112) and value * self.settings[key - 10] > C.MAX_STEP_RATE_HZ * 60:
            raise GrblError(C.E_MAX_STEP_RATE_EXCEEDED)
        if key in C.INT_SETTINGS:
            value = int(value)
        if key == 0 and value < 3:
            raise GrblError(C.E_SETTING_STEP_PULSE_MIN)
        if key == 20 and value and not self.settings[22]:
            raise GrblError(C.E_SOFT_LIMIT_ERROR)
        if key == 22 and not value:
            self.settings[20] = 0  # disabling homing disables soft limits
        self.settings[key] = value

    @staticmethod
    def _format_setting(key: int, value: float) -> str:
        if key in C.INT_SETTINGS:
            return str(int(value))
        if key in C.ZERO_DECIMAL_SETTINGS:
            return fmt(value, 0)
        return fmt(value, 3)

    def _report_params(self) -> None:
        def axes(v: np.ndarray) -> str:
            return ",".join(fmt(x, 3) for x in v)

        for i in range(6):
            self._emit(f"[G{54 + i}:{axes(self.params.coord[i])}]")
        self._emit(f"[G28:{axes(self.params.g28)}]")
        self._emit(f"[G30:{axes(self.params.g30)}]")
        self._emit(f"[G92:{axes(self._gc.g92)}]")
        self._emit(f"[TLO:{fmt(self._gc.tlo, 3)}]")
        self._emit("[PRB:0.000,0.000,0.000:0]")

    def _home_position(self) -> np.ndarray:
        travel = np.array([self.settings[130], self.settings[131], self.settings[132]], float)
        pull = float(self.settings[27])
        mask = int(self.settings[23])
        home = np.zeros(3)
        for i in range(3):
            if self.force_origin:
                home[i] = 0.0
            elif mask & (1 << i):
                home[i] = -travel[i] + pull
            else:
                home[i] = -pull
        return home

    def _start_homing(self) -> None:
        self._home_target = self._home_position()
        seek = max(float(self.settings[25]), 1.0) / 60.0
        travel = np.array([self.settings[130], self.settings[131], self.settings[132]], float)
        # Search then locate: bounded by the travel, at the seek rate, plus the pull-off.
        duration = float(np.max(np.minimum(np.abs(self._home_target - self._pos) + 1.0,
                                           travel))) / seek
        duration += 2 * float(self.settings[27]) / max(float(self.settings[24]) / 60.0, 1e-3)
        self._homing_until = self.sim_time + duration
        self._state = "Home"

    def _finish_homing(self) -> None:
        self._pos = self._home_target.copy()
        self._gc.position = self._pos.copy()
        self._homing_until = None
        self._state = "Idle"
        self._ok()
        self._run_startup_lines()

    # ------------------------------------------------------------------ simulated time
    #: Clock steps: a host that keeps writing (at least every HOST_PACE wall seconds) moves
    #: the clock itself, by at most HOST_STEP simulated seconds per write; otherwise the
    #: clock thread does, by at most THREAD_STEP wall seconds per tick (HOST_STEP while the
    #: host is only late, see HOST_GONE). WHY: at speed 50 a
    #: Python host cannot keep a sub-millisecond schedule; pausing the machine between its
    #: writes emulates a host as fast, relative to the machine, as a real one at speed 1
    #: (a USB round trip takes 1-2 ms; 10 ms is 0.5 mm at 3000 mm/min). A stalled process
    #: pauses its machine instead of jumping half a second of motion nobody saw. A host
    #: that cannot know the speed (over a pty) gets an unpaced machine (``paced=False``).
    #: A paced host silent for less than HOST_GONE wall seconds is taken as late (its
    #: process descheduled by a loaded machine), not gone: the clock thread then moves the
    #: machine at most HOST_STEP per tick, as a write would, so that a stall of the host
    #: does not hide centimetres of motion at speed 50 (a real host at speed 1 is late by
    #: milliseconds, not by tenths of the machine's seconds).
    HOST_PACE = 0.02
    HOST_STEP = 0.01
    HOST_GONE = 1.0
    THREAD_STEP = 0.005

    def _run(self) -> None:
        while not self._stopped:
            time.sleep(0.002)
            with self._cond:
                silent = time.monotonic() - self._host_wall
                if not self.paced or silent > self.HOST_GONE:
                    self._catch_up(self.THREAD_STEP)
                elif silent > self.HOST_PACE:
                    self._catch_up(self.HOST_STEP / self.speed)

    def _catch_up(self, max_wall: float) -> None:
        """Bring simulated time to the present wall instant, at most ``max_wall`` of it
        (realtime machines only; see HOST_STEP).

        Called by the clock thread and on every write, so a status report is the machine's
        state at the moment the ``?`` arrived, not at the clock thread's last tick (at speed
        50 one 2 ms tick is 0.1 simulated seconds, 5 mm at 3000 mm/min).
        """
        if not self.realtime:
            return
        now = time.monotonic()
        dt, self._wall = min(now - self._wall, max_wall), now
        if dt > 0:
            self.advance(dt * self.speed)

    def advance(self, dt: float) -> None:
        """Advance simulated time by dt seconds (called by the background thread)."""
        with self._cond:
            end = self.sim_time + dt
            for _ in range(100_000):
                self._service()
                if self._homing_until is not None and self.sim_time >= self._homing_until:
                    self._finish_homing()
                    continue
                if self.sim_time >= end:
                    break
                if self._planner and not (self._hold and self._v <= 0.0) and self._state not in (
                        "Alarm", "Sleep"):
                    self._motion_step(end)
                else:
                    nxt = end
                    for t in (self._dwell_until, self._homing_until):
                        if t is not None:
                            nxt = min(nxt, max(t, self.sim_time))
                    self.sim_time = nxt
            self._cond.notify_all()

    def _motion_step(self, end: float) -> None:
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
        v_old = self._v
        s = min(max(self._v * tt + 0.5 * acc * tt * tt, 0.0), d)
        v_new = max(self._v + acc * tt, 0.0)
        finished_phase = tt >= duration
        if finished_phase and acc < 0 and (not self._hold) and duration > 0:
            v_new = min(ve, vn) if d - s < 1e-7 else v_new
        self._v = v_new
        if tt > 0:
            b.chunks.append((b.elapsed, b.done, tt, v_old, acc, v_new))
        b.done += s
        b.elapsed += tt
        self.sim_time += tt
        if b.remaining <= 1e-7 or (finished_phase and d - s <= 1e-7):
            b.done = b.length
            self._pos = b.end.copy()
            self._trace_block(b, b.start, b.end, complete=True)
            self._planner.popleft()
            if not self._planner:
                self._v = 0.0
        else:
            self._pos = b.start + b.unit * b.done
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


def _clamp_pct(lo: float, hi: float):
    def make(delta: float):
        return lambda v: min(max(v + delta, lo), hi)

    return make


_feed = _clamp_pct(10.0, 200.0)
_FEED_OVR = {
    C.RT_FEED_OVR_RESET: lambda v: 100.0,
    C.RT_FEED_OVR_COARSE_PLUS: _feed(10),
    C.RT_FEED_OVR_COARSE_MINUS: _feed(-10),
    C.RT_FEED_OVR_FINE_PLUS: _feed(1),
    C.RT_FEED_OVR_FINE_MINUS: _feed(-1),
}
_RAPID_OVR = {C.RT_RAPID_OVR_RESET: 100.0, C.RT_RAPID_OVR_MEDIUM: 50.0, C.RT_RAPID_OVR_LOW: 25.0}
_spin = _clamp_pct(10.0, 200.0)
_SPINDLE_OVR = {
    C.RT_SPINDLE_OVR_RESET: lambda v: 100.0,
    C.RT_SPINDLE_OVR_COARSE_PLUS: _spin(10),
    C.RT_SPINDLE_OVR_COARSE_MINUS: _spin(-10),
    C.RT_SPINDLE_OVR_FINE_PLUS: _spin(1),
    C.RT_SPINDLE_OVR_FINE_MINUS: _spin(-1),
}
