"""Streaming a program to GRBL 1.1 over any pyserial-like port, knowing exactly what was cut.

The streamer follows GRBL's character-counting protocol: it keeps the bytes of every line
sent but not yet answered, and sends the next line only while they fit in the controller's
receive buffer (127 of its 128 bytes). Only ``ok`` and ``error:N`` answer a line; everything
else (status reports, messages, alarms, the banner) is pushed and handled on its own.

A piece goes pending -> cutting when its first line is sent and -> cut only when the ``ok``
of its sync line (``G4 P0.01`` after its last cut) arrives: GRBL answers a dwell only after
every motion before it has finished. Once anything goes wrong (error, alarm, reset banner,
garbled answer, silence, disconnect, a hold it did not ask for) piece states freeze, so no
piece is ever reported cut on an answer that might have been misattributed.

Works with a real serial port, a pseudo-terminal, or a pyserial URL (the emulator), because
it only uses ``read``, ``write``, ``in_waiting`` and ``timeout``.
"""

from __future__ import annotations

import logging
import math
import re
import time
from collections import deque
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from enum import Enum

import numpy as np

from gcode.corners import DEFAULT_JUNCTION_DEVIATION
from gcode.grbl import Response, Status, error_message, parse_settings, time_scale_of
from gcode.program import Program, strip_comment
from gcode.session import PortLost, ResponseReader
from gcode.watchdog import CATCH_MM, StopReason, Watchdog

__all__ = ["BEAM_OFF", "PieceState", "Progress", "StopReason", "StreamError", "StreamResult",
           "StreamState", "Streamer", "is_sync_command", "turns_beam_on"]

log = logging.getLogger("gcode.stream")

FEED_HOLD = b"!"
CYCLE_START = b"~"
STATUS = b"?"
SOFT_RESET = b"\x18"
SPINDLE_STOP = b"\x9e"  # real-time spindle/laser stop, honoured in Hold
#: The first bytes on every (re)connection: a controller left modal ``M4 S700`` by a lost
#: connection must not fire again on whatever comes next.
BEAM_OFF = b"M5\nM9\n"

# Commands GRBL must execute alone: they write EEPROM (which stalls the serial interrupt on
# AVR) or change state that the lines behind them depend on.
_SYNC_CMD = re.compile(r"^(\$|G10L[0-9]|G28\.1|G30\.1)", re.IGNORECASE)


_BEAM_ON = re.compile(r"M0*[34](?![0-9])", re.IGNORECASE)


def turns_beam_on(code: str) -> bool:
    """True for a line with M3/M4: sent only once every line before it is answered ``ok``.

    WHY: GRBL goes on after an ``error``. Were the travel to a cut's start rejected (a
    corrupted byte), the cut would begin wherever the head stands, beam on, before the
    host could react; waiting for the travel's ``ok`` costs one round trip per stroke.
    """
    return bool(_BEAM_ON.search(code.replace(" ", "")))


def _piece_map(program: Program, stream: list[tuple[int, str]]
               ) -> tuple[list[PieceState], dict[int, int], np.ndarray]:
    """The pieces' records, stream position of each sync line -> piece, and the piece each
    stream position belongs to (-1: none)."""
    pos_of_line = {i: k for k, (i, _) in enumerate(stream)}
    pieces = [PieceState(p.number, p.id, p.name, p.sync_line) for p in program.pieces]
    sync_at = {pos_of_line[p.sync_line]: n for n, p in enumerate(pieces)
               if p.sync_line in pos_of_line}
    piece_of = np.full(len(stream), -1)
    line_idx = np.array([i for i, _ in stream], int)
    for n, p in enumerate(program.pieces):
        lo = int(np.searchsorted(line_idx, p.first_line))
        piece_of[lo:pos_of_line.get(p.sync_line, lo) + 1] = n
    return pieces, sync_at, piece_of


