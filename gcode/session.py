"""One reader for everything GRBL sends, dispatching each line to the handler of its kind.

Modelled on Klipper's serial layer (``klippy/serialhdl.py``, ``register_response``): the
reader owns the port's input, splits it into lines, classifies each line once
(:func:`gcode.grbl.parse_response`) and hands it to the handler registered for its kind.
An operation (connecting, a command, a status query, the streaming loop) registers the
handlers it needs for as long as it runs and waits until its condition holds; everything
else goes to the standing handlers. A handler may raise to end the wait: lines read but
not yet dispatched stay queued for the next wait, so no answer is ever lost.
"""

from __future__ import annotations

import logging
import time
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from gcode.grbl import Response, Status, parse_response, parse_settings, time_scale_of

__all__ = ["KINDS", "BEAM_OFF", "GrblSession", "PortLost", "PortTiming", "ResponseReader",
           "StreamError", "port_timing"]

log = logging.getLogger("gcode.stream")

STATUS = b"?"
SOFT_RESET = b"\x18"
#: The first bytes on every (re)connection: a controller left modal ``M4 S700`` by a lost
#: connection must not fire again on whatever comes next.
BEAM_OFF = b"M5\nM9\n"

#: Handler groups by response kind, as the issue names them.
KINDS: dict[str, str] = {
    "ok": "ok", "error": "error", "alarm": "alarm", "status": "status", "banner": "banner",
    "msg": "feedback", "gc": "feedback", "help": "feedback", "ver": "feedback",
    "opt": "feedback", "echo": "feedback", "feedback": "feedback", "startup_exec": "feedback",
    "setting": "settings", "startup_line": "settings", "param": "parameters",
    "unknown": "unknown", "empty": "empty",
}

Handler = Callable[[Response], None]


class PortLost(Exception):
    """Reading or writing the port failed: the controller is gone (cable, power, USB)."""


class ResponseReader:
    """Reads ``port`` (anything with ``read``, ``in_waiting``) and dispatches by kind."""

    def __init__(self, port) -> None:
        self.port = port
        self._buf = b""
        self._lines: deque[str] = deque()
        self._handlers: dict[str, Handler] = {}
        self.last_rx = time.monotonic()

    def register_response(self, group: str, handler: Handler | None) -> None:
        """Send every response of ``group`` (a value of KINDS) to ``handler`` (None: drop)."""
        if group not in set(KINDS.values()):
            raise ValueError(f"unknown response group {group!r}")
        if handler is None:
            self._handlers.pop(group, None)
        else:
            self._handlers[group] = handler

    @contextmanager
    def handlers(self, **by_group: Handler | None) -> Iterator[None]:
        """Register handlers for the duration of a ``with`` block, then restore the old."""
        old = {g: self._handlers.get(g) for g in by_group}
        for g, h in by_group.items():
            self.register_response(g, h)
        try:
            yield
        finally:
            for g, h in old.items():
                self.register_response(g, h)

    def _read(self) -> None:
        try:
            n = self.port.in_waiting
            data = self.port.read(n if n else 1)
        except Exception as exc:  # serial.SerialException, OSError, PortNotOpenError
            raise PortLost(f"read failed: {exc}") from exc
        if data:
            self.last_rx = time.monotonic()
            self._buf += data
            *lines, self._buf = self._buf.split(b"\n")
            self._lines.extend(ln.rstrip(b"\r").decode("ascii", errors="replace")
                               for ln in lines)

    def pump(self) -> None:
        """Read once (waiting at most the port's timeout) and dispatch every whole line."""
        if not self._lines:
            self._read()
        while self._lines:
            r = parse_response(self._lines.popleft())
            handler = self._handlers.get(KINDS.get(r.kind, "unknown"))
            if handler is not None:
                handler(r)

    def wait(self, done: Callable[[], bool], timeout: float,
             between: Callable[[], None] | None = None) -> bool:
        """Pump until ``done()`` (True) or ``timeout`` seconds (False); ``between`` runs
        before each read (polls, sends)."""
        end = time.monotonic() + timeout
        while not done():
            if time.monotonic() >= end:
                return False
            if between is not None:
                between()
            self.pump()
        return True


