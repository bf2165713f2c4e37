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
import time
from collections.abc import Callable

import numpy as np

from gcode.blocks import parse_line
from gcode.corners import DEFAULT_JUNCTION_DEVIATION
from gcode.grbl import Response, Status, error_message
from gcode.program import Program
from gcode.session import BEAM_OFF, SOFT_RESET, GrblSession, PortLost, StreamError
from gcode.streamrecords import (
    Fault,
    PieceState,
    Progress,
    StreamResult,
    StreamState,
    piece_map,
    stroke_starts,
    wire_lines,
)
from gcode.watchdog import CATCH_MM, StopReason, Watchdog

__all__ = ["BEAM_OFF", "PieceState", "Progress", "StopReason", "StreamError", "StreamResult",
           "StreamState", "Streamer", "is_sync_command", "turns_beam_on"]

log = logging.getLogger("gcode.stream")

FEED_HOLD = b"!"
CYCLE_START = b"~"
SPINDLE_STOP = b"\x9e"  # real-time spindle/laser stop, honoured in Hold


def turns_beam_on(code: str) -> bool:
    """True for a line of text with M3/M4 (see `gcode.blocks.Block.turns_beam_on`)."""
    return parse_line(code).turns_beam_on


def is_sync_command(code: str) -> bool:
    """True for ``$`` system commands and EEPROM-writing G-codes (sent one at a time)."""
    return parse_line(code).alone


class StreamJob:
    """One run's bookkeeping: the lines, what was sent and answered, the pieces, and the
    handlers the session reader calls with ``ok``/``error``/alarms/banners while it lasts."""

    def __init__(self, streamer: Streamer, program: Program, stream: list[tuple[int, str]],
                 check: bool):
        self.st = streamer
        self.t0 = time.monotonic()
        self.stream = stream
        self.check = check
        self.blocks = program.blocks
        self.pieces, self.sync_at, self.piece_of = piece_map(program, stream)
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
                raise Fault(StopReason.ERROR, f"line longer than the receive buffer "
                             f"({n_bytes} bytes)", i)
            block = self.blocks[i]
            if block.alone and st._inflight:
                break
            if block.turns_beam_on and (st._inflight or not st._at_start(
                    self.starts.get(self.sent), i)):
                break  # see Block.turns_beam_on
            if st._inflight and self.blocks[stream[st._inflight[-1][0]][0]].alone:
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
            raise Fault(StopReason.UNMATCHED, f"{r.raw!r} with no line in flight")
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
                raise Fault(StopReason.ERROR, err["message"], self.stream[k][0])
        elif k in self.sync_at:
            self.set_piece(self.sync_at[k], "cut")

    def on_alarm(self, r: Response) -> None:
        self.res.alarms.append({"code": r.code, "message": r.message})
        raise Fault(StopReason.ALARM, r.message, self.st._oldest_line(self.stream))

    def on_banner(self, r: Response) -> None:
        self.st._on_banner(r)
        if self.st._banners != self.banners_at_start:
            raise Fault(StopReason.RESET, "the controller restarted (banner) mid-job: "
                         "lines in flight were lost")

    def on_garbled(self, r: Response) -> None:
        raise Fault(StopReason.GARBLED, f"unreadable answer {r.raw!r}",
                     self.st._oldest_line(self.stream))


