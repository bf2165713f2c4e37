"""Behaviour of the GRBL 1.1h emulator, checked against the GRBL 1.1 documentation.

Each test quotes the sentence of the documentation it checks: gnea/grbl wiki "Grbl v1.1
Interface" (interface.md), "Grbl v1.1 Commands" (commands.md), "Grbl v1.1 Configuration"
(settings.md), "Grbl v1.1 Laser Mode" (laser_mode.md), and doc/csv/*_codes_en_US.csv.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
import serial

import simulators.grbl
from simulators.grbl import GrblEmulator, forget
from simulators.grbl import codes as C

FAST = "speed=1000"


def open_port(query: str = FAST, timeout: float = 2.0) -> serial.SerialBase:
    return serial.serial_for_url(f"grblsim://?{query}", timeout=timeout)


def read_line(port: serial.SerialBase) -> str:
    raw = port.readline()
    assert raw.endswith(b"\r\n"), f"no complete line before the timeout: {raw!r}"
    return raw[:-2].decode("latin-1")


def read_boot(port: serial.SerialBase) -> list[str]:
    """The start-up message: an empty line, the banner, and any [MSG:] right after it."""
    lines = [read_line(port), read_line(port)]
    time.sleep(0.02)
    while port.in_waiting:
        lines.append(read_line(port))
    return lines


def send(port: serial.SerialBase, line: str) -> list[str]:
    """Send one line and collect everything up to its `ok` / `error:N` response."""
    port.write(line.encode() + b"\n")
    out = []
    while True:
        text = read_line(port)
        out.append(text)
        if text == "ok" or text.startswith("error:"):
            return out


def status(port: serial.SerialBase) -> str:
    port.write(b"?")
    while True:
        text = read_line(port)
        if text.startswith("<"):
            return text


def wait_state(port: serial.SerialBase, prefix: str, timeout: float = 3.0) -> str:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        report = status(port)
        if report[1:].startswith(prefix):
            return report
        time.sleep(0.005)
    raise AssertionError(f"state never became {prefix!r}; last report {report}")


@pytest.fixture
def port():
    p = open_port()
    assert read_boot(p)[1] == C.BANNER
    yield p
    p.close()


# --------------------------------------------------------------------------- start-up
def test_banner_and_url_registration():
    """interface.md: "The start up message always prints upon startup and after a reset."
    Importing simulators.grbl registers the handler package, as pyserial's URL
    convention requires."""
    assert "simulators.grbl" in serial.protocol_handler_packages
    p = open_port()
    try:
        assert read_boot(p) == ["", "Grbl 1.1h ['$' for help]"]
        assert isinstance(p.emulator, GrblEmulator)
    finally:
        p.close()


def test_homing_enabled_boots_in_alarm():
    """commands.md: "if you have homing enabled and power-up the Arduino, Grbl enters the alarm
    state"; interface.md: "[MSG:'$H'|'$X' to unlock] - Alarm state is active at initialization."
    and "All g-code commands and some '$' are blocked until the alarm state is cancelled"."""
    p = open_port(FAST + "&settings=22:1")
    try:
        assert read_boot(p) == ["", C.BANNER, "[MSG:'$H'|'$X' to unlock]"]
        assert status(p).startswith("<Alarm|")
        assert send(p, "G0 X-1") == ["error:9"]
        assert send(p, "$H") == ["ok"]
        report = status(p)
        assert report.startswith("<Idle|MPos:-1.000,-1.000,-1.000")  # home minus pull-off $27
    finally:
        p.close()


def test_unknown_url_option_is_a_clear_error():
    """pyserial URL handlers are strict: an unknown option fails loudly with the expected form."""
    with pytest.raises(serial.SerialException, match=r"grblsim://\[\?speed=S\].*'sped'"):
        serial.serial_for_url("grblsim://?sped=2")
    with pytest.raises(serial.SerialException, match="LINE:CODE"):
        serial.serial_for_url("grblsim://?error_at=5")


# --------------------------------------------------------------------------- responses
@pytest.mark.parametrize(
    ("line", "code"),
    [
        ("#1", 1),  # "G-code words consist of a letter and a value. Letter was not found."
        ("G1 X", 2),  # "Missing the expected G-code word value or numeric value format is ..."
        ("$10", 3),  # "Grbl '$' system command was not recognized or supported."
        ("$Q", 2),  # GRBL reads an unknown "$x" as a setting number: bad number format
        ("F-100", 4),  # "Negative value received for an expected positive value."
        ("$H", 5),  # "Homing cycle failure. Homing is not enabled via settings."
        ("$0=2", 6),  # "Minimum step pulse time must be greater than 3usec."
        ("$20=1", 10),  # "Soft limits cannot be enabled without homing also enabled."
        ("$100=100000", 12),  # "Grbl '$' setting value cause the step rate to exceed the maximum"
        ("$J=X-1", 22),  # jog needs F: "Feed rate has not yet been set or is undefined."
        ("$J=M3 X-1 F100", 16),  # "Jog command has no '=' or contains prohibited g-code."
        ("G5", 20),  # "Unsupported or invalid g-code command found in block."
        ("G20 G21", 21),  # "More than one g-code command from same modal group found in block."
        ("G1 X-1", 22),  # "Feed rate has not yet been set or is undefined."
        ("G54.5", 23),  # "G-code command in block requires an integer value."
        ("G0 G10 L2 P1 X0", 24),  # "More than one g-code command that requires axis words found"
        ("G0 X1 X2", 25),  # "Repeated g-code word found in block."
        ("G92", 26),  # "No axis words found in block for g-code command ... which requires them."
        ("N10000000 G0", 27),  # "Line number value is invalid."
        ("G4", 28),  # "G-code command is missing a required value word."
        ("G10 L2 P7 X0", 29),  # "G59.x work coordinate systems are not supported."
        ("G2 G53 X-1 F10", 30),  # "G53 only allowed with G0 and G1 motion modes."
        ("G80 X-1", 31),  # "Axis words found in block when no command or current modal state uses"
        ("G2 Z-1 I1 F10", 32),  # "G2 and G3 arcs require at least one in-plane axis word."
        ("G2 X-10 I-1 F10", 33),  # "Motion command target is invalid."
        ("G2 X-10 R1 F10", 34),  # "Arc radius value is invalid."
        ("G2 X-1 F10", 35),  # "G2 and G3 arcs require at least one in-plane offset word."
        ("G0 X-1 P3", 36),  # "Unused value words found in block."
        ("G43.1 X1", 37),  # "G43.1 dynamic tool length offset is not assigned to configured ..."
        ("T256", 38),  # "Tool number greater than max supported value."
    ],
)
def test_error_codes(port, line, code):
    """interface.md: "error:X: Something went wrong! Grbl did not recognize the command and did
    not execute anything inside that message." Codes from doc/csv/error_codes_en_US.csv."""
    before = send(port, "$G")[0]
    assert send(port, line) == [f"error:{code}"]
    assert send(port, "$G")[0] == before  # nothing inside the block was executed
    assert port.emulator.trace == []


