"""Watchdogs on what the machine does while it cuts, judged in machine time.

GRBL has no checksum: one flipped bit on the wire turns ``G1X173.9Y67.1`` into the valid
``F1X173.9Y67.1`` (feed 1 mm/min with the beam on) and ``Y829`` into ``Y929``. What was
sent proves nothing, so every status report is held against the program:

* the head stays within ``deviation_mm`` of the program's path (any motion);
* while the beam is on, the reported laser value (``FS:`` second field) is what a healthy
  GRBL 1.1 reports for the program's S at the report's own feed (``FS:`` first field), and
  no override (``Ov:``) is in force: the host sends none. Under M4 (laser mode's dynamic
  power) GRBL scales S by current speed / programmed feed for every step segment it
  prepares, and reports that value (``stepper.c``: ``rpm *= current_speed * inv_rate``;
  ``spindle_compute_pwm_value`` stores it in ``sys.spindle_speed``); the reported feed is
  the same prepared segment's speed (``st_get_realtime_rate``). Under M3 it is S;
* the head is followed along the path in program order: in the middle of a move that
  cuts, the beam is on; in the middle of a travel move, it is off;
* while the beam is on, the reported feed reaches the programmed cutting feed within the
  time the profile's acceleration ($120/$121) needs, and never exceeds it. A machine the
  line cannot keep fed is slower, exactly as far as its look-ahead demands: GRBL plans
  every block so that the last one queued can stop, so with ``n`` blocks queued (``Bf:``)
  the head can go no faster than ``sqrt(2 a d)`` over the distance ``d`` those blocks
  cover; the feed is held to that (a corrupted ``F1`` fills the planner, and is caught).

What a healthy GRBL 1.1 reports, and how each rule allows for it:

* corners: the planner brakes to ``a * $11 * sin / (1 - sin)`` at every junction, so a path
  of short lines never reaches F; the expected feed is capped by ``gcode.corners``;
* the end of a stroke (M5 and G10 lines sync the planner): the report shows the prepared
  segment, so the feed and the M4 power read 0 up to PREP_LEAD_S before the head stops;
  under M4 the segment that brakes to a stop also runs dark. The beam-off timer allows
  that lead and runs on through the corners of one stroke;
* feed hold: power and feed are judged only in Run (in Hold M4 power falls with the
  braking head); a hold the host did not ask for is a recorded stop (``gcode.stream``);
* overrides: ``Ov:`` comes every 20th report while busy, but at once after any change, so
  the first report after a stray override byte shows it;
* ``Bf:`` and ``WCO:``: the look-ahead bound above; ``WCO:`` only every 30th report while
  busy, and the streamer keeps the last one to turn MPos into program coordinates.

Polls are scheduled in machine time: ``watch_mm`` of travel at the fastest programmed
cutting feed, divided by ``time_scale`` (simulated seconds per wall second: 1 on a real
GRBL, the emulator's ``speed`` on ``grblsim://``). A deviation is therefore seen within
``deviation_mm + watch_mm`` of travel at any emulator speed, as long as the host keeps up
with its own schedule, plus what the serial line adds (the ``?`` queued behind the bytes
already written, the report's own transmission). On a line of known baud rate the polls
are also spaced so that the reports take at most half of what the controller can send:
the ``ok``s share that line, and a sender that reads them late leaves the line idle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

from gcode.corners import DEFAULT_JUNCTION_DEVIATION, CornerSpeeds
from gcode.grbl import Status

__all__ = ["CATCH_MM", "REPORT_BYTES", "Breach", "StopReason", "Watchdog", "catch_travel_mm",
           "poll_interval", "report_spacing"]

PLANNER_BLOCKS = 15  # GRBL 1.1's planner on an AVR
#: How far (machine seconds) the values a report shows run ahead of the head: GRBL prepares
#: step segments of 10 ms ahead of the one executing (a buffer of 6 holds up to 5 of
#: them), and ``FS:`` shows the last prepared. The head is still braking into the end of a
#: stroke while the report already shows the feed and the M4 power of its stop (0).
PREP_LEAD_S = 0.05
#: The reported S against the S the program's S and the report's own feed imply: the
#: report prints both as integers (0.5), 2 % of S for $30/PWM rounding and float error,
#: and, for a firmware that samples the two a moment apart, POWER_SKEW_S seconds of
#: acceleration of the feed (GRBL 1.1 takes both from the same prepared segment). The S of a
#: flipped digit (S700 -> S600) lies outside at full speed; a missing digit (S70) at any.
POWER_SHARE = 0.02
POWER_SKEW_S = 0.002
_LEG = -2  # path_line of the leg from where the head stood to the program's first move


class StopReason(str, Enum):
    """Why a stream ended (a ``str`` so that results compare and serialise as text)."""

    DONE = "done"
    CHECKED = "checked"
    ERROR = "error"
    ALARM = "alarm"
    RESET = "reset"
    GARBLED = "garbled"
    UNMATCHED = "unmatched"
    OFF_PATH = "off_path"
    FEED = "feed"
    POWER = "power"
    TIMEOUT = "timeout"
    HOLD = "hold"
    DISCONNECT = "disconnect"
    STOPPED = "stopped"
    INTERRUPTED = "interrupted"

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True)
class Breach:
    """A watchdog's finding: why to stop, in one sentence, and the program line (0-based,
    or None) nearest to where the head was."""

    reason: StopReason
    detail: str
    line: int | None


#: Bytes of a status report with MPos, Bf and FS at full width (WCO and Ov come now and
#: then on top): what one poll costs the controller's transmit line.
REPORT_BYTES = 60
#: The share of the controller's transmit line the reports may take.
REPORT_SHARE = 0.5


def report_spacing(baud: float | None) -> float:
    """Wall seconds between reports so that they fill at most REPORT_SHARE of a ``baud``
    8N1 line (10 bits per byte); 0 when the line is not a real one (no baud)."""
    if not baud or not math.isfinite(baud) or baud <= 0:
        return 0.0
    return REPORT_BYTES / (REPORT_SHARE * baud / 10.0)


#: The travel within which the issue asks a deviation to be caught (mm).
CATCH_MM = 2.0


def catch_travel_mm(feed: float, interval: float, baud: float | None, *,
                    time_scale: float = 1.0, queued_bytes: int = 127) -> float:
    """Worst-case travel (mm) at ``feed`` (mm/min) from the head crossing the deviation
    limit to the host holding a report that shows it: the poll interval, then on a real
    line the ``?`` waiting behind ``queued_bytes`` of lines and the report's own
    transmission (10 bits per byte)."""
    line = (queued_bytes + REPORT_BYTES) * 10.0 / baud if baud else 0.0
    return feed / 60.0 * time_scale * (interval + line)


def poll_interval(fastest_feed: float, time_scale: float, *, watch_mm: float = 0.5,
                  shortest: float = 2e-4, longest: float = 0.2,
                  baud: float | None = None) -> float:
    """Wall seconds between status polls so that the head moves at most ``watch_mm``
    between two reports at ``fastest_feed`` (mm/min), on a machine whose time runs
    ``time_scale`` times the wall clock, and never closer than the line carries
    (:func:`report_spacing`)."""
    if fastest_feed <= 0 or not math.isfinite(fastest_feed):
        return longest
    wall = watch_mm / (fastest_feed / 60.0 * max(time_scale, 1e-9))
    return float(min(max(wall, shortest, report_spacing(baud)), longest))


class Watchdog:
    """Judges each status report against the program; ``check`` returns a Breach or None.

    ``path`` is the program's motion sampled at most ``step`` mm apart, ``path_line`` the
    program line of each sample and ``line_power`` the S each line cuts with (0: beam
    off); ``feeds`` and ``powers`` are what beam-on moves ask for (all empty for a knife:
    then only the path is watched). The head is followed along the path in program order,
    so where the path crosses itself the report is matched to the move being run, and
    what the beam must be doing there is known.
    """

    def __init__(self, path: np.ndarray, path_line: np.ndarray, line_power: np.ndarray,
                 feeds: tuple[float, ...], powers: tuple[float, ...], acceleration: float,
                 fastest: float, *, time_scale: float = 1.0, deviation_mm: float = 0.3,
                 watch_mm: float = 0.5, step: float = 1.0, baud: float | None = None,
                 pairs: tuple[tuple[float, float], ...] = (), dynamic: bool = True,
                 min_s: float = 0.0, junction_deviation: float = DEFAULT_JUNCTION_DEVIATION):
        self.path = np.asarray(path, float).reshape(-1, 2)
        self.path_line = np.asarray(path_line, int)
        self.line_power = np.asarray(line_power, float)
        self.feeds = tuple(feeds)
        self.powers = np.asarray(powers, float)
        # the (S, F) of every beam-on move; without them each S with the slowest feed
        pairs = pairs or tuple((p, min(self.feeds, default=1.0)) for p in powers)
        self.pair_s, self.pair_f = np.asarray(pairs, float).reshape(-1, 2).T
        self.dynamic = dynamic
        self.min_s = float(min_s)  # GRBL's $31: a value below it is reported as $31
        self.time_scale = float(time_scale)
        self.deviation = float(deviation_mm)
        self.step = float(step)
        self.fastest = float(fastest) / 60.0  # mm/s, the bound on how far the head can go
        self.acceleration = float(acceleration)
        self.junction_deviation = float(junction_deviation)  # GRBL's $11
        self.interval = poll_interval(max(self.feeds, default=0.0), self.time_scale,
                                      watch_mm=watch_mm, baud=baud)
        self.catch_mm = catch_travel_mm(max(self.feeds, default=0.0), self.interval, baud,
                                        time_scale=self.time_scale)
        slow = min(self.feeds, default=0.0) / 60.0
        latency = 2.0 * self.interval * self.time_scale  # two polls, in machine time
        # a corner's braking and re-acceleration plus the polls' latency, in machine time
        self.feed_allowance = 3.0 * slow / max(acceleration, 1e-9) + 0.1 + latency + PREP_LEAD_S
        # M4 power comes with its block: the polls' latency before the beam is on, and the
        # reports' lead over the head at the end of a stroke
        self.dark_allowance = 0.02 + latency + PREP_LEAD_S
        self._along = np.zeros(0)
        self._leg_end = 0
        self._reindex()
        self._at = 0.0  # how far along the path the head is (mm)
        self._last_asked: float | None = None
        self._slow_since: float | None = None
        self._dark_since: float | None = None
        self.last_line: int | None = None
        self.reports = 0

    @classmethod
    def for_program(cls, check, acceleration: float, fastest: float, **kw) -> Watchdog:
        """The watchdog over a validated program's ``Check``."""
        return cls(check.path, check.path_line, check.line_power, check.cut_feeds,
                   check.cut_powers, acceleration, fastest, pairs=check.cut_pairs,
                   dynamic=check.dynamic_power, **kw)

    def _reindex(self) -> None:
        """Distance along the path of every sample, and where each line's samples begin
        and end along it."""
        d = np.hypot(*np.diff(self.path, axis=0).T) if len(self.path) > 1 else np.zeros(0)
        self._along = np.concatenate([[0.0], np.cumsum(d)])
        n = int(self.path_line.max()) + 1 if len(self.path_line) else 0
        self._line_from = np.full(n, np.inf)
        self._line_to = np.full(n, -np.inf)
        ok = self.path_line >= 0
        np.minimum.at(self._line_from, self.path_line[ok], self._along[ok])
        np.maximum.at(self._line_to, self.path_line[ok], self._along[ok])
        self._motion_lines = np.flatnonzero(np.isfinite(self._line_to))
        self._knots = np.unique(self._along)  # the samples' distances, repeats dropped
        self.corners = CornerSpeeds(self.path, self.path_line, self._along, self.acceleration,
                                    self.junction_deviation)

    def start_from(self, here: np.ndarray | None) -> None:
        """The first rapid starts wherever the head is: add that leg to the path."""
        if here is None or not len(self.path):
            return
        k = max(1, int(math.ceil(float(np.hypot(*(self.path[0] - here))) / self.step)))
        leg = here + (self.path[0] - here) * np.linspace(0.0, 1.0, k + 1)[:, None]
        self.path = np.vstack([leg, self.path])
        # the leg belongs to the program's first rapid, which has no samples of its own
        self.path_line = np.concatenate([np.full(len(leg), _LEG), self.path_line])
        self._leg_end = len(leg) - 1
        self._reindex()

    def follow(self, xy: np.ndarray, reach: float) -> tuple[float, int, float]:
        """Match ``xy`` to the path from where the head was: within ``reach`` mm further
        if it is there, else anywhere ahead. Returns (distance, segment index, position
        along the segment 0..1) of the earliest match within the deviation that is not
        behind the head's last position (progress is minimal where the path crosses
        itself, and never goes back where it doubles back on itself), else of the
        nearest one."""
        if len(self.path) < 2:
            return math.inf, -1, 0.0
        lo = max(int(np.searchsorted(self._along, self._at - self.step, "right")) - 1, 0)
        hi = int(np.searchsorted(self._along, self._at + reach, "right"))
        found = self._nearest(xy, lo, min(max(hi, lo + 1), len(self.path) - 1))
        if found[0] > self.deviation:  # not where the clock says: look further ahead
            found = self._nearest(xy, lo, len(self.path) - 1)
        return found

    def _nearest(self, xy: np.ndarray, lo: int, hi: int) -> tuple[float, int, float]:
        idx = np.arange(lo, max(hi, lo + 1))
        a, b = self.path[idx], self.path[idx + 1]
        ab = b - a
        t = np.clip(np.einsum("ij,ij->i", xy - a, ab)
                    / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0.0, 1.0)
        d = np.hypot(*(a + t[:, None] * ab - xy).T)
        near = d <= self.deviation
        # The head only moves forward along the program. Where the path doubles back (a
        # cut that starts back along the rapid which brought the head to its start, as
        # when a resumed job re-cuts the piece the head stopped on), a point is near both
        # ways; the way already travelled would put a cutting head on the rapid.
        along = self._along[idx] + t * (self._along[idx + 1] - self._along[idx])
        ahead = np.flatnonzero(near & (along >= self._at - 1e-6))
        behind = np.flatnonzero(near)
        if len(ahead):
            j = int(ahead[0])
        elif len(behind):  # a report a hair behind the last one (rounding at a corner)
            j = int(behind[np.argmax(along[behind])])
        else:
            j = int(np.argmin(d))
        return float(d[j]), int(idx[j]), float(t[j])

    def check(self, st: Status, xy: np.ndarray | None, asked: float, received: float,
              starved: bool = False) -> Breach | None:
        """Judge one report asked for at machine time ``asked`` and read at ``received``
        (seconds): the machine was in that state somewhere in between. ``starved``: the
        sender has nothing in flight (the planner may be running dry)."""
        self.reports += 1
        if st.overrides is not None and st.overrides != (100, 100, 100):
            return self._override_breach(st.overrides)
        now = asked
        # at most this much machine time since the previous report (an upper bound)
        dt = 0.5 if self._last_asked is None else received - self._last_asked
        # timers run only over reports close enough together to see every slow-down end
        close = dt <= self.feed_allowance / 3.0
        if not close:
            self._slow_since = self._dark_since = None
        self._last_asked = asked
        inside = None  # the line whose interior the head is on, if any
        # A head at rest is followed too: the stroke-start gate (Streamer._at_start) sees
        # it Idle at a cut's start, and a short rapid may run between two polls; without
        # that report the cut would be matched from where the head was before the rapid.
        # Only a moving head is judged off the path (at rest before the first move it
        # may stand anywhere).
        if xy is not None and st.state in ("Run", "Hold", "Jog", "Idle"):
            d, k, t = self.follow(xy, self.fastest * dt + 2.0 + self.deviation)
            if d > self.deviation and st.state != "Idle":
                return Breach(StopReason.OFF_PATH, f"head at X{xy[0]:.3f} Y{xy[1]:.3f} is "
                              f"{d:.2f} mm off the program's path (corrupted line?)",
                              self.last_line)
            if d <= self.deviation:
                inside = self._reached(k, t)
        if st.state != "Run" or not len(self.powers):
            self._slow_since = self._dark_since = None
            return None
        if not (st.speed or 0.0) > 0:
            self._slow_since = None
            if not (st.feed or 0.0) > 0:  # at rest, or the segment braking to it: under M4
                self._dark_since = None  # a healthy beam is off there, a lost one not seen
                return None
            return self._check_dark(inside, now)
        self._dark_since = None
        return self._judge_beam(st, inside, now, starved)

    def _judge_beam(self, st: Status, inside: int | None, now: float, starved: bool
                    ) -> Breach | None:
        """A running report with the beam on: on a cutting line, at a power the program
        asks for at the feed shown, then the feed itself (`_judge_feed`)."""
        power = float(st.speed or 0.0)
        if inside == _LEG or (inside is not None and self.line_power[inside] <= 0):
            return Breach(StopReason.POWER, f"laser at S{power:g} on a travel move "
                          "(the cut starts off its path: a corrupted or rejected line?)",
                          inside if inside != _LEG else None)
        feed = float(st.feed or 0.0)
        if not self.power_is_healthy(power, feed):
            if self.dynamic and self.power_is_healthy(power, max(self.feeds)):
                # full M4 power at a feed the program never asks for: GRBL scales S by the
                # feed it was given, so it was given another F
                return Breach(StopReason.FEED, f"beam on at F{feed:g} with the full S{power:g}: "
                              "the machine runs at a programmed feed that is not the "
                              f"program's F{max(self.feeds):g} (corrupted F word?)",
                              self.last_line)
            return Breach(StopReason.POWER, f"laser at S{power:g} at F{feed:g} where the "
                          f"program's {self._asked_power(feed)} (corrupted S word?)",
                          self.last_line)
        return self._judge_feed(st, feed, now, starved)

    def _judge_feed(self, st: Status, feed: float, now: float, starved: bool
                    ) -> Breach | None:
        """The beam on at a feed the program asks for: never above its cutting feed, and
        below it no longer than the machine takes to reach it (corners and a starved
        planner slow it down legitimately)."""
        low, high = min(self.feeds), max(self.feeds)
        expected = low
        if st.planner_free is not None:  # Bf: reported ($10 has 2)
            starved = st.planner_free >= PLANNER_BLOCKS - 2
            # two blocks fewer than reported: the one being run is partly done, and one
            # more may end between GRBL sampling the speed and counting the free blocks
            expected = min(low, self.lookahead_feed(PLANNER_BLOCKS - st.planner_free - 2))
        # the corners within reach cap the speed (the feed shown is up to PREP_LEAD_S ahead)
        ahead = high / 60.0 * PREP_LEAD_S + 0.5
        expected = min(expected, 60.0 * self.corners.cap(self._at - 0.5, self._at + ahead,
                                                         high / 60.0))
        if starved:  # a machine the line cannot keep fed slows down, and M4 power with it
            self._slow_since = None
        if feed > high * 1.02 + 1.0:
            return Breach(StopReason.FEED, f"beam on at F{feed:g}, above the program's "
                          f"cutting feed F{high:g} (corrupted line?)", self.last_line)
        if feed >= 0.9 * expected or starved:
            self._slow_since = None
        elif self._slow_since is None:
            self._slow_since = now
        elif now - self._slow_since > self.feed_allowance:
            return Breach(StopReason.FEED, f"beam on at F{feed:g} for "
                          f"{now - self._slow_since:.2f} s of machine time: the programmed "
                          f"F{low:g} is reached within {self.feed_allowance:.2f} s "
                          "(corrupted F word?)", self.last_line)
        return None

    def expected_power(self, feed: float) -> np.ndarray:
        """The S a healthy GRBL reports for each of the program's (S, F) at reported ``feed``
        (mm/min): S x feed / F under M4, never above S (the feed never exceeds F unasked);
        S under M3."""
        if not self.dynamic:
            return self.pair_s.copy()
        return self.pair_s * np.minimum(max(feed, 0.0), self.pair_f) / self.pair_f

    def power_is_healthy(self, power: float, feed: float) -> bool:
        """Whether a reported S fits one of the program's (S, F) at the report's own feed,
        within the rounding and skew stated at POWER_SHARE (and $31's floor)."""
        if not len(self.pair_s):
            return False
        expected = self.expected_power(feed)
        skew = self.acceleration * 60.0 * POWER_SKEW_S * self.pair_s / self.pair_f \
            if self.dynamic else 0.0
        tolerance = 0.5 + POWER_SHARE * self.pair_s + skew
        fits = np.abs(expected - power) <= tolerance
        floor = (self.min_s > 0) & (abs(power - self.min_s) <= 0.5) & \
            (expected <= self.min_s + tolerance)
        return bool(np.any(fits | floor))

    def _asked_power(self, feed: float) -> str:
        """The program's S words and what they mean at ``feed``, for a breach's message."""
        if not self.dynamic:
            return "M3 asks for " + ", ".join(f"S{p:g}" for p in self.pair_s)
        return "M4 " + ", ".join(f"S{p:g} at F{f:g} means S{e:.0f}" for p, f, e in
                                 zip(self.pair_s, self.pair_f, self.expected_power(feed),
                                     strict=True))

    def _override_breach(self, ovr: tuple[int, int, int]) -> Breach:
        """Feed, rapid and spindle overrides are real-time bytes this host never sends: one
        made by line noise (0x91..0x9D) would cut faster or hotter than the program, and
        the piece would still count as cut."""
        feed, rapid, spindle = ovr
        reason = StopReason.POWER if spindle != 100 else StopReason.FEED
        return Breach(reason, f"overrides at feed {feed}%, rapid {rapid}%, spindle {spindle}% "
                      "that the host never sent (a real-time byte from the line?)",
                      self.last_line)

    def lookahead_feed(self, blocks: int) -> float:
        """The fastest feed (mm/min) GRBL may plan with ``blocks`` queued from the head's
        position: the last of them must be able to stop, so ``sqrt(2 a d)`` over the
        distance ``d`` they cover. Each queued block is taken as one program line, and no
        longer than the path's samples (an arc is many blocks): ``d`` errs short, the bound
        low, so a slow line never passes for a corrupted feed."""
        if self.last_line is None or blocks <= 0 or not len(self._motion_lines):
            return math.inf if blocks > 0 else 0.0
        k = int(np.searchsorted(self._motion_lines, self.last_line))
        last = self._motion_lines[min(k + blocks - 1, len(self._motion_lines) - 1)]
        by_lines = self._line_to[last] - self._at
        j = int(np.searchsorted(self._knots, self._at, "right"))
        by_samples = self._knots[min(j + blocks - 1, len(self._knots) - 1)] - self._at
        d = max(min(by_lines, by_samples), 0.0)
        return math.sqrt(2.0 * self.acceleration * d) * 60.0

    def _reached(self, k: int, t: float) -> int | None:
        """The head is at ``t`` along segment ``k``: move it there; the line whose interior
        that is (``_LEG`` for the leg), if any."""
        self._at = self._along[k] + t * (self._along[k + 1] - self._along[k])
        line = int(self.path_line[k])
        self.last_line = line if line >= 0 else None
        if line >= 0 and self._line_from[line] + 0.5 < self._at < self._line_to[line] - 0.5:
            return line
        if line == _LEG and self._at < self._along[self._leg_end] - 0.5:
            return _LEG
        return None

    def _check_dark(self, inside: int | None, now: float) -> Breach | None:
        """The beam off in the middle of a move that cuts: a lost ``M4`` (flipped to
        ``M5``) would trace the piece without cutting it, and it would count as cut."""
        if inside is None:  # at a line's end (a corner, where the head may stop): the
            return None  # timer runs on through the corners of one stroke, and stops nowhere
        if inside == _LEG or self.line_power[inside] <= 0:
            self._dark_since = None
            return None
        if self._dark_since is None:
            self._dark_since = now
        elif now - self._dark_since > self.dark_allowance:
            return Breach(StopReason.POWER, f"beam off for {now - self._dark_since:.2f} s "
                          f"of machine time on a move that cuts at "
                          f"S{self.line_power[inside]:g} (a lost M4?)", inside)
        return None
