"""Laser mode as GRBL 1.1 runs it (issue 32): under M4 the firmware scales the power with the
speed of every step segment it prepares and reports that value in ``FS:``. The station's
programs must cut to the end with the power watchdog on, at emulator speeds 1 and 50, and
the watchdog must still stop a corrupted S, power on a rapid and power after M5.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import serial

import simulators.grbl  # noqa: F401  (registers grblsim://)
from gcode.grbl import Status
from gcode.layout import layout_from_dict
from gcode.machine import default_machine
from gcode.program import Program, build_program, validate
from gcode.stream import Streamer, StreamError
from gcode.toolpath import build_toolpaths
from gcode.watchdog import StopReason, Watchdog

sys.path.insert(0, str(Path(__file__).parent))  # gcode_helpers (importlib mode)
from gcode_helpers import make_layout, trace  # noqa: E402

SETTINGS = "settings=32:1,130:1600,131:1000,110:12000,111:12000,120:1500,121:1500"


def _star(cx: float, cy: float, spikes: int = 10) -> list[list[float]]:
    """A star of sharp spikes: corners of 40 degrees where GRBL brakes almost to a stop."""
    angle = np.linspace(0.0, 2 * np.pi, 2 * spikes, endpoint=False)
    radius = np.where(np.arange(2 * spikes) % 2 == 0, 8.0, 3.0)
    return np.c_[cx + radius * np.cos(angle), cy + radius * np.sin(angle)].tolist()


def _wiggle(cx: float, cy: float) -> list[list[float]]:
    """A wavy outline in 0.3 mm lines (arcs off): short segments and a corner every few."""
    t = np.linspace(0.0, 2 * np.pi, 120, endpoint=False)
    r = 5.0 + 0.6 * np.sin(15 * t)
    return np.c_[cx + r * np.cos(t), cy + r * np.sin(t)].tolist()


@pytest.fixture(scope="module")
def sharp() -> Program:
    """Short segments and sharp corners: the power ramps at every one of them."""
    machine = default_machine().with_cut(arcs=False)
    data = {"version": 1, "units": "mm",
            "pieces": [{"id": "star", "outline": _star(30, 30)},
                       {"id": "wiggle", "outline": _wiggle(70, 30)}]}
    return build_program(build_toolpaths(layout_from_dict(data, "sharp"), machine), machine)


@pytest.fixture(scope="module")
def station_job() -> Program:
    """The station's own kind of program: curves fitted with arcs, holes, notches, marks."""
    machine = default_machine()
    return build_program(build_toolpaths(layout_from_dict(make_layout(), "job"), machine),
                         machine)


def _cut_path(prog: Program) -> tuple[np.ndarray, np.ndarray]:
    moves = [mv["pts"] for mv in trace(prog.lines, step=0.2) if mv["on"] and len(mv["pts"]) > 1]
    return np.vstack([p[:-1] for p in moves]), np.vstack([p[1:] for p in moves])