class StreamError(Exception):
    """The controller cannot be used: no banner, in alarm, a command unanswered or refused,
    a line or program it must not be sent."""


@dataclass(frozen=True)
class PortTiming:
    """How time runs behind a port, as the port itself declares it.

    A port may declare ``time_scale`` (machine seconds per wall second), ``machine_clock()``
    (the machine's own seconds) and ``line_baud`` (the baud rate of the wire it models,
    None for an instant link); a real serial port declares none of them: its machine runs
    on the wall clock at a scale the controller's ``$I`` may tell, over its ``baudrate``.
    So nothing here ever asks what kind of port it was given.
    """

    time_scale: float | None  # None: not declared (ask the controller's $I)
    clock: Callable[[], float] | None  # None: the wall clock times the time scale
    baud: float | None  # None: no wire to pace the reports


def port_timing(port) -> PortTiming:
    """What ``port`` declares about its time (see `PortTiming`)."""
    scale = getattr(port, "time_scale", None)
    clock = getattr(port, "machine_clock", None)
    if hasattr(port, "line_baud"):
        baud = port.line_baud
    else:
        rate = getattr(port, "baudrate", None)
        baud = float(rate) if isinstance(rate, (int, float)) and rate > 0 else None
    return PortTiming(None if scale is None else float(scale),
                      clock if callable(clock) else None, baud)