def test_empty_line_and_comments_answer_ok(port):
    """interface.md: "If an empty line with only a return is sent to Grbl, it considers it a valid
    line and will return an ok too, except it didn't do anything." """
    assert send(port, "") == ["ok"]
    assert send(port, "(just a comment) ; and another") == ["ok"]
    assert port.emulator.trace == []
    # GRBL ends a line at '\n' or '\r', so CR LF is a line plus an empty line: two oks.
    port.write(b"G0 X-1\r\n")
    assert [read_line(port), read_line(port)] == ["ok", "ok"]


def test_startup_lines_run_after_reset(port):
    """interface.md: "`>G54G20:ok` : The open chevron indicates a startup line has just
    executed." and commands.md `$N`: "startup blocks that Grbl runs every time you power on Grbl
    or reset Grbl"."""
    assert send(port, "$N0=G55 G91") == ["ok"]
    assert send(port, "$N") == ["$N0=G55G91", "$N1=", "ok"]
    port.write(b"\x18")
    assert read_boot(port) == ["", C.BANNER, ">G55G91:ok"]
    assert send(port, "$G")[0].startswith("[GC:G0 G55 G17 G21 G91 ")


def test_line_over_79_characters_is_rejected(port):
    """error_codes_en_US.csv 11: "Line overflow, Max characters per line exceeded. Received command
    line was not executed." GRBL's line buffer holds 79 significant characters (spaces and
    comments are stripped before counting)."""
    line79 = "G1X-1.F100Y-" + "1." + "0" * (79 - 14)
    assert len(line79) == 79
    assert send(port, line79) == ["ok"]
    assert send(port, line79 + "0") == ["error:11"]
    spaced = " ".join(line79) + " (a comment that does not count)"
    assert len(spaced) > 128 - 1 or len(spaced) > 79
    assert send(port, spaced) == ["ok"]
    port.emulator.wait_idle()
    assert len(port.emulator.trace) == 1  # only the first line moved; the third repeats it


def test_settings_print_write_and_keep(port):
    """interface.md: "`$x=val` will only appear when the user queries to print all of Grbl's
    settings via the `$$` print settings command. It does so sequentially and completes with an
    `ok`." (example `$11=0.010`, `$30=1000`, `$100=250.000`)."""
    lines = send(port, "$$")
    assert lines[-1] == "ok"
    printed = dict(line.split("=") for line in lines[:-1])
    assert list(printed) == [f"${k}" for k in C.DEFAULT_SETTINGS]
    assert printed["$11"] == "0.010" and printed["$30"] == "1000"
    assert printed["$100"] == "250.000" and printed["$10"] == "1"
    assert send(port, "$110=1200.5") == ["ok"]
    assert "$110=1200.500" in send(port, "$$")
    assert send(port, "$999=1") == ["error:3"]


