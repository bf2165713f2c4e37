"""The streamer against the GRBL 1.1 emulator (simulators.grbl): whole jobs, every injected
fault, check mode, pause/resume/stop, character counting and the pty from another process."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import serial

import simulators.grbl  # noqa: F401  (registers grblsim://)
from gcode.blocks import parse_lines
from gcode.layout import layout_from_dict
from gcode.machine import default_machine
from gcode.program import Program, build_program, strip_comment
from gcode.stream import BEAM_OFF, Streamer, StreamError

sys.path.insert(0, str(Path(__file__).parent))  # gcode_helpers (importlib mode)
from gcode_helpers import make_layout  # noqa: E402

SETTINGS = "settings=32:1,130:1600,131:1000,110:12000,111:12000,120:1500,121:1500"
SPEED = 200


@pytest.fixture(scope="module")
def job() -> Program:
    machine = default_machine()
    from gcode.toolpath import build_toolpaths

    return build_program(build_toolpaths(layout_from_dict(make_layout(), "t"), machine), machine)


def open_emulator(extra: str = "", speed: float = SPEED):
    return serial.serial_for_url(f"grblsim://?speed={speed}&{SETTINGS}{extra}", timeout=0.02)


#: Lines every connection sends before the program (M5, M9: see gcode.stream.BEAM_OFF).
CONNECT_LINES = BEAM_OFF.count(b"\n")
#: Lines a laser run sends before the program: $$, whose $32 must say laser mode.
RUN_LINES = 1


def stream_pos(prog: Program) -> dict[int, int]:
    """program line index -> 1-based number of that line as the controller counts it."""
    idx = [i for i, ln in enumerate(prog.lines) if strip_comment(ln)]
    return {i: k + 1 + CONNECT_LINES + RUN_LINES for k, i in enumerate(idx)}


def last_cut_point(prog: Program, piece) -> tuple[float, float]:
    for ln in reversed(prog.lines[piece.first_line:piece.sync_line]):
        if ln.startswith(("G1 ", "G2 ", "G3 ")):
            w = dict((t[0], float(t[1:])) for t in ln.split()[1:])
            return w["X"], w["Y"]
    raise AssertionError("piece without cutting moves")


def finished_on_machine(em, xy, dark_mm: float = 0.1) -> bool:
    """The machine really completed a powered move ending at ``xy``: a completed cut ends
    there with the beam on to within ``dark_mm`` of it (under M4 GRBL gives each 10 ms step
    segment the power of the speed at its end, so the one that brakes to a stop runs dark:
    0.075 mm at 1500 mm/s^2)."""
    trace = list(em.trace)
    for i, s in enumerate(trace):
        if s.rapid or not s.complete or math.hypot(s.x1 - xy[0], s.y1 - xy[1]) >= 1e-3:
            continue
        dark = 0.0
        for t in reversed(trace[:i + 1]):  # back along the cut that ends there
            if t.rapid or not t.complete or dark > dark_mm:
                break
            if t.power > 0:
                return True
            dark += math.hypot(t.x1 - t.x0, t.y1 - t.y0)
    return False


def run_job(port, prog, **kw):
    changes = []
    st = Streamer(port, response_timeout=3.0, stall_timeout=3.0,
                  on_piece=lambda p: changes.append((p.number, p.state)), **kw)
    st.connect()
    return st, st.run(prog), changes


def test_whole_job_cuts_every_piece(job):
    port = open_emulator()
    progress = []
    st, res, changes = run_job(port, job, on_progress=progress.append)
    em = port.emulator
    assert res.completed and res.reason == "done"
    assert res.pieces_cut == len(job.pieces) == 3
    # plus the M5 and M9 every connection starts with, and the $$ that checks laser mode
    assert res.lines_sent == res.lines_acked == res.lines_total == \
        em.lines_executed - CONNECT_LINES - RUN_LINES
    # each piece went pending -> cutting -> cut, in order, one change at a time
    assert changes == [(n, s) for n in (1, 2, 3) for s in ("cutting", "cut")] or \
        sorted(changes) == sorted((n, s) for n in (1, 2, 3) for s in ("cutting", "cut"))
    for n in (1, 2, 3):
        assert changes.index((n, "cutting")) < changes.index((n, "cut"))
    for p in job.pieces:
        assert finished_on_machine(em, last_cut_point(job, p))
    # the laser never fired during a rapid move; the job ended parked with the laser off
    assert not any(s.rapid and s.power > 0 for s in em.trace)
    assert em.state == "Idle" and em.parser_state.spindle == "M5"
    assert progress[-1].fraction == pytest.approx(1.0) and progress[-1].pieces_cut == 3
    fr = [p.fraction for p in progress]
    assert fr == sorted(fr) and len(progress) >= 2
    assert all(p.lines_acked <= p.lines_sent <= p.lines_total for p in progress)
    port.close()


def test_interrupt_stops_safely(job):
    """Ctrl-C (KeyboardInterrupt in any hook) ends in the same safe stop as a fault."""
    port = open_emulator(speed=20)
    faults = []

    def hook(p):
        if p.pieces_cut >= 1:
            raise KeyboardInterrupt

    st = Streamer(port, on_progress=hook, on_fault=faults.append)
    st.connect()
    res = st.run(job)
    em = port.emulator
    assert res.reason == "interrupted" and len(faults) == 1
    assert [p.state for p in res.pieces][0] == "cut" and res.pieces_cut == 1
    assert em.state == "Idle" and em.parser_state.spindle == "M5" and not res.alarms
    port.close()


@pytest.mark.parametrize("fault", ["error_at={n}:20", "alarm_at={n}:1", "reset_at={n}",
                                   "disconnect_at={n}", "power_cut_at={n}",
                                   "drop:newline", "drop:X", "flip:hundreds"])
def test_fault_in_piece_two_stops_safely(job, fault):
    pos = stream_pos(job)
    p1, p2, _ = job.pieces
    n = (pos[p1.sync_line] + pos[p2.sync_line]) // 2  # a line in the middle of piece 2
    sent = [strip_comment(ln).replace(" ", "") for ln in job.lines if strip_comment(ln)]
    if ":" in fault and "=" not in fault:  # a byte fault, placed exactly in line n
        port = open_emulator()
        line = sent[n - 1 - CONNECT_LINES]
        k = {"newline": len(line), "X": line.index("X"), "hundreds": line.index("X") + 1}
        port = _ByteFault(port, (line + "\n").encode(), fault.split(":")[0], k[fault[5:]])
    else:
        port = open_emulator("&" + fault.format(n=n))
    em = port.emulator
    st, res, changes = run_job(port, job)
    assert not res.completed and res.fault is not None
    states = [p.state for p in res.pieces]
    assert states[0] == "cut" and states[1] != "cut" and states[2] == "pending", states
    assert res.fault["lines_acked"] < len(sent)
    # never a piece recorded cut that the machine did not finish, nor piece 2
    for p, rec in zip(job.pieces, res.pieces, strict=True):
        if rec.state == "cut":
            assert finished_on_machine(em, last_cut_point(job, p))
    assert not finished_on_machine(em, last_cut_point(job, p2))
    if em.connected:
        # stopped: not moving, laser off (a reset or alarm leaves the spindle off)
        time.sleep(0.2)
        assert not em.state.startswith("Run")
        assert em.parser_state.spindle == "M5"
        assert not any(s.rapid and s.power > 0 for s in em.trace)
    expected = {"error_at": {"error"}, "alarm_at": {"alarm"}, "reset_at": {"alarm", "reset"},
                "drop": {"error"}, "flip": {"error", "off_path"},
                "disconnect_at": {"disconnect"}, "power_cut_at": {"reset", "disconnect"}}
    assert res.reason in expected[fault.split("=")[0].split(":")[0]], res.fault
    port.close()


class _ByteFault:
    """Arms the emulator's own byte fault on byte ``k`` of the first write equal to ``line``
    (the emulator counts every byte it receives, status polls included, so the offset is
    only known at that moment)."""

    def __init__(self, port, line: bytes, kind: str, k: int):
        self.__dict__.update(port=port, line=line, kind=kind, k=k, armed=False)

    def __getattr__(self, name):
        return getattr(self.port, name)

    def __setattr__(self, name, value):
        setattr(self.port, name, value)

    def write(self, data):
        if data == self.line and not self.armed:
            em = self.port.emulator
            getattr(em.faults, f"{self.kind}_byte_at").add(em.bytes_received + self.k + 1)
            self.__dict__["armed"] = True
        return self.port.write(data)


def test_corrupted_coordinate_is_caught_off_path():
    """A flipped digit that GRBL accepts (no checksum) moves the head off the program's path:
    the status watchdog sees it and stops before the piece is recorded cut."""
    from gcode.layout import layout_from_dict as lfd
    from gcode.toolpath import build_toolpaths

    sq = [[100, 100], [140, 100], [140, 140], [100, 140]]
    data = {"version": 1, "units": "mm", "pieces": [{"id": "sq", "outline": sq}]}
    machine = default_machine().with_cut(kerf=0.0)
    prog = build_program(build_toolpaths(lfd(data, "sq"), machine), machine)
    cut = [ln for ln in prog.lines if ln.startswith("G1 ")]
    target = cut[1].replace(" ", "")  # "G1X140Y140": flip '1' of 140 -> '0' = X040
    port = _ByteFault(open_emulator(speed=4), (target + "\n").encode(), "flip",
                      target.index("X") + 1)
    em = port.emulator
    st, res, _ = run_job(port, prog)
    assert res.reason == "off_path", res.fault
    assert res.pieces[0].state != "cut"
    def off(x: float, y: float) -> float:  # distance to the square's edges y=100, x=140
        return min(abs(y - 100) if 100 <= x <= 140 else 1e9, abs(x - 140) if 100 <= y <= 140
                   else 1e9)

    assert off(*em.mpos[:2]) > 0.3  # the machine really went astray before the stop ...
    burnt = [s for s in em.trace if s.power > 0]  # ... and burnt no more than 2 mm off
    assert max(off(s.x1, s.y1) for s in burnt) <= 2.0
    assert em.parser_state.spindle == "M5"
    port.close()


@pytest.mark.parametrize("offset,cut", [(0, False), (1, True)])
def test_error_at_the_sync_line_boundary(job, offset, cut):
    """An error on piece 1's G4 leaves it uncut; one on the line after leaves it cut."""
    pos = stream_pos(job)
    n = pos[job.pieces[0].sync_line] + offset
    port = open_emulator(f"&error_at={n}:20")
    _, res, _ = run_job(port, job)
    assert res.reason == "error" and res.fault["line"] == [k for k, v in pos.items()
                                                           if v == n][0] + 1
    assert (res.pieces[0].state == "cut") is cut
    port.close()


