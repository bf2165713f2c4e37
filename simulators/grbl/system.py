"""The emulated controller's system side: `$` commands, settings, real-time bytes, homing,
soft reset and boot.

`$` lines go through two tables as in GRBL's system_execute_line: commands allowed in any
state (`$J=`, `$$`, `$G`, `$C`, `$X`) and commands only while Idle or in Alarm (`$#`, `$H`,
`$SLP`, `$I`, `$RST`, `$N`), anything else being `$x=value`. Real-time bytes are picked off
the receive line on arrival and go through `SystemCommands._REALTIME`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

import simulators.grbl.codes as C
from simulators.grbl.executor import Executor
from simulators.grbl.parser_state import GrblError, Params, fmt, gc_report


def _clamp_pct(lo: float, hi: float) -> Callable[[float], Callable[[float], float]]:
    """Override steps: ``make(delta)`` adds ``delta`` percent, kept within [lo, hi]."""

    def make(delta: float) -> Callable[[float], float]:
        return lambda v: min(max(v + delta, lo), hi)

    return make


_feed = _clamp_pct(10.0, 200.0)
_FEED_OVR = {
    C.RT_FEED_OVR_RESET: lambda v: 100.0,
    C.RT_FEED_OVR_COARSE_PLUS: _feed(10),
    C.RT_FEED_OVR_COARSE_MINUS: _feed(-10),
    C.RT_FEED_OVR_FINE_PLUS: _feed(1),
    C.RT_FEED_OVR_FINE_MINUS: _feed(-1),
}
_RAPID_OVR = {C.RT_RAPID_OVR_RESET: 100.0, C.RT_RAPID_OVR_MEDIUM: 50.0, C.RT_RAPID_OVR_LOW: 25.0}
_spin = _clamp_pct(10.0, 200.0)
_SPINDLE_OVR = {
    C.RT_SPINDLE_OVR_RESET: lambda v: 100.0,
    C.RT_SPINDLE_OVR_COARSE_PLUS: _spin(10),
    C.RT_SPINDLE_OVR_COARSE_MINUS: _spin(-10),
    C.RT_SPINDLE_OVR_FINE_PLUS: _spin(1),
    C.RT_SPINDLE_OVR_FINE_MINUS: _spin(-1),
}
_RESTORE = {"$RST=$": "$", "$RST=#": "#", "$RST=*": "*"}


def _two_letters(line: str) -> None:
    """`$$`, `$G`, `$C`, `$X`, `$#` take nothing after their letter."""
    if len(line) != 2:
        raise GrblError(C.E_INVALID_STATEMENT)


class SystemCommands(Executor):
    """`$` commands, settings, real-time bytes, homing, reset and boot (a base of
    `GrblEmulator`)."""

    # ------------------------------------------------------------------ boot / reset
    def _power_on(self) -> None:
        self._pos = np.zeros(3)
        self._state = "Idle"
        if self.settings[22]:
            self._state = "Alarm"  # homing enabled: position unknown at power-up
        self._reinit()

    def _reinit(self) -> None:
        """GRBL's main-loop initialisation after power-up or soft reset."""
        self._clear_ram()
        self._emit("")
        self._emit(C.BANNER)
        if self._state in ("Alarm", "Sleep"):
            self._state = "Alarm"
            self._emit(C.MSG_UNLOCK)
        else:
            self._state = "Idle"
            self._run_startup_lines()

    def _run_startup_lines(self) -> None:
        for line in self.startup_lines:
            if line:
                try:
                    actions = self._gcode(line)
                except GrblError as exc:
                    self._emit(f">{line}:error:{exc.code}")
                else:
                    self._pending.extend(actions)
                    self._pending.append(("emit", f">{line}:ok", False))

    def _soft_reset(self) -> None:
        moving = (self._state in ("Run", "Jog", "Home")
                  or (self._state == "Hold" and not self._hold_complete))
        ok_first = any(a[0] == "softlimit_ok" for a in self._pending)
        if moving:
            code = C.A_HOMING_FAIL_RESET if self._state == "Home" else C.A_ABORT_CYCLE
            self._stop_motion()
            self._state = "Alarm"
            self._emit(f"ALARM:{code}")
        else:
            self._stop_motion()
        if self._state in ("Check", "Hold", "Run", "Jog"):
            self._state = "Idle"
        if ok_first:
            # The line that hit the soft limit returns from the parser after the reset and
            # reports its `ok` before GRBL re-initialises (protocol_main_loop order).
            self._emit("ok")
        self._reinit()

    # ------------------------------------------------------------------ real-time bytes
    def _realtime(self, byte: int) -> bool:
        """Handle a real-time command byte; True if it was one (never enters the buffer)."""
        handler = self._REALTIME.get(byte)
        if handler is None:
            return False
        handler(self, byte)
        return True

    def _rt_reset(self, byte: int) -> None:
        self._soft_reset()

    def _rt_status(self, byte: int) -> None:
        if not self._critical and self._state != "Home":
            self._emit(self._status_report())

    def _rt_feed_hold(self, byte: int) -> None:
        if self._state == "Jog":
            self._start_jog_cancel()
        elif self._state in ("Idle", "Run"):
            self._state = "Hold"
            self._hold = True
            self._hold_complete = self._v <= 0.0

    def _rt_cycle_start(self, byte: int) -> None:
        if self._state == "Hold" and self._hold_complete:
            self._resume()

    def _rt_jog_cancel(self, byte: int) -> None:
        if self._state == "Jog" and not self._jog_cancel:
            self._start_jog_cancel()

    def _rt_feed_override(self, byte: int) -> None:
        self._feed_ovr = _FEED_OVR[byte](self._feed_ovr)
        self._ovr_counter = 0

    def _rt_rapid_override(self, byte: int) -> None:
        self._rapid_ovr = _RAPID_OVR[byte]
        self._ovr_counter = 0

    def _rt_spindle_override(self, byte: int) -> None:
        self._spindle_ovr = _SPINDLE_OVR[byte](self._spindle_ovr)
        self._ovr_counter = 0

    def _rt_spindle_stop(self, byte: int) -> None:
        if self._state == "Hold":
            self._split_trace()  # the beam changes here, mid-block
            self._spindle_stop = not self._spindle_stop

    def _rt_flood(self, byte: int) -> None:
        if self._state in ("Idle", "Run", "Hold"):
            self._flood = not self._flood
            self._gc.flood = self._flood
            self._ovr_counter = 0

    def _rt_ignored(self, byte: int) -> None:
        """No door switch and no M7 in this build."""

    _REALTIME: dict[int, Callable[[SystemCommands, int], None]] = {
        C.RT_RESET: _rt_reset,
        C.RT_STATUS: _rt_status,
        C.RT_FEED_HOLD: _rt_feed_hold,
        C.RT_CYCLE_START: _rt_cycle_start,
        C.RT_JOG_CANCEL: _rt_jog_cancel,
        **dict.fromkeys(_FEED_OVR, _rt_feed_override),
        **dict.fromkeys(_RAPID_OVR, _rt_rapid_override),
        **dict.fromkeys(_SPINDLE_OVR, _rt_spindle_override),
        C.RT_SPINDLE_OVR_STOP: _rt_spindle_stop,
        C.RT_COOLANT_FLOOD_OVR_TOGGLE: _rt_flood,
        C.RT_SAFETY_DOOR: _rt_ignored,
        C.RT_COOLANT_MIST_OVR_TOGGLE: _rt_ignored,
    }

    def _resume(self) -> None:
        self._hold = False
        self._hold_complete = False
        self._spindle_stop = False
        self._gc.program = ""
        self._state = "Run" if self._planner else "Idle"

    # ------------------------------------------------------------------ `$` commands
    def _system(self, line: str) -> None:
        if line == "$":
            self._emit(C.HELP)
            return self._ok()
        handler = self._ANY_STATE.get(line[1])
        if handler is None:
            if self._state not in ("Idle", "Alarm"):
                raise GrblError(C.E_IDLE_ERROR)
            handler = self._IDLE_ONLY.get(line[1], SystemCommands._sys_store_setting)
        handler(self, line)
        return None

    def _sys_jog(self, line: str) -> None:
        if self._state not in ("Idle", "Jog"):
            raise GrblError(C.E_IDLE_ERROR)
        if len(line) < 3 or line[2] != "=":
            raise GrblError(C.E_INVALID_STATEMENT)
        self._queue_line(self._gcode(line[3:], jog=True))

    def _sys_settings(self, line: str) -> None:
        _two_letters(line)
        if self._state in ("Run", "Hold"):
            raise GrblError(C.E_IDLE_ERROR)
        for key, value in self.settings.items():
            self._emit(f"${key}={self._format_setting(key, value)}")
        self._ok()

    def _sys_parser_state(self, line: str) -> None:
        _two_letters(line)
        self._emit(gc_report(self._gc))
        self._ok()

    def _sys_check_mode(self, line: str) -> None:
        _two_letters(line)
        if self._state == "Check":
            self._emit(C.MSG_DISABLED)
            self._ok()
            # "When toggled off, Grbl will perform an automatic soft-reset"
            self._soft_reset()
            return
        if self._state != "Idle":
            raise GrblError(C.E_IDLE_ERROR)
        self._state = "Check"
        self._emit(C.MSG_ENABLED)
        self._ok()

    def _sys_unlock(self, line: str) -> None:
        _two_letters(line)
        if self._state == "Alarm":
            self._emit(C.MSG_UNLOCKED)
            self._state = "Idle"
        self._ok()

    def _sys_params(self, line: str) -> None:
        _two_letters(line)
        self._report_params()
        self._ok()

    def _sys_home(self, line: str) -> None:
        if not self.settings[22]:
            raise GrblError(C.E_SETTING_DISABLED)
        self._start_homing()

    def _sys_sleep(self, line: str) -> None:
        if line != "$SLP":
            raise GrblError(C.E_INVALID_STATEMENT)
        self._ok()
        self._state = "Sleep"
        self._emit(C.MSG_SLEEPING)

    def _sys_build_info(self, line: str) -> None:
        if line == "$I":
            opts = "V" + ("Z" if self.force_origin else "")
            # the build info (what `$I=` stored) ends with the simulator's time scale,
            # which a sender on a pty can learn no other way (gcode.grbl.time_scale_of)
            info = " ".join(filter(None, (self.build_info, f"grblsim speed={self.speed:g}")))
            self._emit(f"[VER:{C.VERSION}.{C.BUILD_DATE}:{info}]")
            self._emit(f"[OPT:{opts},{C.PLANNER_BLOCKS},{C.RX_BUFFER_SIZE}]")
        elif line.startswith("$I="):
            self.build_info = line[3:]
        else:
            raise GrblError(C.E_INVALID_STATEMENT)
        self._ok()

    def _sys_restore(self, line: str) -> None:
        """`$RST=$` settings, `$RST=#` parameters, `$RST=*` all of EEPROM, then a reset."""
        what = _RESTORE.get(line)
        if what is None:
            raise GrblError(C.E_INVALID_STATEMENT)
        if what in "$*":
            self.settings = dict(C.DEFAULT_SETTINGS)
        if what in "#*":
            self.params = Params()
        if what == "*":
            self.startup_lines = [""] * C.N_STARTUP_LINES
            self.build_info = ""
        self._emit(C.MSG_RESTORING)
        self._ok()
        self._soft_reset()

    def _sys_startup_lines(self, line: str) -> None:
        """`$N` lists the start-up lines, `$Nx=line` checks (and runs) a line, then stores it."""
        if line == "$N":
            for i, text in enumerate(self.startup_lines):
                self._emit(f"$N{i}={text}")
            self._ok()
            return
        idx_text, eq, text = line[2:].partition("=")
        if not eq or not idx_text.isdigit():
            raise GrblError(C.E_INVALID_STATEMENT)
        idx = int(idx_text)
        if idx >= C.N_STARTUP_LINES:
            raise GrblError(C.E_INVALID_STATEMENT)
        actions = self._gcode(text) if text else []
        self.startup_lines[idx] = text
        self._queue_line(actions)

    def _sys_store_setting(self, line: str) -> None:
        """`$x=value`."""
        key_text, eq, value_text = line[1:].partition("=")
        try:
            key = float(key_text)
        except ValueError:
            raise GrblError(C.E_BAD_NUMBER_FORMAT) from None
        if not eq:
            raise GrblError(C.E_INVALID_STATEMENT)
        try:
            value = float(value_text)
        except ValueError:
            raise GrblError(C.E_BAD_NUMBER_FORMAT) from None
        self._store_setting(int(key), value)
        self._queue_line([("store_params",)])  # EEPROM write forces a sync

    _ANY_STATE: dict[str, Callable[[SystemCommands, str], None]] = {
        "J": _sys_jog,
        "$": _sys_settings,
        "G": _sys_parser_state,
        "C": _sys_check_mode,
        "X": _sys_unlock,
    }
    _IDLE_ONLY: dict[str, Callable[[SystemCommands, str], None]] = {
        "#": _sys_params,
        "H": _sys_home,
        "S": _sys_sleep,
        "I": _sys_build_info,
        "R": _sys_restore,
        "N": _sys_startup_lines,
    }

    # ------------------------------------------------------------------ settings
    def _store_setting(self, key: int, value: float) -> None:
        if value < 0:
            raise GrblError(C.E_NEGATIVE_VALUE)
        if key > 255 or key not in self.settings:
            raise GrblError(C.E_INVALID_STATEMENT)
        self._check_step_rate(key, value)
        if key in C.INT_SETTINGS:
            value = int(value)
        if key == 0 and value < 3:
            raise GrblError(C.E_SETTING_STEP_PULSE_MIN)
        if key == 20 and value and not self.settings[22]:
            raise GrblError(C.E_SOFT_LIMIT_ERROR)
        if key == 22 and not value:
            self.settings[20] = 0  # disabling homing disables soft limits
        self.settings[key] = value

    def _check_step_rate(self, key: int, value: float) -> None:
        """Steps/mm ($100-$102) times max rate ($110-$112) must stay within the step rate."""
        if key in (100, 101, 102) and value * self.settings[key + 10] > C.MAX_STEP_RATE_HZ * 60:
            raise GrblError(C.E_MAX_STEP_RATE_EXCEEDED)
        if key in (110, 111, 112) and value * self.settings[key - 10] > C.MAX_STEP_RATE_HZ * 60:
            raise GrblError(C.E_MAX_STEP_RATE_EXCEEDED)

    @staticmethod
    def _format_setting(key: int, value: float) -> str:
        if key in C.INT_SETTINGS:
            return str(int(value))
        if key in C.ZERO_DECIMAL_SETTINGS:
            return fmt(value, 0)
        return fmt(value, 3)

    def _report_params(self) -> None:
        def axes(v: np.ndarray) -> str:
            return ",".join(fmt(x, 3) for x in v)

        for i in range(6):
            self._emit(f"[G{54 + i}:{axes(self.params.coord[i])}]")
        self._emit(f"[G28:{axes(self.params.g28)}]")
        self._emit(f"[G30:{axes(self.params.g30)}]")
        self._emit(f"[G92:{axes(self._gc.g92)}]")
        self._emit(f"[TLO:{fmt(self._gc.tlo, 3)}]")
        self._emit("[PRB:0.000,0.000,0.000:0]")

    # ------------------------------------------------------------------ homing
    def _home_position(self) -> np.ndarray:
        travel = np.array([self.settings[130], self.settings[131], self.settings[132]], float)
        pull = float(self.settings[27])
        mask = int(self.settings[23])
        home = np.zeros(3)
        for i in range(3):
            if self.force_origin:
                home[i] = 0.0
            elif mask & (1 << i):
                home[i] = -travel[i] + pull
            else:
                home[i] = -pull
        return home

    def _start_homing(self) -> None:
        self._home_target = self._home_position()
        seek = max(float(self.settings[25]), 1.0) / 60.0
        travel = np.array([self.settings[130], self.settings[131], self.settings[132]], float)
        # Search then locate: bounded by the travel, at the seek rate, plus the pull-off.
        duration = float(np.max(np.minimum(np.abs(self._home_target - self._pos) + 1.0,
                                           travel))) / seek
        duration += 2 * float(self.settings[27]) / max(float(self.settings[24]) / 60.0, 1e-3)
        self._homing_until = self.sim_time + duration
        self._state = "Home"

    def _finish_homing(self) -> None:
        self._pos = self._home_target.copy()
        self._gc.position = self._pos.copy()
        self._homing_until = None
        self._state = "Idle"
        self._ok()
        self._run_startup_lines()