def stroke_starts(program: Program, lines: list[int]) -> dict[int, np.ndarray]:
    """Stream position -> the XY where the head must stand when that line (one turning
    the beam on) is sent: the end of the last move before it."""
    c = program.check
    if c is None or c.path is None or c.path_line is None or not len(c.path):
        return {}
    out: dict[int, np.ndarray] = {}
    for k, i in enumerate(lines):
        if turns_beam_on(strip_comment(program.lines[i])):
            j = int(np.searchsorted(c.path_line, i)) - 1  # path_line grows with the line
            out[k] = c.path[max(j, 0)]
    return out


def line_baud(port) -> float | None:
    """The baud rate of the wire behind ``port``, if it is a real one: a serial device's
    ``baudrate``, or the emulator's modelled line (``grblsim://?baud=``); None for the
    emulator's instant link, whose time is not the wire's."""
    if getattr(port, "emulator", None) is not None:
        byte_time = getattr(getattr(port, "wire", None), "byte_time", None)
        return 10.0 / byte_time if byte_time else None
    baud = getattr(port, "baudrate", None)
    return float(baud) if isinstance(baud, (int, float)) and baud > 0 else None


def is_sync_command(code: str) -> bool:
    """True for ``$`` system commands and EEPROM-writing G-codes (sent one at a time)."""
    return bool(_SYNC_CMD.match(code.replace(" ", "")))


class StreamState(str, Enum):
    """Where a run is: IDLE -> STREAMING (or CHECKING) -> DRAINING -> DONE, or from any
    of them -> STOPPING (the safe stop) -> STOPPED."""

    IDLE = "idle"
    CHECKING = "checking"
    STREAMING = "streaming"
    DRAINING = "draining"
    STOPPING = "stopping"
    DONE = "done"
    STOPPED = "stopped"


class StreamError(Exception):
    """The streamer could not start (no banner, controller in alarm, port unusable)."""


_Disconnect = PortLost  # the port failed: nothing more can be said to the controller


@dataclass
class PieceState:
    """The cut record of one piece; ``state`` is ``pending``, ``cutting`` or ``cut``."""

    number: int
    id: str
    name: str
    sync_line: int  # 0-based index into the program's lines
    state: str = "pending"


@dataclass
class Progress:
    lines_total: int
    lines_sent: int
    lines_acked: int
    fraction: float
    elapsed: float
    eta_seconds: float | None
    state: str | None  # last machine state reported
    pieces_cut: int


@dataclass
class StreamResult:
    """What happened: ``reason`` is a :class:`StopReason` (a ``str``: ``done``, ``checked``,
    ``error``, ``alarm``, ``reset``, ``garbled``, ``unmatched``, ``off_path``, ``feed``,
    ``power``, ``timeout``, ``hold``, ``disconnect``, ``stopped`` or ``interrupted``)."""

    completed: bool
    reason: StopReason | str
    lines_total: int
    lines_sent: int = 0
    lines_acked: int = 0
    errors: list[dict] = field(default_factory=list)
    alarms: list[dict] = field(default_factory=list)
    pieces: list[PieceState] = field(default_factory=list)
    fault: dict | None = None
    position: tuple[float, ...] | None = None
    seconds: float = 0.0
    check: bool = False
    messages: list[str] = field(default_factory=list)
    status_reports: int = 0  # reports the watchdog judged (its polling load)

    @property
    def pieces_cut(self) -> int:
        return sum(p.state == "cut" for p in self.pieces)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["pieces_cut"] = self.pieces_cut
        d["position"] = list(self.position) if self.position else None
        return d


class _Fault(Exception):
    def __init__(self, reason: StopReason, detail: str, line: int | None = None):
        super().__init__(detail)
        self.reason, self.detail, self.line = reason, detail, line