class Streamer(GrblSession):
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
        super().__init__(port, rx_buffer=rx_buffer, poll_hz=poll_hz,
                         response_timeout=response_timeout, banner_timeout=banner_timeout,
                         time_scale=time_scale, on_status=on_status, name=name)
        self.stall_timeout = stall_timeout
        self.compact = compact
        self.deviation_limit = deviation_limit
        self.watch_mm = watch_mm
        self.acceleration = acceleration
        self.rapid_feed = rapid_feed
        self.watchdog: Watchdog | None = None
        self.on_piece = on_piece
        self.on_progress = on_progress
        self.on_fault = on_fault
        self.on_state = on_state
        self.state = StreamState.IDLE
        self._last_ack = time.monotonic()
        self._pause = self._resume = self._stop = False
        self._held = False  # the host asked for the feed hold the machine may be in
        self._resumed_at = -1e9  # wall time of the last cycle start written
        self._frozen = False

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

    # ------------------------------------------------------------ streaming
    def run(self, program: Program, *, check: bool = False) -> StreamResult:
        """Stream ``program``; with ``check`` run it in GRBL's check mode ($C) instead.

        Returns when the job is done or has stopped safely; never raises for machine faults
        (they are in the result), only StreamError when it cannot start.
        """
        job = StreamJob(self, program, wire_lines(program, self.budget, self.compact, self.prefix),
                        check)
        self._refuse_state(check)
        settings = {} if check else self._refuse_laser_settings(program)
        wd = self._make_watchdog(program, settings) if not check else None
        self._held = False
        self._frozen = check  # check mode proves nothing was cut
        self._messages = job.res.messages
        if wd is not None:
            self._refuse_slow_reports(wd, job.res.messages)
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
            except (KeyboardInterrupt, Fault) as exc:
                f = exc if isinstance(exc, Fault) else Fault(StopReason.INTERRUPTED,
                                                                "interrupted")
                self._frozen = True
                self._record_fault(job.res, f, job.stream, job.sent, job.acked)
                # after an alarm too: GRBL wants a reset to continue, and the reset clears
                # the parser's spindle and coolant state (the beam is already off). Motion
                # has already stopped and a critical alarm ignores status queries, so no hold.
                self._enter(StreamState.STOPPING)
                self._safe_stop(job.res, hold=f.reason != StopReason.ALARM)
        except PortLost as exc:
            self._frozen = True
            if not job.res.reason:
                self._record_fault(job.res, Fault(StopReason.DISCONNECT, str(exc)),
                                   job.stream, job.sent, job.acked)
            else:
                job.res.messages.append(f"disconnected during the safe stop: {exc}")
        return self._result(job, wd)

    def _refuse_slow_reports(self, wd: Watchdog, messages: list[str]) -> None:
        """Refuse a cut whose deviations the status reports would show too late; on an
        emulator's instant link say so instead (no beam is at stake)."""
        if wd.catch_mm <= CATCH_MM:
            return
        if not self.line_baud:
            # an emulator's instant link: the host's own polling pace is the limit, and a
            # paced emulator waits for the host
            note = (f"at F{max(wd.feeds):g} a deviation may travel {wd.catch_mm:.1f} mm "
                    f"before a report shows it ({CATCH_MM:g} mm asked) at this emulator speed")
            log.warning("%s%s", self.prefix, note)
            messages.append(note)
            return
        fastest = max(wd.feeds)
        # travel before a report is proportional to the feed: the fastest watchable one
        watchable = fastest * CATCH_MM / wd.catch_mm
        raise StreamError(
            f"{self.prefix}at F{fastest:g} with the beam on a deviation may travel "
            f"{wd.catch_mm:.1f} mm before a status report shows it ({CATCH_MM:g} mm is "
            f"the limit): the serial line carries too few reports; cut at most "
            f"F{math.floor(watchable):g} or raise the baud rate")

    def _refuse_state(self, check: bool) -> None:
        """A controller in alarm, or in check mode for a real cut, cannot start a run."""
        st = self.query_status(1.0)
        if st is not None and st.state == "Alarm":
            raise StreamError(f"{self.prefix}controller is in ALARM: home ($H) or unlock ($X) "
                              "it first")
        if st is not None and st.state == "Check" and not check:
            # in check mode every line is answered ok and nothing moves: no piece would be cut
            raise StreamError(f"{self.prefix}controller is in check mode ($C); leave it first")

    def _turn(self, job: StreamJob, wd: Watchdog | None) -> None:
        """One turn of the streaming loop: operator requests, send, poll, read, judge."""
        now = time.monotonic()
        if self._stop:
            self._stop = False  # consumed: the next run starts afresh
            raise Fault(StopReason.STOPPED, "stopped by the operator")
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
                raise Fault(breach.reason, breach.detail, breach.line
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
        raise Fault(StopReason.HOLD, f"{st.state}:{st.substate} that the host did not ask "
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

    def _result(self, job: StreamJob, wd: Watchdog | None) -> StreamResult:
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
            raise Fault(StopReason.OFF_PATH, f"head at rest at X{xy[0]:.3f} Y{xy[1]:.3f}, "
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
            raise Fault(StopReason.TIMEOUT, f"no status report for {self.response_timeout:g} s "
                         "(controller silent: power cut or cable?)", self._oldest_line(stream))
        st = self.status
        if (self._inflight and st is not None and st.state == "Idle"
                and now - self._last_ack > self.stall_timeout):
            raise Fault(StopReason.TIMEOUT, "controller idle with lines unanswered (a lost byte?)",
                         self._oldest_line(stream))

    def _record_fault(self, res: StreamResult, f: Fault, stream, sent: int, acked: int) -> None:
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

    def _wait_idle(self, timeout: float = 120.0) -> None:
        def at_rest(s: Status) -> bool:
            self._refuse_unasked_hold(s, None)
            return s.state in ("Idle", "Check")

        if not self._wait_status(at_rest, timeout):
            raise Fault(StopReason.TIMEOUT,
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
            raise Fault(StopReason.ERROR, f"could not leave check mode: {r.raw}")
