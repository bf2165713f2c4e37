"""The watchdog follows the head forward along the program, also where the path doubles back.

A resumed job re-cuts the piece the head stopped on from that piece's start: the rapid from
where the head rests to the start runs back along the first cut, so every point of that
cut's first stretch is near the rapid too. Matched to the rapid, the cutting beam looked
like a beam on a travel move and a legitimate resumed cut was stopped (the flaky crash test,
`tests/station/test_crash.py`). The beam on a real travel move must still stop the machine.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
import serial

import simulators.grbl  # noqa: F401  (registers grblsim://)
from gcode.grbl import Status
from gcode.layout import layout_from_dict
from gcode.machine import default_machine
from gcode.program import build_program, strip_comment, validate
from gcode.stream import Streamer, StreamError
from gcode.toolpath import build_toolpaths
from gcode.watchdog import Breach, StopReason, Watchdog

SETTINGS = "settings=32:1,130:1600,131:1000,110:12000,111:12000,120:1500,121:1500"
MACHINE = default_machine()
FEED, POWER = MACHINE.cut.feed, MACHINE.cut.power
SQUARE = [f"G1 X60 Y20 F{FEED:g}", "G1 X60 Y60", "G1 X20 Y60", "G1 X20 Y20"]


def square_program(*travel: str) -> list[str]:
    """A 40 mm square cut from (20, 20) towards +X, after the given travel lines."""
    return ["G21", "G90", *travel, "G0 X20 Y20", f"M4 S{POWER:g}", *SQUARE, "M5", "G0 X0 Y0"]


def drive(wd: Watchdog, moves: list[tuple[np.ndarray, np.ndarray, bool]],
          step: float = 0.4, t: float = 0.0) -> Breach | None:
    """Report the head every ``step`` mm along each (from, to, beam on) move, in order,
    from machine time ``t`` on."""
    for a, b, beam in moves:
        n = max(1, int(np.ceil(np.hypot(*(b - a)) / step)))
        for xy in a + (b - a) * np.linspace(0.0, 1.0, n + 1)[1:, None]:
            t += step / (FEED / 60.0)
            st = Status("Run", wpos=(xy[0], xy[1], 0.0), feed=FEED if beam else 12000.0,
                        speed=POWER if beam else 0.0, planner_free=5)
            breach = wd.check(st, xy, t, t)
            if breach is not None:
                return breach
    return None


def square_moves(start: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, bool]]:
    corners = np.array([[20, 20], [60, 20], [60, 60], [20, 60], [20, 20]], float)
    rapid = [(start, corners[0], False)]
    return rapid + [(corners[k], corners[k + 1], True) for k in range(4)]


def watchdog(lines: list[str], here: tuple[float, float] | None) -> Watchdog:
    wd = Watchdog.for_program(validate(lines, MACHINE), MACHINE.acceleration, 12000.0)
    wd.start_from(None if here is None else np.array(here, float))
    return wd


@pytest.mark.parametrize("rest", [(40.0, 20.0), (59.0, 20.1), (20.5, 20.0)])
def test_a_cut_that_starts_back_along_the_leg_from_the_rest_position_is_followed(rest):
    """The head rests on the square's first edge (where an interrupted attempt stopped);
    the resumed program's rapid to (20, 20) runs back along that edge."""
    here = np.array(rest)
    wd = watchdog(square_program(), rest)
    assert drive(wd, square_moves(here)) is None
    assert wd.last_line == square_program().index("G1 X20 Y20")


def test_a_rapid_seen_only_at_rest_at_both_ends_still_puts_the_cut_after_it():
    """Under load no report may fall inside a short rapid: the head is seen Idle where it
    rests, then Idle at the cut's start (the report that lets the beam come on), then
    cutting. The cut is matched after the rapid, not on it."""
    for rapid_seconds in (0.5, 0.001):  # 0.001: a machine faster than the host's clock
        wd = watchdog(square_program(), (40.0, 20.0))
        for t, xy in ((0.1, (40.0, 20.0)), (0.1 + rapid_seconds, (20.0, 20.0))):
            assert wd.check(Status("Idle", wpos=(*xy, 0.0)), np.array(xy), t, t) is None
        # polled every 1 mm of cut (the streamer's watch_mm): the first report is 1 mm in
        moves = square_moves(np.array([20.0, 20.0]))[1:]
        assert drive(wd, moves, step=1.0, t=0.1 + rapid_seconds) is None
    # a head at rest off the path is no fault (it may stand anywhere before the first move)
    wd = watchdog(square_program(), None)
    assert wd.check(Status("Idle", wpos=(5.0, 5.0, 0.0)), np.array([5.0, 5.0]), 0.1, 0.1) is None