class GrblSession:
    """One connection to a GRBL 1.1 controller: connecting, one command at a time, status
    reports with the machine time they stand for, and the port's one reader.

    ``port`` is anything with ``read(n)``, ``write(b)``, ``in_waiting`` and ``timeout``
    (``serial.Serial``, ``serial.serial_for_url(...)``). ``time_scale``: machine seconds per
    wall second; by default what the port declares, else what the controller's ``$I`` says
    on connecting (1 on a real GRBL).
    """

    def __init__(self, port, *, rx_buffer: int = 128, poll_hz: float = 5.0,
                 response_timeout: float = 5.0, banner_timeout: float = 6.0,
                 time_scale: float | None = None,
                 on_status: Callable[[Status], None] | None = None, name: str = "grbl"):
        if poll_hz <= 0 or poll_hz > 5.0:
            raise ValueError("poll_hz must be in (0, 5]: GRBL answers status queries within "
                             "~5-20 ms but each one costs it serial time")
        self.port = port
        self.budget = rx_buffer - 1
        self.poll_interval = 1.0 / poll_hz
        self.response_timeout = response_timeout
        self.banner_timeout = banner_timeout
        timing = port_timing(port)
        self.line_baud = timing.baud
        self.time_scale = float(time_scale if time_scale is not None
                                else timing.time_scale if timing.time_scale is not None
                                else 1.0)
        self._ask_time_scale = time_scale is None and timing.time_scale is None
        # machine seconds: the port's machine clock, else the wall clock scaled
        self._clock: Callable[[], float] = timing.clock or (
            lambda: time.monotonic() * self.time_scale)
        self._status_wall = 0.0
        self._status_asked = 0.0
        self._status_machine = (0.0, 0.0)  # machine time asked, received
        # when each unanswered `?` went out: a report is the machine's state at some
        # instant between its question and its arrival, which bounds the machine time
        # between two reports even when the host reads them late
        self._asked: deque[tuple[float, float]] = deque(maxlen=256)  # (wall, machine)
        self._wco = np.zeros(2)
        self._wco_known = False  # MPos - WCO needs a WCO field seen since the last banner
        self._status_seq = 0
        self.on_status = on_status  # every status report, as it is read
        self.prefix = f"{name}: "
        # the one reader of the port: standing handlers here, each operation adds its own
        self.reader = ResponseReader(port)
        self.reader.register_response("status", lambda r: self._set_status(r.status))
        self.reader.register_response("banner", self._on_banner)
        for group in ("feedback", "settings", "parameters"):
            self.reader.register_response(group, self._push)
        self._inflight: deque[tuple[int, int]] = deque()  # (stream index, bytes)
        self._inflight_bytes = 0
        self.status: Status | None = None
        self.banner: str | None = None
        self._banners = 0
        self._last_poll = -1e9
        self._status_pending_since: float | None = None
        self._messages: list[str] = []
        try:
            self.port.timeout = 0.02
        except (AttributeError, ValueError, OSError):  # pragma: no cover - odd ports
            pass

    # ------------------------------------------------------------ low level I/O
    def _write(self, data: bytes) -> None:
        try:
            self.port.write(data)
        except Exception as exc:  # serial.SerialException, OSError, PortNotOpenError
            raise PortLost(f"write failed: {exc}") from exc

    def _poll(self, now: float, interval: float | None = None) -> None:
        if now - self._last_poll >= (interval or self.poll_interval):
            self._write(STATUS)
            self._asked.append((time.monotonic(), self._clock()))
            self._last_poll = now
            if self._status_pending_since is None:
                self._status_pending_since = now

    # ------------------------------------------------------------ connecting
    def connect(self, *, reset_if_silent: bool = True, quiet: float = 0.5) -> str:
        """Wait for GRBL's banner (soft-resetting once if it stays silent); return it.

        Raises StreamError if no banner arrives or the controller boots in alarm.
        """
        self._write(BEAM_OFF)  # before anything else: see BEAM_OFF
        start = time.monotonic()
        reset_sent = False
        seen = self._banners

        def reset_if_quiet() -> None:
            nonlocal reset_sent
            if reset_if_silent and not reset_sent and time.monotonic() - start > quiet:
                # never reset a machine in motion (ALARM:3, position lost): ask first
                st = self.query_status(0.5)
                if st is not None and st.state in ("Run", "Jog", "Home"):
                    raise StreamError(f"{self.prefix}controller busy ({st.state}): another "
                                      "sender's job is still moving the machine")
                self._write(SOFT_RESET)
                reset_sent = True

        if not self.reader.wait(lambda: self._banners != seen, self.banner_timeout,
                                reset_if_quiet):
            raise StreamError(f"{self.prefix}no GRBL banner within {self.banner_timeout:g} s")
        # a boot in alarm announces itself right after the banner, so before the answer
        # to a status query sent now
        alarm_boot = False

        def on_feedback(r: Response) -> None:
            nonlocal alarm_boot
            alarm_boot = alarm_boot or (r.kind == "msg" and "unlock" in (r.text or ""))
            self._push(r)

        with self.reader.handlers(feedback=on_feedback):
            st = self.query_status(0.3) or self.query_status()
        if self._ask_time_scale:
            self.time_scale = self.read_time_scale()
            if self.line_baud and self.time_scale != 1.0:
                # an emulator behind a pty: no wire is modelled there, its simulated line
                # runs in machine time, so it carries time_scale times the reports
                self.line_baud *= self.time_scale
        if alarm_boot or (st is not None and st.state == "Alarm"):
            raise StreamError(f"{self.prefix}controller is in ALARM after start-up: home ($H) or "
                              "unlock ($X) it first (station stream --unlock)")
        return self.banner or ""

    def _on_banner(self, r: Response) -> None:
        """GRBL restarted: whatever was in flight is gone, so counters start afresh."""
        self.banner = r.text
        self._banners += 1
        self._inflight.clear()
        self._inflight_bytes = 0
        self._status_pending_since = None
        self._asked.clear()
        self._wco_known = False  # GRBL sends WCO in its first report after a reset
        log.info("%sbanner Grbl %s", self.prefix, r.text)

    def query_status(self, timeout: float = 2.0) -> Status | None:
        """Ask ``?`` and wait for the report (None if none came)."""
        seq = self._status_seq
        self._write(STATUS)
        self._last_poll = time.monotonic()
        self._asked.append((self._last_poll, self._clock()))
        if self.reader.wait(lambda: self._status_seq != seq, timeout):
            return self.status
        return None

    def command(self, line: str, timeout: float = 10.0) -> tuple[Response, list[Response]]:
        """Send one command alone (nothing else in flight) and wait for its ok/error.

        Returns the answer and the pushed lines that came with it (settings, [GC:], ...).
        This is how ``$`` settings and EEPROM writes go out: one at a time.
        """
        if self._inflight:
            raise StreamError(f"{self.prefix}command {line!r} while lines are in flight")
        data = line.strip().encode("ascii") + b"\n"
        if len(data) > self.budget:
            raise StreamError(f"{self.prefix}command longer than the receive buffer: {line!r}")
        answer: list[Response] = []
        got: list[Response] = []

        def banner(r: Response) -> None:
            self._on_banner(r)
            got.append(r)

        with self.reader.handlers(ok=answer.append, error=answer.append, feedback=got.append,
                                  settings=got.append, parameters=got.append,
                                  alarm=got.append, unknown=got.append, banner=banner):
            self._write(data)
            if self.reader.wait(lambda: bool(answer), timeout):
                return answer[0], got
        raise StreamError(f"{self.prefix}no answer to {line!r} within {timeout:g} s")

    def read_time_scale(self) -> float:
        """Machine seconds per wall second, as the controller's ``$I`` build info says
        (``gcode.grbl.time_scale_of``): the watchdogs' polls are paced by it. Status reports
        asked before this are forgotten: their machine times were on the old scale."""
        r, pushed = self.command("$I")
        ver = next((p.text or "" for p in pushed if p.kind == "ver"), "")
        scale = time_scale_of(ver) if r.kind == "ok" else 1.0
        if scale != 1.0:
            log.info("%smachine time runs x%g the wall clock ($I: %s)", self.prefix, scale, ver)
        self._asked.clear()
        return scale

    def read_settings(self) -> dict[int, float]:
        """``$$`` -> {n: value}."""
        r, pushed = self.command("$$")
        if r.kind != "ok":
            raise StreamError(f"{self.prefix}$$ failed: {r.message}")
        return parse_settings([p.raw for p in pushed])

    def unlock(self) -> None:
        """``$X``: leave the alarm lock (after the operator has made the machine safe)."""
        r, _ = self.command("$X")
        if r.kind != "ok":
            raise StreamError(f"{self.prefix}$X failed: {r.message}")

    # ------------------------------------------------------------ status
    def _set_status(self, st: Status) -> None:
        self.status = st
        self._status_wall = time.monotonic()
        received = self._clock()
        self._status_asked, asked = (self._asked.popleft() if self._asked
                                     else (self._status_wall, received))
        self._status_machine = (asked, received)
        self._status_seq += 1
        self._status_pending_since = None
        if st.wco is not None:
            self._wco = np.asarray(st.wco[:2], float)
            self._wco_known = True
        if self.on_status is not None:
            self.on_status(st)

    def _work_xy(self) -> np.ndarray | None:
        """The head's X, Y in work coordinates (what the program speaks)."""
        st = self.status
        if st is None:
            return None
        if st.wpos is not None:
            return np.asarray(st.wpos[:2], float)
        if st.mpos is not None and self._wco_known:
            return np.asarray(st.mpos[:2], float) - self._wco
        return None  # work position unknown: better no path check than a false alarm

    def _push(self, r: Response) -> None:
        """Standing handler of feedback, settings and parameters: kept and logged."""
        self._messages.append(r.raw)
        log.info("%s%s", self.prefix, r.raw)

    def _wait_status(self, pred: Callable[[Status], bool], timeout: float) -> bool:
        hit: list[bool] = []

        def on_status(r: Response) -> None:
            self._set_status(r.status)
            if pred(r.status):
                hit.append(True)

        with self.reader.handlers(status=on_status):
            return self.reader.wait(lambda: bool(hit), timeout,
                                    lambda: self._poll(time.monotonic(), 0.02))