def test_check_mode_reports_all_errors_without_moving(job):
    pos = stream_pos(job)
    port = open_emulator(f"&error_at={pos[job.pieces[0].sync_line] + 1}:33,"
                         f"{pos[job.pieces[2].sync_line]}:20")
    st = Streamer(port)
    st.connect()
    res = st.run(job, check=True)
    em = port.emulator
    assert res.check and not res.completed and len(res.errors) == 2
    assert [e["code"] for e in res.errors] == [33, 20]
    assert all(p.state == "pending" for p in res.pieces)
    assert not [s for s in em.trace if not s.rapid or s.x1 or s.y1]  # nothing moved
    assert em.state == "Idle"  # check mode left (GRBL soft-resets)
    # and a clean pass succeeds
    port.close()
    port = open_emulator()
    st = Streamer(port)
    st.connect()
    res = st.run(job, check=True)
    assert res.completed and res.reason == "checked" and not res.errors
    port.close()


def test_pause_resume_and_safe_stop(job):
    port = open_emulator(speed=20)
    em = port.emulator
    st = Streamer(port)
    st.connect()
    out = {}
    th = threading.Thread(target=lambda: out.setdefault("res", st.run(job)))
    th.start()
    time.sleep(0.6)
    st.pause()
    time.sleep(0.6)
    assert em.state.startswith("Hold")
    held_at = em.mpos.copy()
    time.sleep(0.3)
    assert (em.mpos == held_at).all()  # really holding
    st.resume()
    time.sleep(0.4)
    assert em.state == "Run"
    st.stop()
    th.join(20)
    res = out["res"]
    assert res.reason == "stopped" and not res.completed
    # stopped after a completed hold, so the reset kept the position: no ALARM:3
    assert em.state == "Idle" and not res.alarms
    assert em.parser_state.spindle == "M5" and not em.parser_state.flood
    assert res.position is not None
    port.close()