def test_a_cut_that_starts_back_along_a_travel_move_of_the_program_is_followed():
    """The same doubling back inside one program: a rapid over the first edge, then the
    cut along it the other way."""
    lines = square_program("G0 X50 Y20")
    wd = watchdog(lines, (0.0, 0.0))
    moves = [(np.zeros(2), np.array([50.0, 20.0]), False)] + square_moves(np.array([50.0, 20]))
    assert drive(wd, moves) is None


@pytest.mark.parametrize("travel", [(), ("G0 X50 Y20",)])
def test_a_beam_on_the_travel_move_over_a_later_cut_still_stops(travel):
    """Safety is kept: the beam on during the rapid (which runs over the first edge the
    cut will take) is a beam on a travel move, whichever edge it overlaps."""
    lines = square_program(*travel)
    here = np.array([50.0, 20.0]) if travel else np.array([40.0, 20.0])
    wd = watchdog(lines, (0.0, 0.0) if travel else tuple(here))
    moves = ([(np.zeros(2), here, False)] if travel else []) + [
        (here, np.array([20.0, 20.0]), True)]
    breach = drive(wd, moves)
    assert breach is not None and breach.reason == StopReason.POWER, breach
    assert "travel move" in breach.detail


def test_a_resumed_job_re_cuts_the_piece_the_head_stopped_on():
    """End to end on the emulator: the head parked half way along the first edge of a
    square (as a stop mid-piece leaves it), the program cuts the square from its start.
    Before the fix every such run stopped with 'laser at S... on a travel move'."""
    data = {"version": 1, "units": "mm",
            "pieces": [{"id": "sq", "outline": [[100, 100], [160, 100], [160, 160],
                                                [100, 160]]}]}
    prog = build_program(build_toolpaths(layout_from_dict(data, "sq"), MACHINE), MACHINE)
    code = [strip_comment(ln) for ln in prog.lines]
    on = next(i for i, ln in enumerate(code) if ln.startswith("M4"))
    words = [dict((w[0], float(w[1:])) for w in code[k].split()[1:]) for k in (on - 1, on + 1)]
    start, first = (np.array([w["X"], w["Y"]]) for w in words)
    assert code[on - 1].startswith("G0") and np.hypot(*(first - start)) > 20
    rest = start + 0.6 * (first - start)  # on the first edge, well inside it
    port = serial.serial_for_url(f"grblsim://?speed=10&{SETTINGS}", timeout=0.02)
    try:
        st = Streamer(port, response_timeout=3.0, stall_timeout=3.0)
        st.connect()
        assert st.command(f"G0 X{rest[0]:.3f} Y{rest[1]:.3f}")[0].kind == "ok"
        assert st._wait_status(lambda s: s.state == "Idle", 10.0)
        res = st.run(prog)
        assert res.completed and res.reason == "done", res.fault
        assert res.pieces_cut == 1
        em = port.emulator
        burnt = [s for s in em.trace if s.power > 0 and not s.rapid]
        assert burnt and not any(s.rapid and s.power > 0 for s in em.trace)
        assert np.allclose([burnt[0].x0, burnt[0].y0], start, atol=1e-3)
    finally:
        port.close()


def short_segment_lines(seg: float = 0.1, length: float = 40.0) -> list[str]:
    """A straight cut from (20, 20) along +X in ``seg`` mm lines, as a polyline job
    without arcs sends it."""
    xs = 20.0 + seg * np.arange(1, int(round(length / seg)) + 1)
    return ["G21", "G90", "G0 X20 Y20", f"M4 S{POWER:g}", f"G1 X{xs[0]:.3f} Y20 F{FEED:g}",
            *(f"G1 X{x:.3f} Y20" for x in xs[1:]), "M5", "G0 X0 Y0"]


