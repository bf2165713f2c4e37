"""The machine's time scale, learned from the machine (issue 16): a sender on a pty cannot
see the emulator's ``speed``, so the emulator's ``$I`` says it, and the watchdogs are paced
by it. Judged on the emulator's executed motion, as tests/gcode/test_faults.py judges."""

from __future__ import annotations

import sys
import threading
from pathlib import Path

import numpy as np
import pytest
import serial

from gcode.grbl import time_scale_of
from gcode.stream import Streamer
from simulators.grbl import Faults, GrblEmulator
from simulators.grbl.pty import PtyBridge

sys.path.insert(0, str(Path(__file__).parent))  # test_faults (importlib mode)
import test_faults  # noqa: E402
from test_faults import judge, wire_lines  # noqa: E402

tiny = test_faults.tiny  # the fixture: two 6 mm squares, half a second of cutting

SETTINGS = {32: 1, 130: 1600, 131: 1000, 110: 12000, 111: 12000, 120: 1500, 121: 1500}
SPEED = 50.0


def test_time_scale_is_read_from_the_build_info_only():
    assert time_scale_of("1.1h.20190830:grblsim speed=50") == 50.0
    assert time_scale_of("1.1h.20190830:my table grblsim speed=0.5") == 0.5
    assert time_scale_of("1.1h.20190825:") == 1.0  # a real GRBL
    assert time_scale_of("1.1h.20190825:speed=50") == 1.0  # someone's own $I= text
    assert time_scale_of("1.1h.20190830:grblsim speed=0") == 1.0


class ArmedPort:
    """The pty as a sender opens it, arming the emulator's ``kind`` fault at byte
    ``offset`` of the ``line``-th program line when that line goes out. The emulator
    counts every byte it received, and the pty delivers them in order, so the position is
    this port's own count of bytes written (the emulator may not have read them all yet).
    The streamer sees only the serial port: no ``emulator`` attribute to read a speed from.
    """

    _own = ("port", "em", "lines", "kind", "line", "offset", "next", "written")

    def __init__(self, port, emulator, lines: list[bytes], kind: str, line: int, offset: int):
        self.port, self.em, self.lines = port, emulator, lines
        self.kind, self.line, self.offset, self.next, self.written = kind, line, offset, 0, 0

    def __getattr__(self, name):
        return getattr(self.port, name)

    def __setattr__(self, name, value):
        if name in self._own:
            object.__setattr__(self, name, value)
        else:
            setattr(self.port, name, value)

    def write(self, data):
        if self.next < len(self.lines) and data == self.lines[self.next]:
            if self.next == self.line:
                getattr(self.em.faults, f"{self.kind}_byte_at").add(
                    self.written + self.offset + 1)
            self.next += 1
        self.written += len(data)
        return self.port.write(data)


def stream_on_pty(prog, line: int, offset: int, time_scale: float | None = None,
                  paced: bool = False):
    """Stream ``prog`` through a pty to an emulator at SPEED with one byte flipped;
    unpaced as `station sim-grbl --pty` serves it, or ``paced`` (the machine waits for a
    host that keeps writing, see GrblEmulator.HOST_STEP). Returns (emulator, result,
    streamer)."""
    em = GrblEmulator(speed=SPEED, faults=Faults(), settings=dict(SETTINGS), paced=paced)
    bridge = PtyBridge(em)
    stop = threading.Event()
    server = threading.Thread(target=bridge.serve, args=(stop,), daemon=True)
    server.start()
    try:
        with serial.Serial(bridge.path, 115200, timeout=0.02) as raw:
            port = ArmedPort(raw, em, wire_lines(prog), "flip", line, offset)
            st = Streamer(port, response_timeout=2.0, stall_timeout=1.0, time_scale=time_scale)
            st.connect(quiet=0.05)
            res = st.run(prog)
        judge(prog, em, res)
        return em, res, st
    finally:
        stop.set()
        server.join(5)
        bridge.close()
        em.close()


def _burn_seconds(em, below_feed: float) -> float:
    """Machine seconds the beam was on while moving slower than ``below_feed`` mm/min."""
    segs = [s for s in em.trace if s.power > 0 and not s.rapid and 0 < s.feed < below_feed]
    return float(sum(np.hypot(s.x1 - s.x0, s.y1 - s.y0) / s.feed * 60.0 for s in segs))


def test_a_g_to_f_flip_on_a_pty_at_speed_50_is_stopped_in_machine_time(tiny):
    """`G1X..` -> `F1X..`: beam on at 1 mm/min, on the unpaced machine `station sim-grbl
    --pty` serves. The sender learns the speed from `$I`, so the feed watchdog gives the
    machine its acceleration time (0.24 s) in machine seconds, not in wall seconds: the
    beam dwells a fraction of a second plus the stop's latency (0.3 s here on an idle
    host), where wall-clock pacing let it dwell 13.4 s; and nothing burns more than 2 mm
    off the path (judge). The bound leaves the stop 100 ms of wall time on a busy host."""
    lines = wire_lines(tiny)
    k = next(i for i, ln in enumerate(lines) if ln.startswith(b"G1") and b"F" not in ln)
    em, res, st = stream_on_pty(tiny, k, 0)
    assert st.time_scale == SPEED
    assert res.reason == "feed" and not res.completed, res.fault
    assert _burn_seconds(em, 100.0) < 0.24 + 0.1 * SPEED


def test_an_off_path_flip_on_a_pty_at_speed_50_burns_under_2_mm_off_the_path(tiny):
    """`X26` -> `X36` with the beam on: polls paced in machine time catch the head within
    2 mm of the path (judge measures the burnt trace), where polls paced by the wall clock
    let it run 50 times as far between two looks (6.9 mm, and the job reported done).
    The machine is paced by the host's writes: unpaced, 1 ms of wall time is 2.5 mm of
    travel at 3000 mm/min and speed 50, closer than any host can poll a pty."""
    lines = wire_lines(tiny)
    i = next(i for i, ln in enumerate(lines) if ln.startswith(b"G1X2"))
    em, res, _ = stream_on_pty(tiny, i, lines[i].index(b"2"), paced=True)
    assert not res.completed and res.reason in ("off_path", "feed", "power"), res.fault


@pytest.mark.parametrize("scale", [None, 1.0])
def test_a_given_time_scale_wins_over_the_machines_word(tiny, scale):
    """What the caller states is used as is (a real GRBL behind a pty is 1)."""
    em = GrblEmulator(speed=SPEED, settings=dict(SETTINGS), paced=False)
    bridge = PtyBridge(em)
    stop = threading.Event()
    server = threading.Thread(target=bridge.serve, args=(stop,), daemon=True)
    server.start()
    try:
        with serial.Serial(bridge.path, 115200, timeout=0.02) as raw:
            st = Streamer(raw, time_scale=scale)
            st.connect(quiet=0.05)
            assert st.time_scale == (SPEED if scale is None else scale)
    finally:
        stop.set()
        server.join(5)
        bridge.close()
        em.close()