def test_parameters_parser_state_and_build_info(port):
    """interface.md: `$#` "[G54:0.000,0.000,0.000] ... [TLO:0.000] [PRB:0.000,0.000,0.000:0]";
    `$G` "[GC:G0 G54 G17 G21 G90 G94 M0 M5 M9 T0 F0. S0.]" (1.1h prints no program mode while
    running and zero-decimal F/S); `$I` "[VER:]" and "[OPT:]" lines followed by ok. The help is
    "[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? ctrl-x]"."""
    assert send(port, "G10 L2 P2 X-4 Y-6 Z-7") == ["ok"]
    params = send(port, "$#")
    assert params[0] == "[G54:0.000,0.000,0.000]"
    assert params[1] == "[G55:-4.000,-6.000,-7.000]"
    assert params[-3:] == ["[TLO:0.000]", "[PRB:0.000,0.000,0.000:0]", "ok"]
    assert send(port, "$G") == ["[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]", "ok"]
    assert send(port, "G1 G55 G91 F500 S300 M3 T2") == ["ok"]
    assert send(port, "$G")[0] == "[GC:G1 G55 G17 G21 G91 G94 M3 M9 T2 F500 S300]"
    info = send(port, "$I")
    assert info[0].startswith("[VER:1.1h.") and info[1:] == ["[OPT:V,15,128]", "ok"]
    assert send(port, "$") == [C.HELP, "ok"]


# --------------------------------------------------------------------------- streaming
def _program(n: int) -> list[str]:
    rng = np.random.default_rng(7)  # a random walk of 1-5 mm steps inside the travel
    steps = rng.uniform(1.0, 5.0, size=(n, 1)) * np.exp(1j * rng.uniform(0, 2 * np.pi, n))[:, None]
    pts = np.clip(-30.0 + np.cumsum(np.hstack([steps.real, steps.imag]), axis=0), -60.0, -1.0)
    return [f"G1 X{x:.3f} Y{y:.3f} F{3000 + i % 7}" for i, (x, y) in enumerate(pts)]


def test_character_counting_never_loses_a_line():
    """interface.md, Streaming Protocol: Character-Counting: "We know Grbl has a 128 character
    serial receive buffer, and the host PC can send up to 128 characters without overflowing the
    buffer." and "It always ensures Grbl's serial read buffer is filled, while never overflowing
    it." A sender that keeps at most 128 bytes un-acknowledged loses nothing."""
    program = _program(150)
    p = open_port("speed=100", timeout=5)
    # Unpaced: this host is blocked on the machine's answers, never late (see HOST_STEP).
    p.emulator.paced = False
    try:
        read_boot(p)
        in_flight: list[int] = []
        answers: list[str] = []
        max_rx = 0
        for line in program:
            data = (line + "\n").encode()
            while sum(in_flight) + len(data) > 128:
                text = read_line(p)
                if text == "ok" or text.startswith("error:"):
                    answers.append(text)
                    in_flight.pop(0)
            p.write(data)
            in_flight.append(len(data))
            max_rx = max(max_rx, p.emulator.rx_used)
        while in_flight:
            text = read_line(p)
            if text == "ok" or text.startswith("error:"):
                answers.append(text)
                in_flight.pop(0)
        assert answers == ["ok"] * len(program)
        # The receive buffer really was used: it holds what the blocked parser has not read.
        assert max_rx > 64
        assert p.emulator.bytes_lost == 0
        assert send(p, "G4 P0") == ["ok"]
        ends = np.array([(s.x1, s.y1) for s in p.emulator.trace])
        targets = np.array([[float(w[1:]) for w in line.split()[1:3]] for line in program])
        np.testing.assert_allclose(ends, targets, atol=1e-9)
    finally:
        p.close()


def test_overrunning_the_receive_buffer_loses_data():
    """serial.c of GRBL writes a received byte "to buffer unless it is full", and interface.md
    warns the host to keep within the "128 character serial receive buffer": while the planner
    is full GRBL reads nothing, so bytes beyond 128 are lost, as on the real controller."""
    p = open_port("speed=1&settings=10:3")
    try:
        read_boot(p)
        for i in range(16):  # 15 planner blocks plus one line blocked in the parser
            p.write(f"G1 X-{i + 1} F60\n".encode())
        time.sleep(0.05)
        assert p.emulator.planner_blocks == 15
        burst = b"".join(f"G1 X-{k} Y-{k} F60\n".encode() for k in range(20, 40))
        assert len(burst) > 300
        p.write(burst)
        assert p.emulator.bytes_lost == len(burst) - 128
        assert "|Bf:0,0|" in status(p)  # no planner block, no RX byte available
    finally:
        p.write(b"\x18")
        p.close()