def crawl(wd: Watchdog, feed: float, planner_free: int, seconds: float = 2.0) -> Breach | None:
    """Reports of a head cutting along the line at ``feed`` with ``planner_free`` free
    planner blocks, every 0.1 mm (from x = 20.5 on), for ``seconds`` of machine time. M4
    scales the reported S with the feed, as GRBL does."""
    v = feed / 60.0
    t = 0.0
    for x in np.arange(20.5, 59.0, 0.1):
        t = (x - 20.5) / v
        if t > seconds:
            break
        st = Status("Run", wpos=(x, 20.0, 0.0), feed=feed,
                    speed=POWER * min(feed, FEED) / FEED, planner_free=planner_free)
        breach = wd.check(st, np.array([x, 20.0]), t, t)
        if breach is not None:
            return breach
    return None


def test_a_planner_the_line_cannot_fill_may_run_as_slow_as_its_look_ahead_and_no_slower():
    """GRBL plans so that the last queued block can stop: with n blocks of 0.1 mm queued
    the head goes no faster than sqrt(2 a n 0.1 mm). A job of short lines on a line that
    cannot keep the planner full runs that slow, and was stopped as a corrupted feed; a
    machine slower than its queue allows is still stopped (a corrupted F word)."""
    lines = short_segment_lines()
    a = MACHINE.acceleration
    for queued in (4, 5):
        wd = watchdog(lines, (20.0, 20.0))
        assert crawl(wd, FEED, 0, seconds=0.0) is None  # one report: the head is at 20.5
        reach = float(np.sqrt(2.0 * a * queued * 0.1)) * 60.0  # mm/min
        assert reach < 0.9 * FEED
        assert wd.lookahead_feed(queued) > 0.8 * reach  # half a line is left of the first
        # the bound errs short (never above what the queued lines allow)
        assert wd.lookahead_feed(queued) <= reach * 1.001
        # judged on two blocks fewer than reported (one partly run, one may just end)
        allowed = wd.lookahead_feed(queued - 2)
        assert crawl(wd, 0.95 * allowed, 15 - queued) is None, queued
        wd = watchdog(lines, (20.0, 20.0))
        breach = crawl(wd, 0.5 * allowed, 15 - queued)
        assert breach is not None and breach.reason == StopReason.FEED, (queued, breach)
    # a full planner (what F1 does: the line fills it) leaves the programmed feed due
    wd = watchdog(lines, (20.0, 20.0))
    breach = crawl(wd, 0.6 * FEED, 0)
    assert breach is not None and breach.reason == StopReason.FEED


def test_a_line_limited_job_cuts_through_a_real_time_115200_baud_line_with_the_watchdog():
    """End to end: 0.05 mm lines at 3000 mm/min ask for 1000 lines/s, the 115200-baud line
    carries ~680: the planner runs short and the machine slows to its look-ahead. Before
    the fix every such run stopped 'beam on at F3954 ... (corrupted F word?)'. The polls
    are spaced for the receive line: the reports leave room for the `ok`s."""
    from gcode.watchdog import report_spacing

    prog = _ring_program(step=0.05, feed=3000.0)
    assert sum(ln.startswith("G1") for ln in prog.lines) > 900
    port = serial.serial_for_url(f"grblsim://?speed=1&baud=115200&{SETTINGS},10:3",
                                 timeout=0.02)
    try:
        st = Streamer(port)
        st.connect(quiet=0.05)
        assert st.line_baud == 115200
        rx0 = port.wire.bytes_to_host
        res = st.run(prog)
        assert res.completed and res.reason == "done", res.fault
        assert res.pieces_cut == 1
        assert st.watchdog.interval >= report_spacing(115200) > 0
        assert (port.wire.bytes_to_host - rx0) / res.seconds < 0.85 * 11520
        assert st.watchdog.catch_mm <= 2.0
        burnt = [s for s in port.emulator.trace if s.power > 0]
        assert burnt and min(s.feed for s in burnt) == 3000.0
    finally:
        port.close()