class _Spy:
    """A port wrapper recording what the streamer had in flight at each write."""

    def __init__(self, port, streamer_ref):
        self.port, self.ref = port, streamer_ref
        self.writes: list[tuple[bytes, int, int]] = []
        self.polls: list[float] = []

    def __getattr__(self, name):
        return getattr(self.port, name)

    def __setattr__(self, name, value):
        if name == "timeout":
            self.port.timeout = value
        else:
            super().__setattr__(name, value)

    def write(self, data):
        st = self.ref[0] if self.ref else None
        if data == b"?":
            self.polls.append(time.monotonic())
        elif st is not None:
            self.writes.append((data, len(st._inflight), st._inflight_bytes))
        return self.port.write(data)


def test_character_counting_and_one_at_a_time_settings(job):
    ref: list = []
    raw = open_emulator()
    raw.emulator.paced = False  # what is checked is the protocol, not the host's pace
    spy = _Spy(raw, ref)
    st = Streamer(spy)
    ref.append(st)
    st.connect()
    head = ["$11=0.010", "$12=0.002", "$32=1"]
    prog = Program(parse_lines(head + job.lines), [])
    t0 = time.monotonic()
    res = st.run(prog)
    t1 = time.monotonic()
    assert res.completed
    em = raw.emulator
    assert em.bytes_lost == 0
    for data, n_inflight, n_bytes in spy.writes:
        if len(data) > 1:
            assert n_bytes + len(data) <= 127  # the line fitted in the RX budget
        if data.startswith(b"$"):
            assert n_inflight == 0  # settings writes go alone
    # the next line after a $ write waited for its answer too
    dollar = [k for k, w in enumerate(spy.writes) if w[0].startswith(b"$")]
    for k in dollar:
        assert spy.writes[k + 1][1] == 0
    # many lines were in flight at once elsewhere (the budget is used)
    assert max(w[1] for w in spy.writes) >= 3
    # status polled at no more than 5 Hz during streaming
    polls = [t for t in spy.polls if t0 <= t <= t1]
    assert len(polls) <= 5 * (t1 - t0) + 2
    raw.close()