def test_g4_dwell_answers_only_after_motion(port):
    """interface.md, Synchronization: "insert a `G4 P0.01` dwell command ... This acts as a quick
    force-synchronization and ensures the planner buffer is completely empty"; an `ok` otherwise
    "Indicates the command line received was parsed and executed (or set to be executed)"."""
    p = open_port("speed=5")
    try:
        read_boot(p)
        assert send(p, "G1 X-20 F500") == ["ok"]
        assert p.emulator.mpos[0] > -20.0  # ok came back while the move is still running
        assert send(p, "G4 P0.01") == ["ok"]
        assert p.emulator.mpos[0] == -20.0
        assert p.emulator.planner_blocks == 0
        assert status(p).startswith("<Idle|MPos:-20.000,0.000,0.000")
    finally:
        p.close()


def test_motion_takes_simulated_time_with_acceleration():
    """settings.md: $110 "X-axis maximum rate, mm/min" and $120 "X-axis acceleration, mm/sec^2":
    a 100 mm move at F600 is capped to 500 mm/min and follows a trapezoid (accelerate, cruise,
    decelerate)."""
    emu = GrblEmulator(realtime=False)
    emu.take_output()
    emu.receive(b"G1 X-100 F600\nG4 P0\n")
    assert emu.take_output() == b"ok\r\n"
    v, a = 500.0 / 60.0, 10.0
    expected = v / a + 100.0 / v  # two ramps of v/(2a) each plus the cruise at v
    t = 0.0
    while b"ok" not in emu.take_output():
        emu.advance(0.01)
        t += 0.01
        assert t < 2 * expected
    assert t == pytest.approx(expected, abs=0.011)
    assert emu.trace[0].feed == pytest.approx(500.0)
    emu.close()


# --------------------------------------------------------------------------- real-time commands
def test_feed_hold_then_cycle_start_resumes():
    """commands.md: `!` "Places Grbl into a suspend or HOLD state. If in motion, the machine will
    decelerate to a stop and then be suspended."; `~` "Resumes a feed hold"; interface.md
    sub-states "Hold:0 Hold complete. Ready to resume." and "Hold:1 Hold in-progress."."""
    p = open_port("speed=5")
    try:
        read_boot(p)
        assert send(p, "G1 X-40 F500") == ["ok"]
        time.sleep(0.05)
        p.write(b"!")
        assert status(p).startswith(("<Hold:1|", "<Hold:0|"))
        held = wait_state(p, "Hold:0")
        time.sleep(0.05)
        assert status(p).split("|")[1] == held.split("|")[1]  # stopped, not moving on
        x_held = p.emulator.mpos[0]
        assert -40.0 < x_held < 0.0
        p.write(b"~")
        assert send(p, "G4 P0") == ["ok"]
        assert p.emulator.mpos[0] == -40.0
        assert [(s.x0, s.x1, s.complete) for s in p.emulator.trace] == [(0.0, -40.0, True)]
    finally:
        p.close()


def test_reset_during_motion_raises_alarm_3():
    """commands.md, 0x18: "If reset while in motion, Grbl will throw an alarm to indicate position
    may be lost from the motion halt."; alarm_codes_en_US.csv 3: "Reset while in motion."."""
    p = open_port("speed=5")
    try:
        read_boot(p)
        assert send(p, "G1 X-40 F500") == ["ok"]
        time.sleep(0.05)
        p.write(b"\x18")
        assert read_line(p) == "ALARM:3"
        assert read_boot(p) == ["", C.BANNER, C.MSG_UNLOCK]
        x = p.emulator.mpos[0]
        assert -40.0 < x < 0.0
        assert send(p, "G1 X-1 F100") == ["error:9"]
        assert send(p, "$X") == [C.MSG_UNLOCKED, "ok"]
        assert status(p).startswith(f"<Idle|MPos:{x:.3f},")
        assert p.emulator.trace[-1].complete is False
    finally:
        p.close()


def test_reset_when_idle_keeps_position_without_alarm(port):
    """commands.md: "If reset while in not motion, position is retained and re-homing is not
    required."."""
    assert send(port, "G0 X-3 Y-4") == ["ok"]
    assert send(port, "G4 P0") == ["ok"]
    port.write(b"\x18")
    assert read_boot(port) == ["", C.BANNER]
    assert status(port).startswith("<Idle|MPos:-3.000,-4.000,0.000")