def _off_path(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    ap = points[:, None, :] - a[None]
    t = np.clip(np.einsum("nmk,mk->nm", ap, ab) / np.maximum((ab * ab).sum(1), 1e-12), 0, 1)
    return float(np.hypot(*(ap - t[..., None] * ab[None]).transpose(2, 0, 1)).min(axis=1).max())


def _cut_clean(prog: Program, speed: float) -> tuple[list[Status], list]:
    """Stream ``prog`` with the watchdog on; it must complete with every piece cut and the
    beam only on the program's path. Returns (status reports, traced segments)."""
    port = serial.serial_for_url(f"grblsim://?speed={speed}&{SETTINGS}", timeout=0.02)
    em = port.emulator
    reports: list[Status] = []
    st = Streamer(port, response_timeout=3.0, stall_timeout=3.0, on_status=reports.append)
    assert st.deviation_limit  # the watchdog is on
    st.connect(quiet=0.05)
    res = st.run(prog)
    assert res.completed and res.reason == "done", res.fault
    assert res.pieces_cut == len(prog.pieces)
    burnt = [s for s in em.trace if s.power > 0]
    ends = np.array([(s.x1, s.y1) for s in burnt] + [(s.x0, s.y0) for s in burnt])
    assert _off_path(ends, *_cut_path(prog)) <= 0.05
    assert not any(s.rapid and s.power > 0 for s in em.trace)
    port.close()
    return reports, list(em.trace)


@pytest.mark.parametrize("speed", [1, 50])
def test_sharp_corners_and_short_segments_cut_to_the_end_with_the_watchdog(sharp, speed):
    reports, segments = _cut_clean(sharp, speed)
    power = 700.0  # the profile's S
    running = [(r.feed, r.speed) for r in reports if r.state == "Run" and r.speed]
    assert running, "no report while cutting"
    # what the machine reported is S scaled by its own feed ...
    assert all(abs(s - power * min(f, 3000.0) / 3000.0) <= 1.0 for f, s in running)
    # ... and the ramps were seen: reports below S while the head sped up or braked
    assert any(0 < s < 0.9 * power for _, s in running)
    # the trace shows the power actually applied ramping with the speed at every corner
    cut = np.array([s.power for s in segments if not s.rapid and s.power > 0])
    assert (cut < 0.5 * power).sum() > 20 and cut.max() == pytest.approx(power)


def test_the_stations_own_program_cuts_at_speed_50(station_job):
    reports, _ = _cut_clean(station_job, 50)
    assert any(r.state == "Run" and 0 < (r.speed or 0) < 690 for r in reports)


def test_a_controller_outside_laser_mode_is_refused_before_anything_moves(sharp):
    """M4 with $32=0 is a spindle turning the other way: the beam would stay on through
    every rapid and stop. An S above $30 would be clamped and look corrupted."""
    for settings, match in (("32:0", r"\$32=0"), ("32:1,30:500", r"S700, above .*\$30=500")):
        port = serial.serial_for_url(f"grblsim://?speed=50&settings={settings}",
                                     timeout=0.02)
        st = Streamer(port)
        st.connect(quiet=0.05)
        with pytest.raises(StreamError, match=match):
            st.run(sharp)
        assert port.emulator.trace == [] and port.emulator.lines_received <= 3
        port.close()


def test_constant_power_mode_writes_m3_and_is_watched_as_constant():
    """``[cut] power_mode = "constant"``: the program uses M3, the checker holds it to it,
    and the watchdog expects S whatever the speed (M3 reports the programmed S)."""
    machine = default_machine().with_cut(power_mode="constant")
    data = {"version": 1, "units": "mm", "pieces": [{"id": "star", "outline": _star(30, 30)}]}
    prog = build_program(build_toolpaths(layout_from_dict(data, "m3"), machine), machine)
    assert any(ln.startswith("M3 S") for ln in prog.lines)
    assert not any(ln.startswith("M4") for ln in prog.lines)
    assert prog.check is not None and not prog.check.dynamic_power
    reports, _ = _cut_clean(prog, 50)
    assert {r.speed for r in reports if r.state == "Run" and r.speed} == {700.0}
    with pytest.raises(ValueError, match="power_mode"):
        default_machine().with_cut(power_mode="pulsed")


def _square_watchdog(dynamic: bool = True) -> Watchdog:
    lines = ["G21", "G90", "G0 X20 Y20", "M4 S700" if dynamic else "M3 S700",
             "G1 X60 Y20 F3000", "G1 X60 Y60", "G1 X20 Y60", "G1 X20 Y20", "M5", "G0 X0 Y0"]
    machine = default_machine().with_cut(power_mode="dynamic" if dynamic else "constant")
    wd = Watchdog.for_program(validate(lines, machine), machine.acceleration,
                              machine.rapid_feed)
    wd.start_from(np.array([20.0, 20.0]))
    return wd


def _judge(wd: Watchdog, feed: float, power: float, x: float = 40.0):
    st = Status("Run", wpos=(x, 20.0, 0.0), feed=feed, speed=power, planner_free=10)
    return wd.check(st, np.array([x, 20.0]), 0.0, 0.0)


def test_the_power_watchdog_accepts_what_a_healthy_laser_reports_and_nothing_else():
    """Healthy under M4: S x F_reported / F at every feed up to F. A corrupted S word (S7 or
    S600 for S700 at full speed), full power at a crawl (a corrupted F) and power above the
    programmed one are stopped; under M3 only the programmed S is healthy."""
    for feed in (150.0, 900.0, 1800.0, 2990.0, 3000.0):
        assert _judge(_square_watchdog(), feed, round(700.0 * feed / 3000.0)) is None, feed
    for feed, power in ((3000.0, 7.0), (3000.0, 600.0), (1500.0, 700.0), (3000.0, 900.0)):
        breach = _judge(_square_watchdog(), feed, power)
        assert breach is not None and breach.reason in (StopReason.POWER, StopReason.FEED)
    assert _judge(_square_watchdog(), 1500.0, 700.0).reason == StopReason.FEED  # F corrupted
    assert _judge(_square_watchdog(dynamic=False), 1500.0, 700.0) is None
    assert _judge(_square_watchdog(dynamic=False), 3000.0, 350.0).reason == StopReason.POWER