def test_alarm_at_start_up_is_refused_then_unlocked(job):
    port = serial.serial_for_url(f"grblsim://?speed={SPEED}&{SETTINGS},22:1", timeout=0.02)
    st = Streamer(port)
    with pytest.raises(StreamError, match="ALARM"):
        st.connect()
    st.unlock()
    assert st.query_status().state == "Idle"
    port.close()


@pytest.mark.parametrize("line", ["G1 X10? Y10", "G1 X10 Y10 F1000!", "G1 X1" + "0" * 80])
def test_streamer_refuses_dangerous_lines_before_sending(line):
    port = open_emulator()
    st = Streamer(port)
    st.connect()
    before = port.emulator.lines_received
    with pytest.raises(StreamError, match="line 2"):
        st.run(Program(parse_lines(["G21 G90", line]), []))
    assert port.emulator.lines_received == before
    port.close()


def test_refuses_to_cut_in_check_mode(job):
    """A controller left in $C would answer ok to everything without moving."""
    port = open_emulator()
    st = Streamer(port)
    st.connect()
    r, pushed = st.command("$C")
    assert r.kind == "ok" and any("Enabled" in (p.text or "") for p in pushed)
    with pytest.raises(StreamError, match="check mode"):
        st.run(job)
    port.close()


def test_connect_never_resets_a_moving_machine(job):
    port = open_emulator(speed=1)
    st = Streamer(port)
    st.connect()
    port.write(b"G21G90G0X500Y500\n")  # someone else's move, about 5 s long at speed 1
    time.sleep(0.3)
    again = Streamer(port)
    with pytest.raises(StreamError, match="busy"):
        again.connect(quiet=0.1)
    assert port.emulator.state == "Run" and not port.emulator.state.startswith("Alarm")
    port.close()


def test_no_banner_is_an_error():
    class Silent:
        timeout = 0.01
        in_waiting = 0

        def read(self, n):
            time.sleep(0.01)
            return b""

        def write(self, data):
            return len(data)

    st = Streamer(Silent(), banner_timeout=0.3)
    with pytest.raises(StreamError, match="no GRBL banner"):
        st.connect(quiet=0.1)


def test_stream_command_through_a_pty_from_another_process(job, tmp_path):
    """`station sim-grbl --pty` in one process, `station stream` in another."""
    nc = tmp_path / "job.nc"
    job.write(nc)
    station = [sys.executable, "-m", "station.cli"]
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    sets = [a for kv in ("32=1", "130=1600", "131=1000", "110=12000", "111=12000", "120=1500",
                         "121=1500") for a in ("--setting", kv)]
    sim = subprocess.Popen(station + ["sim-grbl", "--pty", "--speed", "50", *sets],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        path = sim.stdout.readline().strip()
        assert path.startswith("/dev/")
        out = subprocess.run(station + ["stream", str(nc), "--port", path, "--json"],
                             capture_output=True, text=True, timeout=60, env=env)
        assert out.returncode == 0, out.stderr
        rep = json.loads(out.stdout)
        assert rep["completed"] and rep["errors"] == 0 and rep["alarms"] == 0
        assert rep["lines_sent"] == rep["lines_total"] > 50
        assert rep["pieces_cut"] == 3 and rep["seconds"] > 0
        assert [p["state"] for p in rep["piece_states"]] == ["cut"] * 3
    finally:
        sim.terminate()
        sim.wait(10)


def test_stream_command_refuses_mismatched_controller(job, tmp_path):
    from station.cli import main

    nc = tmp_path / "job.nc"
    job.write(nc)
    # the emulator's default settings: laser mode off, 200 mm travels
    rc = main(["simulate-stream", str(nc), "--port", f"grblsim://?speed={SPEED}", "--json"])
    assert rc == 2