def test_overrides_change_feed_and_report(port):
    """commands.md: `0x91` "Increase 10%" of the feed override and interface.md "Ov:100,100,100
    indicates current override values in percent ... If an override value has changed, this data
    field will appear immediately in the next report"."""
    status(port), status(port)
    port.write(bytes([0x91, 0x91, 0x97, 0x9B]))
    assert status(port).endswith("|Ov:120,25,90>")
    port.write(bytes([0x90]))
    assert "|Ov:100,25,90" in status(port)


def test_jog_and_jog_cancel(port):
    """commands.md: "Jog commands are completely independent of the g-code parser state. It will
    not change any modes like G91"; 0x85: "Immediately cancels the current jog state by a feed
    hold and automatically flushing any remaining jog commands in the buffer."."""
    p = open_port("speed=5")
    try:
        read_boot(p)
        assert send(p, "$J=G91 X-50 F600") == ["ok"]
        assert send(p, "$J=G91 Y-50 F600") == ["ok"]
        assert status(p).startswith("<Jog|")
        # error 9: "G-code commands are locked out during alarm or jog state."
        assert send(p, "G1 X0 F100") == ["error:9"]
        time.sleep(0.05)
        p.write(b"\x85")
        wait_state(p, "Idle")
        x, y = p.emulator.mpos[:2]
        assert -50.0 < x < 0.0 and y == 0.0
        assert send(p, "$G")[0].startswith("[GC:G0 G54 G17 G21 G90 ")
    finally:
        p.close()


# --------------------------------------------------------------------------- alarms and modes
def test_soft_limit_raises_alarm_2_and_nothing_runs_until_reset_and_unlock():
    """alarm_codes_en_US.csv 2: "Soft limit alarm. G-code motion target exceeds machine travel.
    Machine position retained. Alarm may be safely unlocked."; interface.md: "[MSG:Reset to
    continue] - Critical event message. Reset is required before Grbl accepts any other
    commands." and `?` is answered "except ... when critical alarm (hard/soft limit error) is
    thrown"."""
    p = open_port("speed=20&settings=22:1,20:1", timeout=0.3)
    try:
        assert read_boot(p)[-1] == C.MSG_UNLOCK
        assert send(p, "$X") == [C.MSG_UNLOCKED, "ok"]
        assert send(p, "G1 X-30 Y-30 F500") == ["ok"]
        p.write(b"G1 X10 Y-30\nG1 X-5 Y-5\n")  # the first leaves the travel (X > 0)
        assert read_line(p) == "ALARM:2"
        assert read_line(p) == C.MSG_RESET_TO_CONTINUE
        p.write(b"?")
        assert p.readline() == b""  # nothing answers, nothing runs
        time.sleep(0.2)
        emu = p.emulator
        assert all(s.x1 <= 0.0 and (s.x1, s.y1) != (-5.0, -5.0) for s in emu.trace)
        stopped = emu.mpos.copy()
        assert np.all(stopped <= 0.0)
        p.timeout = 2
        p.write(b"\x18")
        assert read_line(p) == "ok"  # the offending line returns from the parser after reset
        assert read_boot(p) == ["", C.BANNER, C.MSG_UNLOCK]
        assert send(p, "G1 X-5 Y-5 F500") == ["error:9"]
        assert np.array_equal(emu.mpos, stopped)  # "Machine position retained"
        assert send(p, "$X") == [C.MSG_UNLOCKED, "ok"]
        assert send(p, "G1 X-5 Y-5 F500") == ["ok"]
        assert send(p, "G4 P0") == ["ok"]
        assert emu.mpos[0] == -5.0 and emu.mpos[1] == -5.0
    finally:
        p.close()


def test_soft_limit_jog_is_an_error_not_an_alarm():
    """commands.md: "If soft-limits are enabled, any jog command that exceeds a soft-limit will
    simply return an error. It will not throw an alarm"; error 15: "Jog target exceeds machine
    travel. Jog command has been ignored."."""
    p = open_port(FAST + "&settings=22:1,20:1")
    try:
        read_boot(p)
        assert send(p, "$X")[-1] == "ok"
        assert send(p, "$J=X10 F100") == ["error:15"]
        assert status(p).startswith("<Idle|MPos:0.000,0.000,0.000")
    finally:
        p.close()


def test_check_mode_reports_errors_without_moving(port):
    """commands.md, `$C`: "process them completely, as it would in normal operation, but it does
    not move any of the axes, ignores dwells, and powers off the spindle and coolant" and "When
    toggled off, Grbl will perform an automatic soft-reset (^X)."."""
    assert send(port, "$C") == [C.MSG_ENABLED, "ok"]
    assert status(port).startswith("<Check|")
    assert send(port, "G1 X-10 Y-10 F300 M3 S500") == ["ok"]
    assert send(port, "G2 X-20 Y-10 F300") == ["error:35"]
    assert send(port, "G1 X-10 Q3") == ["error:20"]
    t0 = time.monotonic()
    assert send(port, "G4 P100") == ["ok"]
    assert time.monotonic() - t0 < 0.5  # 100 s dwell ignored
    assert port.emulator.trace == []
    assert status(port).startswith("<Check|MPos:0.000,0.000,0.000|FS:0,0")
    assert send(port, "$C") == [C.MSG_DISABLED, "ok"]
    assert read_boot(port) == ["", C.BANNER]
    assert send(port, "$G")[0] == "[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]"


