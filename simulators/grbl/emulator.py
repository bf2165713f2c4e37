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

import numpy as np

import simulators.grbl.codes as C
from simulators.grbl.faults import Faults
from simulators.grbl.parser_state import GrblError, ParserState
from simulators.grbl.system import SystemCommands
from simulators.grbl.words import preparse

__all__ = ["Faults", "GrblEmulator"]

log = logging.getLogger("simulators.grbl")


class GrblEmulator(SystemCommands):
    """A GRBL 1.1h controller with its machine, in simulated time.

    Inspect `trace` (executed `Segment`s), `lines_received`, `lines_executed` (lines answered
    `ok`), `state`, `mpos`, `wpos`, `settings`; drive faults with `inject_reset()`,
    `disconnect()`, `power_cut()`. With `realtime=False` no thread runs and simulated time
    moves only through `advance(dt)` (deterministic tests).

    The machine is built in layers, each using only those below it: `state.MachineState`
    (memory, output, status report), `executor.Executor` (parsed lines, planner, motion,
    alarms), `system.SystemCommands` (`$` commands, settings, real-time bytes, homing,
    reset); this class adds the serial receive line, GRBL's main loop and the clock.
    """

    def __init__(self, *, speed: float = 1.0, faults: Faults | None = None,
                 force_origin: bool = False, name: str | None = None,
                 settings: dict[int, float] | None = None, realtime: bool = True,
                 paced: bool = True):
        super().__init__(speed=speed, faults=faults, force_origin=force_origin,
                         settings=settings)
        self.name = name
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
        if self._line_fault(self.lines_received):
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
                self._queue_line(self._gcode(line))
        except GrblError as exc:
            self._emit(f"error:{exc.code}")

    def _line_fault(self, n: int) -> bool:
        """Inject the faults set for received line ``n``; True if the line is lost to them."""
        f = self.faults
        if n in f.power_cut_at:
            self.power_cut()
            return True
        if n in f.reset_at:
            self._soft_reset()
            return True
        if n in f.disconnect_at:
            self.disconnect()
        if n in f.error_at:
            self._emit(f"error:{f.error_at[n]}")
            return True
        if n in f.alarm_at:
            self._alarm(f.alarm_at[n])
            return True
        return False

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
