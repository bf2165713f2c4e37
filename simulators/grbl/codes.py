"""GRBL 1.1h constants: status/alarm codes, default settings, build options.

The numbers come from the GRBL 1.1 documentation (gnea/grbl doc/csv/error_codes_en_US.csv,
alarm_codes_en_US.csv, doc/markdown/interface.md, settings.md); the emulator must answer with
exactly these so a sender written against it works against the real controller.
"""

from __future__ import annotations

VERSION = "1.1h"
BUILD_DATE = "20190830"
BANNER = f"Grbl {VERSION} ['$' for help]"
HELP = "[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? ctrl-x]"

RX_BUFFER_SIZE = 128  # "Grbl has a 128 character serial receive buffer" (interface.md)
PLANNER_BLOCKS = 15  # `$I` reports "[OPT:V,15,128]": 15 usable planner blocks
# The stepper's segment clock (stepper.c): a step segment lasts DT_SEGMENT = 1/(60 *
# ACCELERATION_TICKS_PER_SECOND) min with ACCELERATION_TICKS_PER_SECOND 100, and the segment
# buffer (SEGMENT_BUFFER_SIZE 6) holds 5 of them: the executing one and 4 prepared ahead.
DT_SEGMENT = 0.01  # seconds
SEGMENTS_AHEAD = 4
LINE_BUFFER_SIZE = 80  # at most 79 significant characters per line, else error:11
N_STARTUP_LINES = 2
MAX_LINE_NUMBER = 9_999_999
MAX_TOOL_NUMBER = 255

# Status codes (error:N), doc/csv/error_codes_en_US.csv.
E_EXPECTED_COMMAND_LETTER = 1
E_BAD_NUMBER_FORMAT = 2
E_INVALID_STATEMENT = 3
E_NEGATIVE_VALUE = 4
E_SETTING_DISABLED = 5
E_SETTING_STEP_PULSE_MIN = 6
E_SETTING_READ_FAIL = 7
E_IDLE_ERROR = 8
E_SYSTEM_GC_LOCK = 9
E_SOFT_LIMIT_ERROR = 10
E_OVERFLOW = 11
E_MAX_STEP_RATE_EXCEEDED = 12
E_CHECK_DOOR = 13
E_LINE_LENGTH_EXCEEDED = 14
E_TRAVEL_EXCEEDED = 15
E_INVALID_JOG_COMMAND = 16
E_SETTING_DISABLED_LASER = 17
E_GCODE_UNSUPPORTED_COMMAND = 20
E_GCODE_MODAL_GROUP_VIOLATION = 21
E_GCODE_UNDEFINED_FEED_RATE = 22
E_GCODE_COMMAND_VALUE_NOT_INTEGER = 23
E_GCODE_AXIS_COMMAND_CONFLICT = 24
E_GCODE_WORD_REPEATED = 25
E_GCODE_NO_AXIS_WORDS = 26
E_GCODE_INVALID_LINE_NUMBER = 27
E_GCODE_VALUE_WORD_MISSING = 28
E_GCODE_UNSUPPORTED_COORD_SYS = 29
E_GCODE_G53_INVALID_MOTION_MODE = 30
E_GCODE_AXIS_WORDS_EXIST = 31
E_GCODE_NO_AXIS_WORDS_IN_PLANE = 32
E_GCODE_INVALID_TARGET = 33
E_GCODE_ARC_RADIUS_ERROR = 34
E_GCODE_NO_OFFSETS_IN_PLANE = 35
E_GCODE_UNUSED_WORDS = 36
E_GCODE_G43_DYNAMIC_AXIS_ERROR = 37
E_GCODE_MAX_VALUE_EXCEEDED = 38

ERROR_CODES = {
    1: "Expected command letter",
    2: "Bad number format",
    3: "Invalid statement",
    4: "Value < 0",
    5: "Setting disabled",
    6: "Value < 3 usec",
    7: "EEPROM read fail. Using defaults",
    8: "Not idle",
    9: "G-code lock",
    10: "Homing not enabled",
    11: "Line overflow",
    12: "Step rate > 30kHz",
    13: "Check Door",
    14: "Line length exceeded",
    15: "Travel exceeded",
    16: "Invalid jog command",
    17: "Setting disabled",
    20: "Unsupported command",
    21: "Modal group violation",
    22: "Undefined feed rate",
    23: "Invalid gcode ID:23",
    24: "Invalid gcode ID:24",
    25: "Invalid gcode ID:25",
    26: "Invalid gcode ID:26",
    27: "Invalid gcode ID:27",
    28: "Invalid gcode ID:28",
    29: "Invalid gcode ID:29",
    30: "Invalid gcode ID:30",
    31: "Invalid gcode ID:31",
    32: "Invalid gcode ID:32",
    33: "Invalid gcode ID:33",
    34: "Invalid gcode ID:34",
    35: "Invalid gcode ID:35",
    36: "Invalid gcode ID:36",
    37: "Invalid gcode ID:37",
    38: "Invalid gcode ID:38",
}