def _ring_program(*, step: float, feed: float):
    """A laser program cutting a 16 mm circle in chords of ``step`` mm at ``feed``."""
    t = np.linspace(0.0, 2 * np.pi, int(round(2 * np.pi * 8 / step)), endpoint=False)
    ring = np.c_[60 + 8 * np.cos(t), 60 + 8 * np.sin(t)]
    data = {"version": 1, "units": "mm", "pieces": [{"id": "o", "outline": ring.tolist()}]}
    m = MACHINE.with_cut(arcs=False, kerf=0.0, feed=feed, tolerance=0.001)
    return build_program(build_toolpaths(layout_from_dict(data, "ring"), m), m)


def test_a_beam_feed_the_line_cannot_watch_is_refused_before_anything_moves():
    """At 6000 mm/min a 115200-baud line cannot show a deviation within 2 mm of travel:
    the laser job is refused, naming the fastest feed it could watch, and nothing runs."""
    prog = _ring_program(step=0.5, feed=6000.0)
    port = serial.serial_for_url(f"grblsim://?speed=1&baud=115200&{SETTINGS},10:3",
                                 timeout=0.02)
    try:
        st = Streamer(port)
        st.connect(quiet=0.05)
        with pytest.raises(StreamError, match=r"cut at most F(\d+)") as err:
            st.run(prog)
        fastest = float(re.search(r"cut at most F(\d+)", str(err.value)).group(1))
        assert 3000.0 < fastest < 6000.0
        assert not [s for s in port.emulator.trace if s.power > 0]
    finally:
        port.close()


def test_the_travel_before_a_deviation_shows_counts_the_line():
    """Polls every watch_mm of travel; on a real line the `?` may wait behind a buffer of
    lines and the report takes its own time: at 115200 baud 3000 mm/min is caught within
    2 mm, 6000 is not (the streamer says so). The emulator's instant link adds nothing, at
    any speed."""
    from gcode.watchdog import CATCH_MM, catch_travel_mm, poll_interval

    lines = square_program()
    check = validate(lines, MACHINE)
    for feed, baud, within in ((3000.0, 115200, True), (6000.0, 115200, False),
                               (6000.0, 250000, True)):
        wd = Watchdog(check.path, check.path_line, check.line_power, (feed,),
                      check.cut_powers, MACHINE.acceleration, 12000.0, watch_mm=1.0,
                      baud=baud)
        assert (wd.catch_mm <= CATCH_MM) == within, (feed, baud, wd.catch_mm)
        assert wd.catch_mm > 1.0  # never less than the polls' own spacing
    for speed in (1.0, 50.0):
        interval = poll_interval(6000.0, speed, watch_mm=1.0)
        assert abs(catch_travel_mm(6000.0, interval, None, time_scale=speed) - 1.0) < 1e-9


@pytest.mark.parametrize("feed,stops", [(0.0, False), (FEED, True)])
def test_the_beam_off_mid_cut_stops_the_job_only_while_the_head_moves(feed, stops):
    """Under M4 GRBL reports S0 whenever the prepared segment's speed is 0: a head braking to
    rest mid-line (a sender that fell behind, a starved planner) is dark and healthy. A head
    moving with the beam off is a lost M4, and must stop the job."""
    wd = watchdog(square_program(), (0.0, 0.0))
    start = np.array([20.0, 20.0])
    assert drive(wd, [(np.array([0.0, 0.0]), start, False),
                      (start, np.array([40.0, 20.0]), True)]) is None
    xy, breach, t = np.array([40.0, 20.0]), None, 10.0
    for _ in range(50):  # half a second of machine time, reported every 10 ms
        t += 0.01
        st = Status("Run", wpos=(40.0, 20.0, 0.0), feed=feed, speed=0.0, planner_free=5)
        breach = breach or wd.check(st, xy, t, t)
    assert (breach is not None) == stops
    if stops:
        assert breach.reason == StopReason.POWER and "beam off" in breach.detail