def test_status_report_fields_follow_settings(port):
    """settings.md `$10`: "Position Type | 1 | Enabled MPos:. Disabled WPos:." and "Buffer Data |
    2 | ... planner and serial RX available buffer"; interface.md: WCO appears "In the first
    report after a reset/power-cycle" and "Immediately in the next report, if an offset value
    has changed", with "WPos = MPos - WCO"."""
    assert status(port) == "<Idle|MPos:0.000,0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>"
    assert status(port) == "<Idle|MPos:0.000,0.000,0.000|FS:0,0|Ov:100,100,100>"
    assert status(port) == "<Idle|MPos:0.000,0.000,0.000|FS:0,0>"
    assert send(port, "G0 X-5 Y-2") == ["ok"]
    assert send(port, "G10 L20 P1 X0 Y0") == ["ok"]
    assert send(port, "$10=2") == ["ok"]
    assert status(port) == "<Idle|WPos:0.000,0.000,0.000|Bf:15,128|FS:0,0|WCO:-5.000,-2.000,0.000>"


def test_laser_mode_power_only_in_feed_motion(port):
    """laser_mode.md: "The laser will only turn on when Grbl is in a G1, G2, or G3 motion mode."
    and "`G0 M3 S1000` will not turn on the laser, but will set the laser modal state to `M3`
    enabled and power of `S1000`. A following `G1` command will then immediately be set to `M3`
    and `S1000`."; Grbl "will move continuously through consecutive motion commands when
    programmed with a new S spindle speed"."""
    assert send(port, "$32=1") == ["ok"]
    for line in ["G0 M3 S1000", "G0 X-5", "G1 X-10 F600", "G1 X-15 S500", "G0 X-20",
                 "G1 X-25 S0", "M5", "G1 X-30", "G4 P0"]:
        assert send(port, line) == ["ok"], line
    powers = [s.power for s in port.emulator.trace]
    assert powers == [0.0, 1000.0, 500.0, 0.0, 0.0, 0.0]
    assert [s.rapid for s in port.emulator.trace] == [True, False, False, True, False, False]


def test_laser_m4_power_follows_speed_segment_by_segment(port):
    """laser_mode.md: "`M4` enables dynamic laser power mode. Dynamic laser power mode will
    automatically adjust laser power based on the current speed relative to the programmed
    rate." GRBL does it per 10 ms step segment, from the speed at the segment's end
    (stepper.c: ``rpm *= current_speed * inv_rate``). From rest at a = 10 mm/s^2 the speed
    at distance s is sqrt(2 a s), so the trace's power along a 100 mm cut at F500 ramps as
    S sqrt(2 a s) / F up to S, holds, and ramps down to 0 at the stop."""
    assert send(port, "$32=1") == ["ok"]
    for line in ["G1 M4 S1000 F500 X-1", "G4 P0", "G1 X-1 Y-100", "G4 P0"]:
        assert send(port, line) == ["ok"], line
    a, v_f = 10.0, 500.0 / 60.0
    long = [seg for seg in port.emulator.trace if seg.x0 == -1.0]
    s_end = np.array([-seg.y1 for seg in long])  # distance along the cut of each piece's end
    assert len(long) > 20 and np.all(np.diff(s_end) > 0) and s_end[-1] == pytest.approx(100.0)
    v_end = np.minimum(np.sqrt(2 * a * np.minimum(s_end, 100.0 - s_end)), v_f)
    assert [seg.power for seg in long] == pytest.approx(1000.0 * v_end / v_f, abs=1.0)
    powers = np.array([seg.power for seg in long])
    ramp = powers[:np.argmax(powers)]
    assert len(ramp) > 10 and np.all(np.diff(ramp) > 0) and powers.max() == 1000.0
    assert powers[-1] == 0.0  # the segment that brakes to a stop runs dark
    # the 1 mm cut never reaches F500: at most S x sqrt(a x 1 mm) / F
    short = [seg.power for seg in port.emulator.trace if seg.x0 > -1.0 and seg.y0 == 0.0]
    assert 0 < max(short) <= 1000.0 * np.sqrt(a * 1.0) / v_f + 1.0