# Alarm codes (ALARM:N), doc/csv/alarm_codes_en_US.csv.
A_HARD_LIMIT = 1
A_SOFT_LIMIT = 2
A_ABORT_CYCLE = 3
A_PROBE_FAIL_INITIAL = 4
A_PROBE_FAIL_CONTACT = 5
A_HOMING_FAIL_RESET = 6
A_HOMING_FAIL_DOOR = 7
A_HOMING_FAIL_PULLOFF = 8
A_HOMING_FAIL_APPROACH = 9

ALARM_CODES = {
    1: "Hard limit",
    2: "Soft limit",
    3: "Abort during cycle",
    4: "Probe fail",
    5: "Probe fail",
    6: "Homing fail",
    7: "Homing fail",
    8: "Homing fail",
    9: "Homing fail",
}
# "Only hard or soft limit errors send this message immediately after the ALARM:x code."
CRITICAL_ALARMS = frozenset({A_HARD_LIMIT, A_SOFT_LIMIT})

MSG_RESET_TO_CONTINUE = "[MSG:Reset to continue]"
MSG_UNLOCK = "[MSG:'$H'|'$X' to unlock]"
MSG_UNLOCKED = "[MSG:Caution: Unlocked]"
MSG_ENABLED = "[MSG:Enabled]"
MSG_DISABLED = "[MSG:Disabled]"
MSG_PGM_END = "[MSG:Pgm End]"
MSG_RESTORING = "[MSG:Restoring defaults]"
MSG_SLEEPING = "[MSG:Sleeping]"

# Default `$$` settings of the generic 1.1h build (defaults.h), in `$$` print order.
DEFAULT_SETTINGS: dict[int, float] = {
    0: 10, 1: 25, 2: 0, 3: 0, 4: 0, 5: 0, 6: 0,
    10: 1, 11: 0.010, 12: 0.002, 13: 0,
    20: 0, 21: 0, 22: 0, 23: 0, 24: 25.0, 25: 500.0, 26: 250, 27: 1.0,
    30: 1000.0, 31: 0.0, 32: 0,
    100: 250.0, 101: 250.0, 102: 250.0,
    110: 500.0, 111: 500.0, 112: 500.0,
    120: 10.0, 121: 10.0, 122: 10.0,
    130: 200.0, 131: 200.0, 132: 200.0,
}  # fmt: skip
# Settings stored as integers (printed without decimals); $30/$31 print with 0 decimals too.
INT_SETTINGS = frozenset({0, 1, 2, 3, 4, 5, 6, 10, 13, 20, 21, 22, 23, 26, 32})
ZERO_DECIMAL_SETTINGS = frozenset({30, 31})
MAX_STEP_RATE_HZ = 30000.0

# Real-time command bytes (commands.md, "Grbl v1.1 Realtime commands").
RT_RESET = 0x18
RT_STATUS = ord("?")
RT_CYCLE_START = ord("~")
RT_FEED_HOLD = ord("!")
RT_SAFETY_DOOR = 0x84
RT_JOG_CANCEL = 0x85
RT_FEED_OVR_RESET = 0x90
RT_FEED_OVR_COARSE_PLUS = 0x91
RT_FEED_OVR_COARSE_MINUS = 0x92
RT_FEED_OVR_FINE_PLUS = 0x93
RT_FEED_OVR_FINE_MINUS = 0x94
RT_RAPID_OVR_RESET = 0x95
RT_RAPID_OVR_MEDIUM = 0x96
RT_RAPID_OVR_LOW = 0x97
RT_SPINDLE_OVR_RESET = 0x99
RT_SPINDLE_OVR_COARSE_PLUS = 0x9A
RT_SPINDLE_OVR_COARSE_MINUS = 0x9B
RT_SPINDLE_OVR_FINE_PLUS = 0x9C
RT_SPINDLE_OVR_FINE_MINUS = 0x9D
RT_SPINDLE_OVR_STOP = 0x9E
RT_COOLANT_FLOOD_OVR_TOGGLE = 0xA0
RT_COOLANT_MIST_OVR_TOGGLE = 0xA1

# Status report refresh counts (config.h defaults quoted in interface.md: "every 10 or 30").
REPORT_WCO_REFRESH_BUSY = 30
REPORT_WCO_REFRESH_IDLE = 10
REPORT_OVR_REFRESH_BUSY = 20
REPORT_OVR_REFRESH_IDLE = 10