class _Run:
    """One run's bookkeeping: the lines, what was sent and answered, the pieces, and the
    handlers the session reader calls with ``ok``/``error``/alarms/banners while it lasts."""

    def __init__(self, streamer: Streamer, program: Program, stream: list[tuple[int, str]],
                 check: bool):
        self.st = streamer
        self.t0 = time.monotonic()
        self.stream = stream
        self.check = check
        self.pieces, self.sync_at, self.piece_of = _piece_map(program, stream)
        weights = (np.array([program.check.seconds[i] for i, _ in stream])
                   if program.check is not None and len(stream) else np.ones(len(stream)))
        self.cum = np.concatenate([[0.0], np.cumsum(np.maximum(weights, 1e-3))])
        self.res = StreamResult(completed=False, reason="", lines_total=len(stream),
                                check=check, pieces=self.pieces)
        self.starts = (stroke_starts(program, [i for i, _ in stream])
                       if streamer.deviation_limit and not check else {})
        self.sent = self.acked = 0
        self.last_progress = 0.0
        self.seen_status = streamer._status_seq
        self.banners_at_start = streamer._banners

    def set_piece(self, n: int, state: str) -> None:
        st, piece = self.st, self.pieces[n]
        if st._frozen or piece.state == state or piece.state == "cut":
            return
        piece.state = state
        log.info("%spiece %d %s %s", st.prefix, piece.number, piece.id, state)
        if st.on_piece:
            st.on_piece(piece)

    def progress(self, force: bool = False) -> None:
        st, now = self.st, time.monotonic()
        if not st.on_progress or (not force and now - self.last_progress < 0.1):
            return
        self.last_progress = now
        frac = float(self.cum[self.acked] / self.cum[-1]) if len(self.stream) else 1.0
        el = now - self.t0
        eta = el * (1 - frac) / frac if frac > 0.02 else None
        st.on_progress(Progress(len(self.stream), self.sent, self.acked, frac, el, eta,
                                st.status.state if st.status else None,
                                sum(p.state == "cut" for p in self.pieces)))

    def send_ready(self) -> None:
        """Send while the next line fits; sync commands and the beam coming on go alone."""
        st, stream = self.st, self.stream
        while self.sent < len(stream):
            i, code = stream[self.sent]
            n_bytes = len(code) + 1
            if n_bytes > st.budget:
                raise _Fault(StopReason.ERROR, f"line longer than the receive buffer "
                             f"({n_bytes} bytes)", i)
            if is_sync_command(code) and st._inflight:
                break
            if turns_beam_on(code) and (st._inflight or not st._at_start(
                    self.starts.get(self.sent), i)):
                break  # see turns_beam_on
            if st._inflight and is_sync_command(stream[st._inflight[-1][0]][1]):
                break
            if st._inflight_bytes + n_bytes > st.budget:
                break
            if not st._inflight:
                st._last_ack = time.monotonic()
            st._write(code.encode("ascii") + b"\n")
            st._inflight.append((self.sent, n_bytes))
            st._inflight_bytes += n_bytes
            if self.piece_of[self.sent] >= 0:
                self.set_piece(int(self.piece_of[self.sent]), "cutting")
            self.sent += 1

    def on_answer(self, r: Response) -> None:
        """``ok`` / ``error:N``: the oldest line in flight is answered."""
        st = self.st
        if not st._inflight:
            raise _Fault(StopReason.UNMATCHED, f"{r.raw!r} with no line in flight")
        k, nb = st._inflight.popleft()
        st._inflight_bytes -= nb
        st._last_ack = time.monotonic()
        self.acked = k + 1
        if r.kind == "error":
            err = {"line": self.stream[k][0] + 1, "text": self.stream[k][1], "code": r.code,
                   "message": error_message(r.code or 0)}
            self.res.errors.append(err)
            log.warning("%sline %d %r: %s", st.prefix, err["line"], err["text"],
                        err["message"])
            if not self.check:
                raise _Fault(StopReason.ERROR, err["message"], self.stream[k][0])
        elif k in self.sync_at:
            self.set_piece(self.sync_at[k], "cut")

    def on_alarm(self, r: Response) -> None:
        self.res.alarms.append({"code": r.code, "message": r.message})
        raise _Fault(StopReason.ALARM, r.message, self.st._oldest_line(self.stream))

    def on_banner(self, r: Response) -> None:
        self.st._on_banner(r)
        if self.st._banners != self.banners_at_start:
            raise _Fault(StopReason.RESET, "the controller restarted (banner) mid-job: "
                         "lines in flight were lost")

    def on_garbled(self, r: Response) -> None:
        raise _Fault(StopReason.GARBLED, f"unreadable answer {r.raw!r}",
                     self.st._oldest_line(self.stream))