def test_laser_reports_the_prepared_segment_speed_and_m4_power():
    """``FS:`` shows the speed and the laser value of the last step segment prepared
    (``st_get_realtime_rate`` returns ``prep.current_speed``, and ``sys.spindle_speed`` is
    computed from it): under M4 the reported S is S x reported feed / F, from rest up to S
    at cruise, and ahead of the head (the feed already rising while MPos is still 0). M3
    reports S whatever the speed. At rest the programmed S is shown with the beam off."""
    emu = GrblEmulator(realtime=False, settings={32: 1, 110: 6000, 111: 6000, 120: 100,
                                                 121: 100})
    emu.take_output()

    def report() -> tuple[str, float, float, float]:
        emu.receive(b"?")
        text = emu.take_output().decode()
        state, *rest = text[text.index("<") + 1:text.index(">")].split("|")
        fields = dict(f.split(":", 1) for f in rest)
        feed, power = (float(v) for v in fields["FS"].split(","))
        return state, float(fields["MPos"].split(",")[0]), feed, power

    seen = []
    for mode in ("M4", "M3"):
        emu.receive(f"G1 {mode} S800 F1200 X-20\nG4 P0\n".encode())
        emu.take_output()
        while True:
            state, x, feed, power = report()
            if state != "Run":
                break
            seen.append((mode, x, feed, power))
            emu.advance(0.02)
        assert (state, feed, power) == ("Idle", 0.0, 800.0)  # at rest: S shown, beam off
        emu.receive(b"G0 X0\nG4 P0\n")
        emu.advance(5.0)
        emu.take_output()
    m4 = [r for r in seen if r[0] == "M4"]
    assert m4[0][1] == 0.0 and m4[0][2] > 0  # prepared ahead of the head
    for _, _, feed, power in m4:
        assert power == pytest.approx(800.0 * feed / 1200.0, abs=1.0)
    assert {r[3] for r in m4} > {800.0} and min(r[3] for r in m4) < 400
    assert {r[3] for r in seen if r[0] == "M3"} == {800.0}


# --------------------------------------------------------------------------- fault injection
def test_injected_error_and_alarm_at_lines():
    """Fault injection: `error_at=LINE:CODE` answers that line with the error (and does not run
    it); `alarm_at=LINE:CODE` raises the alarm there; alarm 1, a hard limit, is critical
    (interface.md: "Only hard or soft limit errors send this message immediately after the
    ALARM:x code")."""
    p = open_port(FAST + "&error_at=2:20&alarm_at=5:1", timeout=0.5)
    try:
        read_boot(p)
        assert send(p, "G1 X-1 F1000") == ["ok"]
        assert send(p, "G1 X-2") == ["error:20"]
        assert send(p, "G1 X-3") == ["ok"]
        assert send(p, "G4 P0") == ["ok"]
        p.write(b"G1 X-4\n")
        assert read_line(p) == "ALARM:1"
        assert read_line(p) == C.MSG_RESET_TO_CONTINUE
        p.write(b"G1 X-5\n")
        assert p.readline() == b""
        assert [s.x1 for s in p.emulator.trace] == [-1.0, -3.0]
    finally:
        p.close()


@pytest.mark.parametrize(("fault", "x"), [("drop_byte_at=19", -2.0), ("flip_byte_at=20", -13.0)])
def test_injected_byte_faults_corrupt_the_line(fault, x):
    """A byte lost or flipped on the wire changes what GRBL parses (bytes count from 1: the
    second line `G1 X-12` spans bytes 14-21)."""
    p = open_port(f"{FAST}&{fault}")
    try:
        read_boot(p)
        assert send(p, "G1 X-1 F1000") == ["ok"]  # 13 bytes with its newline
        assert send(p, "G1 X-12") == ["ok"]
        assert send(p, "G4 P0") == ["ok"]
        assert p.emulator.trace[-1].x1 == x
    finally:
        p.close()


@pytest.mark.parametrize(("fault", "x"), [("dup_byte_at=20", -122.0),
                                          ("insert_at=20:35", -152.0)])
def test_injected_byte_duplicated_or_inserted_toward_grbl(fault, x):
    """`dup_byte_at=N` delivers byte N twice; `insert_at=N:HEX` puts a burst before it."""
    p = open_port(f"{FAST}&{fault}")
    try:
        read_boot(p)
        assert send(p, "G1 X-1 F1000") == ["ok"]
        assert send(p, "G1 X-12") == ["ok"]
        assert send(p, "G4 P0") == ["ok"]
        assert p.emulator.trace[-1].x1 == x
    finally:
        p.close()


