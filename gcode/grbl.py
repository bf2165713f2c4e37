"""GRBL 1.1 protocol: response parsing, error and alarm codes, settings checks.

Every line GRBL can send is classified by :func:`parse_response` without context, as the
GRBL 1.1 interface document promises ("All messages are designed to be deterministic
without needing to know the context of the message"). The streamer relies on that: only
``ok`` and ``error:N`` count against the character-counting budget.

References: gnea/grbl ``doc/markdown/interface.md``, ``doc/csv/error_codes_en_US.csv``,
``doc/csv/alarm_codes_en_US.csv``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from gcode.machine import Machine

__all__ = [
    "ALARM_CODES",
    "ERROR_CODES",
    "SETTINGS",
    "Response",
    "Status",
    "alarm_message",
    "check_settings",
    "error_message",
    "parse_response",
    "parse_settings",
    "parse_status",
    "time_scale_of",
]

#: error:N -> (short name, description), GRBL 1.1 doc/csv/error_codes_en_US.csv.
ERROR_CODES: dict[int, tuple[str, str]] = {
    1: ("Expected command letter",
        "G-code words consist of a letter and a value. Letter was not found."),
    2: ("Bad number format",
        "Missing the expected G-code word value or numeric value format is not valid."),
    3: ("Invalid statement", "Grbl '$' system command was not recognized or supported."),
    4: ("Value < 0", "Negative value received for an expected positive value."),
    5: ("Setting disabled", "Homing cycle failure. Homing is not enabled via settings."),
    6: ("Value < 3 usec", "Minimum step pulse time must be greater than 3usec."),
    7: ("EEPROM read fail. Using defaults",
        "An EEPROM read failed. Auto-restoring affected EEPROM to default values."),
    8: ("Not idle",
        "Grbl '$' command cannot be used unless Grbl is IDLE. "
        "Ensures smooth operation during a job."),
    9: ("G-code lock", "G-code commands are locked out during alarm or jog state."),
    10: ("Homing not enabled", "Soft limits cannot be enabled without homing also enabled."),
    11: ("Line overflow",
         "Max characters per line exceeded. Received command line was not executed."),
    12: ("Step rate > 30kHz",
          "Grbl '$' setting value cause the step rate to exceed the maximum supported."),
    13: ("Check Door", "Safety door detected as opened and door state initiated."),
    14: ("Line length exceeded",
         "Build info or startup line exceeded EEPROM line length limit. Line not stored."),
    15: ("Travel exceeded", "Jog target exceeds machine travel. Jog command has been ignored."),
    16: ("Invalid jog command", "Jog command has no '=' or contains prohibited g-code."),
    17: ("Setting disabled", "Laser mode requires PWM output."),
    20: ("Unsupported command", "Unsupported or invalid g-code command found in block."),
    21: ("Modal group violation",
         "More than one g-code command from same modal group found in block."),
    22: ("Undefined feed rate", "Feed rate has not yet been set or is undefined."),
    23: ("Invalid gcode ID:23", "G-code command in block requires an integer value."),
    24: ("Invalid gcode ID:24",
         "More than one g-code command that requires axis words found in block."),
    25: ("Invalid gcode ID:25", "Repeated g-code word found in block."),
    26: ("Invalid gcode ID:26",
         "No axis words found in block for g-code command or current modal state "
         "which requires them."),
    27: ("Invalid gcode ID:27", "Line number value is invalid."),
    28: ("Invalid gcode ID:28", "G-code command is missing a required value word."),
    29: ("Invalid gcode ID:29", "G59.x work coordinate systems are not supported."),
    30: ("Invalid gcode ID:30", "G53 only allowed with G0 and G1 motion modes."),
    31: ("Invalid gcode ID:31",
         "Axis words found in block when no command or current modal state uses them."),
    32: ("Invalid gcode ID:32", "G2 and G3 arcs require at least one in-plane axis word."),
    33: ("Invalid gcode ID:33", "Motion command target is invalid."),
    34: ("Invalid gcode ID:34", "Arc radius value is invalid."),
    35: ("Invalid gcode ID:35", "G2 and G3 arcs require at least one in-plane offset word."),
    36: ("Invalid gcode ID:36", "Unused value words found in block."),
    37: ("Invalid gcode ID:37",
         "G43.1 dynamic tool length offset is not assigned to configured tool length axis."),
    38: ("Invalid gcode ID:38", "Tool number greater than max supported value."),
}

#: ALARM:N -> (short name, description), GRBL 1.1 doc/csv/alarm_codes_en_US.csv.
ALARM_CODES: dict[int, tuple[str, str]] = {
    1: ("Hard limit",
        "Hard limit has been triggered. Machine position is likely lost due to sudden halt. "
        "Re-homing is highly recommended."),
    2: ("Soft limit",
        "Soft limit alarm. G-code motion target exceeds machine travel. Machine position "
        "retained. Alarm may be safely unlocked."),
    3: ("Abort during cycle",
        "Reset while in motion. Machine position is likely lost due to sudden halt. "
        "Re-homing is highly recommended."),
    4: ("Probe fail",
        "Probe fail. Probe is not in the expected initial state before starting probe cycle "
        "when G38.2 and G38.3 is not triggered and G38.4 and G38.5 is triggered."),
    5: ("Probe fail",
        "Probe fail. Probe did not contact the workpiece within the programmed travel "
        "for G38.2 and G38.4."),
    6: ("Homing fail", "Homing fail. The active homing cycle was reset."),
    7: ("Homing fail", "Homing fail. Safety door was opened during homing cycle."),
    8: ("Homing fail",
        "Homing fail. Pull off travel failed to clear limit switch. Try increasing pull-off "
        "setting or check wiring."),
    9: ("Homing fail",
        "Homing fail. Could not find limit switch within search distances. Try increasing "
        "max travel, decreasing pull-off distance, or check wiring."),
}

#: $x -> (description, unit), from interface.md's settings table.
SETTINGS: dict[int, tuple[str, str]] = {
    0: ("Step pulse time", "microseconds"),
    1: ("Step idle delay", "milliseconds"),
    2: ("Step pulse invert", "mask"),
    3: ("Step direction invert", "mask"),
    4: ("Invert step enable pin", "boolean"),
    5: ("Invert limit pins", "boolean"),
    6: ("Invert probe pin", "boolean"),
    10: ("Status report options", "mask"),
    11: ("Junction deviation", "millimeters"),
    12: ("Arc tolerance", "millimeters"),
    13: ("Report in inches", "boolean"),
    20: ("Soft limits enable", "boolean"),
    21: ("Hard limits enable", "boolean"),
    22: ("Homing cycle enable", "boolean"),
    23: ("Homing direction invert", "mask"),
    24: ("Homing locate feed rate", "mm/min"),
    25: ("Homing search seek rate", "mm/min"),
    26: ("Homing switch debounce delay", "milliseconds"),
    27: ("Homing switch pull-off distance", "millimeters"),
    30: ("Maximum spindle speed", "RPM"),
    31: ("Minimum spindle speed", "RPM"),
    32: ("Laser-mode enable", "boolean"),
    100: ("X-axis steps per millimeter", "steps/mm"),
    101: ("Y-axis steps per millimeter", "steps/mm"),
    102: ("Z-axis steps per millimeter", "steps/mm"),
    110: ("X-axis maximum rate", "mm/min"),
    111: ("Y-axis maximum rate", "mm/min"),
    112: ("Z-axis maximum rate", "mm/min"),
    120: ("X-axis acceleration", "mm/sec^2"),
    121: ("Y-axis acceleration", "mm/sec^2"),
    122: ("Z-axis acceleration", "mm/sec^2"),
    130: ("X-axis maximum travel", "millimeters"),
    131: ("Y-axis maximum travel", "millimeters"),
    132: ("Z-axis maximum travel", "millimeters"),
}


def error_message(code: int) -> str:
    """``error:N`` as an operator-readable sentence (unknown codes are said to be unknown)."""
    short, desc = ERROR_CODES.get(code, ("Unknown error", "Not in the GRBL 1.1 error table."))
    return f"error:{code} {short}: {desc}"


def alarm_message(code: int) -> str:
    """``ALARM:N`` as an operator-readable sentence."""
    short, desc = ALARM_CODES.get(code, ("Unknown alarm", "Not in the GRBL 1.1 alarm table."))
    return f"ALARM:{code} {short}: {desc}"


@dataclass
class Status:
    """A real-time status report ``<State|MPos:...|...>``; absent fields stay None.

    GRBL sends the machine state and a position always; every other field may or may not
    appear and in any order, so each is optional here.
    """

    state: str
    substate: int | None = None
    mpos: tuple[float, ...] | None = None
    wpos: tuple[float, ...] | None = None
    wco: tuple[float, ...] | None = None
    planner_free: int | None = None  # Bf: first value, free planner blocks
    rx_free: int | None = None  # Bf: second value, free bytes in the serial RX buffer
    line_number: int | None = None  # Ln:
    feed: float | None = None  # F: or FS: first value
    speed: float | None = None  # FS: second value
    pins: str | None = None  # Pn:
    overrides: tuple[int, int, int] | None = None  # Ov: feed, rapid, spindle percent
    accessories: str | None = None  # A: S/C spindle, F flood, M mist
    extra: dict[str, str] = field(default_factory=dict)  # fields newer than GRBL 1.1

    def position(self) -> tuple[float, ...] | None:
        """Machine position: MPos, or WPos + WCO when only those were reported."""
        if self.mpos is not None:
            return self.mpos
        if self.wpos is not None and self.wco is not None:
            return tuple(w + o for w, o in zip(self.wpos, self.wco, strict=False))
        return None


@dataclass
class Response:
    """One line from GRBL, classified.

    kind is one of ``ok``, ``error``, ``alarm``, ``status``, ``banner``, ``msg``, ``gc``,
    ``help``, ``ver``, ``opt``, ``echo``, ``param`` ($# data), ``setting`` ($x=val),
    ``startup_line`` ($Nx=line), ``startup_exec`` (>line:ok), ``feedback`` (any other
    ``[...]``), ``empty`` or ``unknown`` (a garbled line: the streamer treats it as a fault).
    """

    kind: str
    raw: str
    code: int | None = None  # error/alarm number, setting number, startup line number
    text: str | None = None  # message text, setting value text, banner version, ...
    status: Status | None = None
    value: float | None = None  # numeric setting value

    @property
    def message(self) -> str:
        if self.kind == "error" and self.code is not None:
            return error_message(self.code)
        if self.kind == "alarm" and self.code is not None:
            return alarm_message(self.code)
        return self.raw


_BANNER = re.compile(r"^Grbl\s+(\S+)\s*\[.*\]\s*$")
_ERROR = re.compile(r"^error:(\d+)$")
_ALARM = re.compile(r"^ALARM:(\d+)$")
_SETTING = re.compile(r"^\$(\d+)=([-+0-9.]+)$")
_STARTUP = re.compile(r"^\$N(\d)=(.*)$")
_STARTUP_EXEC = re.compile(r"^>(.*):(ok|error:\d+)$")
_FEEDBACK = re.compile(r"^\[([A-Za-z0-9]+):(.*)\]$")
_PARAM_KEYS = {"G54", "G55", "G56", "G57", "G58", "G59", "G28", "G30", "G92", "TLO", "PRB"}


def _floats(text: str) -> tuple[float, ...]:
    return tuple(float(v) for v in text.split(","))


def parse_status(line: str) -> Status:
    """Parse ``<Run|MPos:1.000,2.000,0.000|Bf:15,128|FS:500,0|Ov:100,100,100|A:S>``.

    Raises ValueError on a report that is not well formed (a dropped byte can do that).
    """
    if not (line.startswith("<") and line.endswith(">")) or len(line) < 3:
        raise ValueError(f"not a status report: {line!r}")
    fields = line[1:-1].split("|")
    state, _, sub = fields[0].partition(":")
    if not state.isalpha():
        raise ValueError(f"bad machine state in status report: {line!r}")
    st = Status(state=state, substate=int(sub) if sub else None)
    for f in fields[1:]:
        key, sep, val = f.partition(":")
        if not sep:
            raise ValueError(f"bad field {f!r} in status report: {line!r}")
        if key == "MPos":
            st.mpos = _floats(val)
        elif key == "WPos":
            st.wpos = _floats(val)
        elif key == "WCO":
            st.wco = _floats(val)
        elif key == "Bf":
            a, b = val.split(",")
            st.planner_free, st.rx_free = int(a), int(b)
        elif key == "Ln":
            st.line_number = int(val)
        elif key == "F":
            st.feed = float(val)
        elif key == "FS":
            a, b = val.split(",")
            st.feed, st.speed = float(a), float(b)
        elif key == "Pn":
            st.pins = val
        elif key == "Ov":
            a, b, c = val.split(",")
            st.overrides = (int(a), int(b), int(c))
        elif key == "A":
            st.accessories = val
        else:
            st.extra[key] = val
    if st.mpos is None and st.wpos is None:
        raise ValueError(f"status report without a position: {line!r}")
    return st


def parse_response(line: str) -> Response:
    """Classify one line received from GRBL (without its line ending).

    Never raises: a line that fits no GRBL 1.1 message form comes back as ``unknown``.
    """
    s = line.strip()
    if not s:
        return Response("empty", line)
    if s == "ok":
        return Response("ok", line)
    if m := _ERROR.match(s):
        return Response("error", line, code=int(m.group(1)))
    if m := _ALARM.match(s):
        return Response("alarm", line, code=int(m.group(1)))
    if s.startswith("<"):
        try:
            return Response("status", line, status=parse_status(s))
        except ValueError:
            return Response("unknown", line)
    if m := _BANNER.match(s):
        return Response("banner", line, text=m.group(1))
    if m := _SETTING.match(s):
        try:
            value = float(m.group(2))
        except ValueError:
            return Response("unknown", line)
        return Response("setting", line, code=int(m.group(1)), text=m.group(2), value=value)
    if m := _STARTUP.match(s):
        return Response("startup_line", line, code=int(m.group(1)), text=m.group(2))
    if m := _STARTUP_EXEC.match(s):
        return Response("startup_exec", line, text=m.group(1))
    if m := _FEEDBACK.match(s):
        key, body = m.group(1), m.group(2)
        kind = {"MSG": "msg", "GC": "gc", "HLP": "help", "VER": "ver", "OPT": "opt",
                "echo": "echo"}.get(key)
        if kind is None:
            kind = "param" if key in _PARAM_KEYS else "feedback"
        return Response(kind, line, text=body if kind != "param" else f"{key}:{body}")
    return Response("unknown", line)


_TIME_SCALE = re.compile(r"(?:^|[\s:])grblsim speed=([0-9.]+(?:[eE][-+]?[0-9]+)?)(?:\s|$)")


def time_scale_of(ver: str) -> float:
    """Machine seconds per wall second, from the build info of ``$I``'s ``[VER:...]`` line:
    the emulator (``simulators.grbl``) ends it with ``grblsim speed=S``; a real GRBL, whose
    machine runs on the wall clock, says nothing of it (1)."""
    found = _TIME_SCALE.findall(ver)
    try:
        scale = float(found[-1]) if found else 1.0
    except ValueError:
        return 1.0
    return scale if math.isfinite(scale) and scale > 0 else 1.0


def parse_settings(lines: list[str]) -> dict[int, float]:
    """``$$`` printout lines -> {setting number: value}; other lines are ignored."""
    out: dict[int, float] = {}
    for line in lines:
        r = parse_response(line)
        if r.kind == "setting" and r.code is not None and r.value is not None:
            out[r.code] = r.value
    return out


def check_settings(settings: dict[int, float], machine: Machine) -> list[str]:
    """Faults of the controller's settings against the machine profile, one sentence each.

    WHY: a program validated against the profile is only safe if the controller agrees
    with the profile: laser mode off would keep the beam on through every M5 sync stop,
    a different $30 rescales every S word, and too short travels trip soft limits mid-cut.
    """
    faults: list[str] = []

    def get(n: int) -> float | None:
        return settings.get(n)

    if machine.tool == "laser":
        if get(32) is not None and int(get(32)) != 1:
            faults.append("$32 laser mode is off on the controller; the laser profile needs $32=1")
        if get(30) is not None and abs(get(30) - machine.max_s) > 1e-6:
            faults.append(f"$30 maximum spindle/laser S is {get(30):g} on the controller, "
                          f"the profile says {machine.max_s:g}")
    x0, y0, x1, y1 = machine.work_area
    for axis, n_rate, n_travel, extent in (("X", 110, 130, x1), ("Y", 111, 131, y1)):
        if get(n_rate) is not None and get(n_rate) + 1e-6 < machine.max_feed:
            faults.append(f"${n_rate} {axis} maximum rate {get(n_rate):g} mm/min is below the "
                          f"profile's max_feed {machine.max_feed:g}")
        n_acc = n_rate + 10
        if get(n_acc) is not None and get(n_acc) + 1e-6 < machine.acceleration:
            faults.append(f"${n_acc} {axis} acceleration {get(n_acc):g} mm/s^2 is below the "
                          f"profile's acceleration {machine.acceleration:g} (the feed watchdog "
                          "expects the programmed feed within that acceleration time)")
        if get(n_travel) is not None and get(n_travel) + 1e-6 < extent:
            faults.append(f"${n_travel} {axis} maximum travel {get(n_travel):g} mm is shorter "
                          f"than the profile's work area ({extent:g} mm)")
    if get(13) is not None and int(get(13)) != 0:
        faults.append("$13 reports in inches; the station works in millimetres ($13=0)")
    return faults