class Streamer:
    """Stream G-code to a GRBL 1.1 controller with character counting.

    ``port`` is anything with ``read(n)``, ``write(b)``, ``in_waiting`` and ``timeout``
    (``serial.Serial``, ``serial.serial_for_url(...)``). Hooks: ``on_piece(PieceState)`` on
    every change of a piece's state (the job store persists it there), ``on_progress``
    (``Progress``) at most 10 times a second, ``on_fault(dict)`` once when a run stops early.
    """

    def __init__(self, port, *, rx_buffer: int = 128, poll_hz: float = 5.0,
                 response_timeout: float = 5.0, stall_timeout: float = 5.0,
                 banner_timeout: float = 6.0, compact: bool = True,
                 deviation_limit: float | None = 0.3, watch_mm: float = 1.0,
                 acceleration: float = 1500.0, rapid_feed: float = 12000.0,
                 time_scale: float | None = None,
                 on_piece: Callable[[PieceState], None] | None = None,
                 on_progress: Callable[[Progress], None] | None = None,
                 on_fault: Callable[[dict], None] | None = None,
                 on_state: Callable[[StreamState], None] | None = None,
                 on_status: Callable[[Status], None] | None = None,
                 name: str = "grbl"):
        if poll_hz <= 0 or poll_hz > 5.0:
            raise ValueError("poll_hz must be in (0, 5]: GRBL answers status queries within "
                             "~5-20 ms but each one costs it serial time")
        self.port = port
        self.budget = rx_buffer - 1
        self.poll_interval = 1.0 / poll_hz
        self.response_timeout = response_timeout
        self.stall_timeout = stall_timeout
        self.banner_timeout = banner_timeout
        self.compact = compact
        self.deviation_limit = deviation_limit
        self.watch_mm = watch_mm
        self.acceleration = acceleration
        self.rapid_feed = rapid_feed
        self.line_baud = line_baud(port)
        # machine seconds per wall second: 1 on a real GRBL, `speed` on the emulator; the
        # machine tells it (`$I`) on connecting unless given or the emulator is in-process
        emulator = getattr(port, "emulator", None)
        self.time_scale = float(time_scale if time_scale is not None else getattr(
            emulator, "speed", 1.0))
        self._ask_time_scale = time_scale is None and emulator is None
        self.watchdog: Watchdog | None = None
        # machine seconds: the emulator's simulated clock, else the wall clock scaled
        self._clock: Callable[[], float] = (
            (lambda: emulator.sim_time) if hasattr(emulator, "sim_time")
            else lambda: time.monotonic() * self.time_scale)
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
        self.on_piece = on_piece
        self.on_progress = on_progress
        self.on_fault = on_fault
        self.on_state = on_state
        self.on_status = on_status  # every status report, as it is read
        self.state = StreamState.IDLE
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
        self._last_ack = time.monotonic()
        self._pause = self._resume = self._stop = False
        self._held = False  # the host asked for the feed hold the machine may be in
        self._resumed_at = -1e9  # wall time of the last cycle start written
        self._frozen = False
        self._messages: list[str] = []
        try:
            self.port.timeout = 0.02
        except (AttributeError, ValueError, OSError):  # pragma: no cover - odd ports
            pass

    # ------------------------------------------------------------ control (any thread)
    def pause(self) -> None:
        """Feed hold (``!``) at the next loop turn; lines keep filling the buffer."""
        self._pause = True

    def resume(self) -> None:
        """Cycle start (``~``)."""
        self._resume = True

    def stop(self) -> None:
        """Safe stop: feed hold, wait for Hold:0, soft reset, laser off."""
        self._stop = True

    # ------------------------------------------------------------ low level I/O
    def _write(self, data: bytes) -> None:
        try:
            self.port.write(data)
        except Exception as exc:  # serial.SerialException, OSError, PortNotOpenError
            raise _Disconnect(f"write failed: {exc}") from exc

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

    # ------------------------------------------------------------ streaming
    def run(self, program: Program, *, check: bool = False) -> StreamResult:
        """Stream ``program``; with ``check`` run it in GRBL's check mode ($C) instead.

        Returns when the job is done or has stopped safely; never raises for machine faults
        (they are in the result), only StreamError when it cannot start.
        """
        job = _Run(self, program, self._wire_lines(program), check)
        self._refuse_state(check)
        settings = {} if check else self._refuse_laser_settings(program)
        wd = self._make_watchdog(program, settings) if not check else None
        self._held = False
        self._frozen = check  # check mode proves nothing was cut
        self._messages = job.res.messages
        if wd is not None and wd.catch_mm > CATCH_MM and not self.line_baud:
            # an emulator's instant link: the host's own polling pace is the limit, and a
            # paced emulator waits for the host; said, not refused (no beam is at stake)
            note = (f"at F{max(wd.feeds):g} a deviation may travel {wd.catch_mm:.1f} mm "
                    f"before a report shows it ({CATCH_MM:g} mm asked) at this emulator speed")
            log.warning("%s%s", self.prefix, note)
            job.res.messages.append(note)
        elif wd is not None and wd.catch_mm > CATCH_MM:
            fastest = max(wd.feeds)
            # travel before a report is proportional to the feed: the fastest watchable one
            watchable = fastest * CATCH_MM / wd.catch_mm
            raise StreamError(
                f"{self.prefix}at F{fastest:g} with the beam on a deviation may travel "
                f"{wd.catch_mm:.1f} mm before a status report shows it ({CATCH_MM:g} mm is "
                f"the limit): the serial line carries too few reports; cut at most "
                f"F{math.floor(watchable):g} or raise the baud rate")
        try:
            try:
                self._enter(StreamState.CHECKING if check else StreamState.STREAMING)
                if check:
                    self._enter_check()
                    job.banners_at_start = self._banners
                with self.reader.handlers(ok=job.on_answer, error=job.on_answer,
                                          alarm=job.on_alarm, banner=job.on_banner,
                                          unknown=job.on_garbled):
                    while job.acked < len(job.stream):
                        self._turn(job, wd)
                    job.progress(force=True)
                self._enter(StreamState.DRAINING)
                self._finish(job.res, check)
            except (KeyboardInterrupt, _Fault) as exc:
                f = exc if isinstance(exc, _Fault) else _Fault(StopReason.INTERRUPTED,
                                                                "interrupted")
                self._frozen = True
                self._record_fault(job.res, f, job.stream, job.sent, job.acked)
                # after an alarm too: GRBL wants a reset to continue, and the reset clears
                # the parser's spindle and coolant state (the beam is already off). Motion
                # has already stopped and a critical alarm ignores status queries, so no hold.
                self._enter(StreamState.STOPPING)
                self._safe_stop(job.res, hold=f.reason != StopReason.ALARM)
        except _Disconnect as exc:
            self._frozen = True
            if not job.res.reason:
                self._record_fault(job.res, _Fault(StopReason.DISCONNECT, str(exc)),
                                   job.stream, job.sent, job.acked)
            else:
                job.res.messages.append(f"disconnected during the safe stop: {exc}")
        return self._result(job, wd)

    def _refuse_state(self, check: bool) -> None:
        """A controller in alarm, or in check mode for a real cut, cannot start a run."""
        st = self.query_status(1.0)
        if st is not None and st.state == "Alarm":
            raise StreamError(f"{self.prefix}controller is in ALARM: home ($H) or unlock ($X) "
                              "it first")
        if st is not None and st.state == "Check" and not check:
            # in check mode every line is answered ok and nothing moves: no piece would be cut
            raise StreamError(f"{self.prefix}controller is in check mode ($C); leave it first")

    def _turn(self, job: _Run, wd: Watchdog | None) -> None:
        """One turn of the streaming loop: operator requests, send, poll, read, judge."""
        now = time.monotonic()
        if self._stop:
            self._stop = False  # consumed: the next run starts afresh
            raise _Fault(StopReason.STOPPED, "stopped by the operator")
        if self._pause:
            self._pause, self._held = False, True
            self._write(FEED_HOLD)
        if self._resume:
            self._resume, self._held = False, False
            self._write(CYCLE_START)
            self._resumed_at = time.monotonic()
        job.send_ready()
        self._poll(now, wd.interval if wd is not None else None)
        self.reader.pump()
        if self._status_seq != job.seen_status and self.status is not None:
            self._refuse_unasked_hold(self.status, self._oldest_line(job.stream))
        if wd is not None and self._status_seq != job.seen_status:
            job.seen_status = self._status_seq
            breach = wd.check(self.status, self._work_xy(), *self._status_machine,
                              not self._inflight)
            if breach is not None:
                raise _Fault(breach.reason, breach.detail, breach.line
                             if breach.line is not None else self._oldest_line(job.stream))
        self._watchdog(job.stream)
        job.progress()

    def _refuse_unasked_hold(self, st: Status, line: int | None) -> None:
        """A hold or open door the host did not ask for is a fault: a ``!`` made by line
        noise looks exactly like a hold button, and a job nobody resumes would wait
        forever with its piece half cut and recorded as being cut."""
        if st.state not in ("Hold", "Door") or self._held:
            return
        if self._status_asked <= self._resumed_at:
            return  # asked before our cycle start reached the controller
        raise _Fault(StopReason.HOLD, f"{st.state}:{st.substate} that the host did not ask "
                     "for (a feed hold or door from the line or a switch)", line)

    def _finish(self, res: StreamResult, check: bool) -> None:
        """Every line answered: leave check mode, or wait until the machine is at rest."""
        if check:
            self._leave_check()
            res.reason = StopReason.CHECKED if not res.errors else StopReason.ERROR
            res.completed = not res.errors
        else:
            self._wait_idle()
            res.reason, res.completed = StopReason.DONE, True

    def _result(self, job: _Run, wd: Watchdog | None) -> StreamResult:
        res = job.res
        res.lines_sent, res.lines_acked = job.sent, job.acked
        if wd is not None:
            res.status_reports = wd.reports
            try:
                self.port.timeout = 0.02
            except (AttributeError, ValueError, OSError):  # pragma: no cover - odd ports
                pass
        res.seconds = time.monotonic() - job.t0
        self._enter(StreamState.DONE if res.completed else StreamState.STOPPED)
        if res.position is None and self.status is not None:
            res.position = self.status.position()
        return res

    # ------------------------------------------------------------ helpers
    def _enter(self, state: StreamState) -> None:
        self.state = state
        log.debug("%sstream %s", self.prefix, state.value)
        if self.on_state:
            self.on_state(state)

    def _oldest_line(self, stream: list[tuple[int, str]]) -> int | None:
        return stream[self._inflight[0][0]][0] if self._inflight else None

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

    def _wire_lines(self, program: Program) -> list[tuple[int, str]]:
        """(program line index, code to send) of every line with code; refuses up front
        what must never reach the controller (real-time bytes, over-long lines)."""
        stream: list[tuple[int, str]] = []
        for i, line in enumerate(program.lines):
            code = strip_comment(line)
            if self.compact:
                code = code.replace(" ", "")
            if not code:
                continue
            bad = sorted({ch for ch in code if ch in "?!~" or not " " <= ch <= "~"})
            if bad:
                raise StreamError(f"{self.prefix}line {i + 1} holds real-time or non-ASCII "
                                  f"character(s) {bad!r}: {code!r}")
            if len(code) > 79 or len(code) + 1 > self.budget:
                raise StreamError(f"{self.prefix}line {i + 1} is longer than GRBL accepts "
                                  f"({len(code)} characters): {code!r}")
            stream.append((i, code))
        return stream

    def _at_start(self, start: np.ndarray | None, line: int) -> bool:
        """True once a report asked for after the last answer shows the head where the
        stroke of ``line`` starts (the beam may come on); a head at rest elsewhere is a
        fault: a corrupted travel move would start the cut off its path."""
        if start is None or self.watchdog is None:
            return True
        xy = self._work_xy()
        if xy is None or self.status is None or self._status_asked <= self._last_ack:
            return False  # no report since the travel was answered: wait for one
        d = float(np.hypot(*(xy - start)))
        if d <= self.watchdog.deviation:
            return True
        if self.status.state == "Idle":
            raise _Fault(StopReason.OFF_PATH, f"head at rest at X{xy[0]:.3f} Y{xy[1]:.3f}, "
                         f"{d:.2f} mm from where the cut starts (corrupted travel move?)",
                         line)
        return False

    def _refuse_laser_settings(self, program: Program) -> dict[int, float]:
        """Refuse, before anything moves, a laser program the controller would not run as
        checked: M3/M4 outside laser mode ($32=0) keep the beam on through rapids and
        stops, and an S above $30 is clamped (the power watchdog would see it as corrupt).
        Returns the settings read (none for a program without the beam)."""
        c = program.check
        if c is None or not c.cut_pairs:
            return {}
        settings = self.read_settings()
        word = "M4" if c.dynamic_power else "M3"
        if settings.get(32) is None or int(settings[32]) != 1:
            found = "does not report $32" if settings.get(32) is None else \
                f"has $32={settings[32]:g}"
            raise StreamError(f"{self.prefix}the program's laser power ({word}) needs GRBL's "
                              f"laser mode, but the controller {found}: without it the beam "
                              "stays on through rapids and stops; set $32=1")
        top = max(s for s, _ in c.cut_pairs)
        if settings.get(30) is not None and top > settings[30] + 1e-6:
            raise StreamError(f"{self.prefix}the program asks for S{top:g}, above the "
                              f"controller's $30={settings[30]:g}: GRBL would clamp it")
        return settings

    def _make_watchdog(self, program: Program,
                       settings: dict[int, float]) -> Watchdog | None:
        """The watchdog over ``program``'s path, polls and port timeout set to its pace."""
        c = program.check
        self.watchdog = None
        if not self.deviation_limit or c is None or c.path is None or not len(c.path):
            return None
        wd = Watchdog.for_program(c, self.acceleration, self.rapid_feed,
                                  time_scale=self.time_scale, deviation_mm=self.deviation_limit,
                                  watch_mm=self.watch_mm, baud=self.line_baud,
                                  min_s=settings.get(31, 0.0),  # the least non-zero S shown
                                  junction_deviation=settings.get(
                                      11, DEFAULT_JUNCTION_DEVIATION))
        wd.start_from(self._work_xy() if self.status is not None else None)
        try:  # never sleep in a read longer than the next poll is due
            self.port.timeout = min(0.02, wd.interval)
        except (AttributeError, ValueError, OSError):  # pragma: no cover - odd ports
            pass
        self.watchdog = wd
        return wd

    def _watchdog(self, stream: list[tuple[int, str]]) -> None:
        now = time.monotonic()
        if (self._status_pending_since is not None
                and now - self._status_pending_since > self.response_timeout):
            raise _Fault(StopReason.TIMEOUT, f"no status report for {self.response_timeout:g} s "
                         "(controller silent: power cut or cable?)", self._oldest_line(stream))
        st = self.status
        if (self._inflight and st is not None and st.state == "Idle"
                and now - self._last_ack > self.stall_timeout):
            raise _Fault(StopReason.TIMEOUT, "controller idle with lines unanswered (a lost byte?)",
                         self._oldest_line(stream))

    def _record_fault(self, res: StreamResult, f: _Fault, stream, sent: int, acked: int) -> None:
        res.reason = f.reason
        res.position = self.status.position() if self.status else None
        line = f.line
        res.fault = {
            "reason": f.reason,
            "detail": f.detail,
            "line": None if line is None else line + 1,
            "lines_sent": sent,
            "lines_acked": acked,
            "state": self.status.state if self.status else None,
            "position": list(res.position) if res.position else None,
        }
        log.error("%sstopping: %s (%s)", self.prefix, f.detail, f.reason)
        if self.on_fault:
            self.on_fault(res.fault)

    def _wait_status(self, pred: Callable[[Status], bool], timeout: float) -> bool:
        hit: list[bool] = []

        def on_status(r: Response) -> None:
            self._set_status(r.status)
            if pred(r.status):
                hit.append(True)

        with self.reader.handlers(status=on_status):
            return self.reader.wait(lambda: bool(hit), timeout,
                                    lambda: self._poll(time.monotonic(), 0.02))

    def _wait_idle(self, timeout: float = 120.0) -> None:
        def at_rest(s: Status) -> bool:
            self._refuse_unasked_hold(s, None)
            return s.state in ("Idle", "Check")

        if not self._wait_status(at_rest, timeout):
            raise _Fault(StopReason.TIMEOUT,
                         f"the controller did not come back to Idle in {timeout:g} s")

    def _safe_stop(self, res: StreamResult, hold: bool = True, hold_timeout: float = 10.0
                   ) -> None:
        """Feed hold, wait for Hold:0 (decelerated: a reset keeps position), soft reset,
        then laser and air off."""
        if hold:
            # one write: GRBL runs the hold first, then the laser stop it allows in Hold
            self._write(FEED_HOLD + SPINDLE_STOP)
            held = self._wait_status(
                lambda s: (s.state == "Hold" and s.substate == 0)
                or s.state in ("Idle", "Alarm", "Check"), hold_timeout)
            if not held:
                res.messages.append("no Hold:0 before the reset (controller silent?)")
        banners = self._banners
        self._write(SOFT_RESET)

        def on_alarm(r: Response) -> None:
            res.alarms.append({"code": r.code, "message": r.message})

        with self.reader.handlers(alarm=on_alarm):
            self.reader.wait(lambda: self._banners != banners, self.banner_timeout)
        if self._banners == banners:
            res.messages.append("no banner after the soft reset")
            return
        st = self.query_status(1.0)
        if st is not None and st.state not in ("Alarm",):
            for cmd in ("M5", "M9"):  # a reset already stops them; say so explicitly anyway
                try:
                    self.command(cmd, timeout=2.0)
                except StreamError as exc:
                    res.messages.append(str(exc))

    def _enter_check(self) -> None:
        r, pushed = self.command("$C")
        if r.kind != "ok" or not any("Enabled" in (p.text or "") for p in pushed):
            raise StreamError(f"{self.prefix}could not enter check mode: {r.raw}")

    def _leave_check(self) -> None:
        """``$C`` again: GRBL leaves check mode with a soft reset (a banner follows)."""
        banners = self._banners
        r, pushed = self.command("$C")
        self.reader.wait(lambda: self._banners != banners, self.banner_timeout)
        if r.kind != "ok":
            raise _Fault(StopReason.ERROR, f"could not leave check mode: {r.raw}")