def test_injected_faults_on_grbls_transmit_line():
    """`out_*` corrupt the bytes GRBL sends (counted from its start-up message), and
    `drop_ok_at` / `dup_ok_at` lose or double its K-th `ok`."""
    boot = len(f"\r\n{C.BANNER}\r\n")
    p = open_port(f"{FAST}&out_flip_at={boot + 1}&drop_ok_at=2&dup_ok_at=3"
                  f"&out_insert_at={boot + 5}:213e0d0a")
    try:
        assert read_boot(p)[:2] == ["", C.BANNER]
        p.write(b"G4P0\nG4P0\nG4P0\n")
        time.sleep(0.1)
        # `ok` with o^1 = n; the second `ok` lost; the third twice, a burst before it
        assert p.read(100) == b"nk\r\n!>\r\nok\r\nok\r\n"
    finally:
        p.close()


def test_injected_reset_at_line():
    """`reset_at=LINE`: a soft reset as that line arrives; "The start up message always prints
    upon startup and after a reset."."""
    p = open_port(FAST + "&reset_at=3")
    try:
        read_boot(p)
        assert send(p, "G0 X-1") == ["ok"]
        assert send(p, "G4 P0") == ["ok"]
        p.write(b"G0 X-2\n")
        assert read_boot(p)[:2] == ["", C.BANNER]
        assert send(p, "G4 P0") == ["ok"]
        assert [s.x1 for s in p.emulator.trace] == [-1.0]
    finally:
        p.close()


def test_disconnect_makes_the_port_disappear_and_reopen_finds_the_machine():
    """`disconnect_at=LINE`: the port disappears (reads and writes raise SerialException, as
    pyserial does for an unplugged USB port); the machine keeps running what it received, and
    reopening the same `name` reaches it."""
    name = "test-disconnect"
    p = open_port(f"speed=100&name={name}&disconnect_at=2")
    try:
        read_boot(p)
        assert send(p, "G1 X-5 F3000") == ["ok"]
        p.write(b"G1 X-8\n")
        with pytest.raises(serial.SerialException):
            p.read(1)
        with pytest.raises(serial.SerialException):
            p.write(b"?")
        p.close()
        q = serial.serial_for_url(f"grblsim://?name={name}", timeout=2)
        try:
            assert q.emulator is p.emulator
            assert send(q, "G4 P0") == ["ok"]
            assert status(q).startswith("<Idle|MPos:-8.000,0.000,0.000")
        finally:
            q.close()
    finally:
        forget(name)


def test_power_cut_loses_position_keeps_settings():
    """`power_cut_at=LINE`: "Most of these parameters are directly written to EEPROM anytime they
    are changed and are persistent. Meaning that they will remain the same, regardless of
    power-down" (commands.md `$#`); machine position is RAM and is lost; GRBL boots again with
    its start-up message."""
    name = "test-power"
    p = open_port(f"speed=100&name={name}&power_cut_at=4")
    try:
        read_boot(p)
        assert send(p, "$110=900") == ["ok"]
        assert send(p, "G10 L2 P1 X-3") == ["ok"]
        assert send(p, "G0 X-10 G92 X0") == ["error:24"]
        p.write(b"G1 X-20 F500\n")
        assert read_boot(p)[:2] == ["", C.BANNER]
        assert status(p).startswith("<Idle|MPos:0.000,0.000,0.000")
        assert "$110=900.000" in send(p, "$$")
        assert send(p, "$#")[0] == "[G54:-3.000,0.000,0.000]"
        p.emulator.power_cut()
        assert read_boot(p)[:2] == ["", C.BANNER]
    finally:
        p.close()
        forget(name)


def test_methods_inject_reset_disconnect(port):
    """The machine object offers the same faults as methods for tests: `inject_reset()` acts as
    0x18, `disconnect()` makes the port vanish."""
    port.emulator.inject_reset()
    assert read_boot(port) == ["", C.BANNER]
    port.emulator.disconnect()
    with pytest.raises(serial.SerialException, match="disconnected"):
        port.in_waiting  # noqa: B018


# --------------------------------------------------------------------------- pyserial semantics
def test_pyserial_timeouts_cancel_and_closed_port():
    """pyserial semantics: timeout 0 never blocks, timeout None blocks until data or
    cancel_read(), and a closed port raises PortNotOpenError."""
    p = serial.serial_for_url("grblsim://?speed=1000", timeout=0)
    read_boot_nonblocking = p.read(1000)
    assert C.BANNER.encode() in read_boot_nonblocking
    t0 = time.monotonic()
    assert p.read(10) == b""
    assert time.monotonic() - t0 < 0.05
    p.timeout = None
    result: list[bytes] = []
    reader = threading.Thread(target=lambda: result.append(p.read(10)))
    reader.start()
    time.sleep(0.05)
    p.cancel_read()
    reader.join(2)
    assert not reader.is_alive() and result == [b""]
    p.close()
    with pytest.raises(serial.PortNotOpenError):
        p.read(1)
    with pytest.raises(serial.PortNotOpenError):
        p.write(b"?")
    assert simulators.grbl.lookup("nonexistent") is None
