"""pyserial URL handler `grblsim://`: a serial port wired to an emulated GRBL 1.1h controller.

pyserial finds it as `<package>.protocol_grblsim` once `simulators.grbl` is in
`serial.protocol_handler_packages` (importing `simulators.grbl` appends it). Options::

    grblsim://?speed=20&name=cutter&error_at=12:20&alarm_at=30:1&drop_byte_at=500
              &flip_byte_at=77&reset_at=40&disconnect_at=50&power_cut_at=60&force_origin=1
              &baud=115200&dup_byte_at=90&insert_at=95:213f0a&out_drop_at=300
              &out_flip_at=310&out_dup_at=320&out_insert_at=330:6f6b0d0a
              &drop_ok_at=7&dup_ok_at=9

speed: simulated seconds per wall second (default 1); baud: model the serial line at that
rate in both directions (default: none, bytes arrive at once; see `wire.SerialLine`);
name: share one machine between opens
(reopen after a disconnect or power cut); *_at: fault injection (lines and bytes count from 1,
several values separated by commas; out_* count the bytes GRBL sends, *_ok_at its `ok`s;
insert bursts are given in hex); force_origin: homing sets the origin at the home switches
(build option Z); settings: `$N` values stored before power-up, e.g. settings=22:1,20:1.
The port object exposes the machine as `port.emulator`, and declares its time as any port
may (`gcode.session.PortTiming`): `time_scale` (the machine's speed), `machine_clock()`
(its simulated seconds) and `line_baud` (the modelled wire's rate, None for an instant link).
"""

from __future__ import annotations

import logging
import time
import urllib.parse

from serial.serialutil import PortNotOpenError, SerialBase, SerialException, to_bytes

from simulators.grbl.emulator import Faults, GrblEmulator
from simulators.grbl.registry import get_or_create
from simulators.grbl.wire import SerialLine

EXPECTED = (
    '"grblsim://[?speed=S][&name=NAME][&error_at=LINE:CODE][&alarm_at=LINE:CODE]'
    "[&drop_byte_at=N][&flip_byte_at=N][&reset_at=LINE][&disconnect_at=LINE]"
    '[&power_cut_at=LINE][&dup_byte_at=N][&insert_at=N:HEX][&out_drop_at=N]'
    "[&out_flip_at=N][&out_dup_at=N][&out_insert_at=N:HEX][&drop_ok_at=K][&dup_ok_at=K]"
    '[&settings=N:V,...][&force_origin=0|1][&baud=BAUD]'
    '[&logging=debug|info|warning|error]"'
)
LOGGER_LEVELS = {"debug": logging.DEBUG, "info": logging.INFO,
                 "warning": logging.WARNING, "error": logging.ERROR}


def _keyed(option: str, items: list[str], form: str, value) -> dict:
    """``{int(KEY): value(VALUE)}`` of ``KEY:VALUE`` items (a fault table of the URL)."""
    table = {}
    for item in items:
        key, sep, text = item.partition(":")
        if not sep:
            raise ValueError(f"{option} needs {form}, got {item!r}")
        table[int(key)] = value(text)
    return table


def parse_url(url: str) -> tuple[dict, dict, str | None]:
    """Split a grblsim URL into (machine options, faults given, logging level); ValueError."""
    parts = urllib.parse.urlsplit(url)
    if parts.scheme != "grblsim":
        raise ValueError(f"not starting with grblsim:// ({parts.scheme!r})")
    if parts.netloc or parts.path.strip("/"):
        raise ValueError(f"unexpected host or path {parts.netloc + parts.path!r}")
    options: dict = {}
    faults: dict = {}
    level = None
    for option, values in urllib.parse.parse_qs(parts.query, keep_blank_values=True).items():
        items = [v for value in values for v in value.split(",") if v != ""]
        if option == "speed":
            speed = float(values[-1])
            if not speed > 0:
                raise ValueError(f"speed must be > 0, got {values[-1]!r}")
            options["speed"] = speed
        elif option == "baud":
            baud = int(values[-1])
            if not baud > 0:
                raise ValueError(f"baud must be > 0, got {values[-1]!r}")
            options["baud"] = baud
        elif option == "name":
            options["name"] = values[-1]
        elif option == "settings":
            table = {}
            for item in items:
                key, sep, value = item.lstrip("$").partition(":")
                if not sep:
                    raise ValueError(f"settings needs N:VALUE, got {item!r}")
                table[int(key)] = float(value)
            options["settings"] = table
        elif option == "force_origin":
            options["force_origin"] = values[-1] not in ("0", "false", "")
        elif option in ("error_at", "alarm_at"):
            faults[option] = _keyed(option, items, "LINE:CODE", int)
        elif option in ("drop_byte_at", "flip_byte_at", "reset_at", "disconnect_at",
                        "power_cut_at", "dup_byte_at", "out_drop_at", "out_flip_at",
                        "out_dup_at", "drop_ok_at", "dup_ok_at"):
            faults[option] = {int(v) for v in items}
        elif option in ("insert_at", "out_insert_at"):
            faults[option] = _keyed(option, items, "BYTE:HEX", bytes.fromhex)
        elif option == "logging":
            if values[-1] not in LOGGER_LEVELS:
                raise ValueError(f"unknown logging level {values[-1]!r}")
            level = values[-1]
        else:
            raise ValueError(f"unknown option: {option!r}")
    return options, faults, level


class Serial(SerialBase):
    """A serial port to an emulated GRBL controller (pyserial URL handler)."""

    BAUDRATES = (9600, 19200, 38400, 57600, 115200, 230400)

    def __init__(self, *args, **kwargs):
        self.emulator: GrblEmulator | None = None
        self.logger: logging.Logger | None = None
        self._generation = -1
        self._owns_machine = False
        self._cancel = False
        self.wire: SerialLine | None = None  # the modelled wire (`baud=`), else none
        super().__init__(*args, **kwargs)

    # -- the time this port's machine runs on (gcode.session.PortTiming) -----------------
    @property
    def time_scale(self) -> float:
        """Machine seconds per wall second: the emulator's speed."""
        return self.emulator.speed if self.emulator is not None else 1.0

    def machine_clock(self) -> float:
        """The emulator's simulated seconds."""
        return self.emulator.sim_time if self.emulator is not None else 0.0

    @property
    def line_baud(self) -> float | None:
        """The modelled wire's baud rate (``baud=``); None: bytes arrive at once."""
        return 10.0 / self.wire.byte_time if self.wire is not None else None

    # -- pyserial contract --------------------------------------------------------------
    def open(self) -> None:
        if self.is_open:
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        self.from_url(self.port)
        self._reconfigure_port()
        self.is_open = True

    def from_url(self, url: str) -> None:
        try:
            options, faults, level = parse_url(url)
        except ValueError as exc:
            raise SerialException(f"expected a string in the form {EXPECTED}: {exc}") from None
        if level:
            logging.basicConfig()
            self.logger = logging.getLogger("pySerial.grblsim")
            self.logger.setLevel(LOGGER_LEVELS[level])
        name = options.pop("name", None)
        baud = options.pop("baud", None)
        machine, created = get_or_create(name, faults=Faults(**faults), **options)
        if not created:
            for key, value in faults.items():
                setattr(machine.faults, key, value)
            if "speed" in options:
                machine.speed = options["speed"]
            self._generation = machine.connect()
        else:
            self._generation = machine.generation
        self._owns_machine = name is None
        self.emulator = machine
        self._cancel = False
        if baud is not None:
            self.wire = SerialLine(baud, self._to_machine, self._from_machine)

    def _alive(self, machine: GrblEmulator) -> bool:
        return (self.is_open and machine.generation == self._generation
                and machine.connected)

    def _to_machine(self, data: bytes) -> bool:
        """The wire delivers bytes to the controller (False: this connection is gone)."""
        machine = self.emulator
        if machine is None or not self._alive(machine):
            return False
        machine.receive(data)
        return True

    def _from_machine(self, timeout: float) -> bytes:
        machine = self.emulator
        if machine is None or not self._alive(machine):
            time.sleep(timeout)
            return b""
        machine.wait_output(timeout)
        return machine.take_output() if self._alive(machine) else b""

    def close(self) -> None:
        if self.is_open:
            self.is_open = False
            if self.wire is not None:
                self.wire.close()
            machine = self.emulator
            if machine is not None:
                if self._owns_machine:
                    machine.close()
                elif machine.generation == self._generation:
                    machine.disconnect()
                machine.wake_readers()
        super().close()

    def _reconfigure_port(self) -> None:
        if self.logger:
            self.logger.info("_reconfigure_port()")

    def _check(self) -> GrblEmulator:
        if not self.is_open:
            raise PortNotOpenError()
        machine = self.emulator
        if machine is None or machine.generation != self._generation or not machine.connected:
            raise SerialException(f"device disconnected: {self.port}")
        return machine

    @property
    def in_waiting(self) -> int:
        machine = self._check()
        return self.wire.waiting() if self.wire is not None else machine.output_waiting()

    def read(self, size: int = 1) -> bytes:
        machine = self._check()
        deadline = None if self._timeout is None else time.monotonic() + self._timeout
        data = bytearray()
        while len(data) < size:
            data += (self.wire.take(size - len(data)) if self.wire is not None
                     else machine.take_output(size - len(data)))
            if len(data) >= size or self._timeout == 0:
                break
            if self._cancel:
                self._cancel = False
                break
            remaining = None if deadline is None else deadline - time.monotonic()
            if remaining is not None and remaining <= 0:
                break
            wait = 0.05 if remaining is None else min(remaining, 0.05)
            if self.wire is not None:
                self.wire.wait(wait)
            else:
                machine.wait_output(wait)
            if not self.is_open:
                break
            self._check()
        if self.logger:
            self.logger.debug("read %r", bytes(data))
        return bytes(data)

    def cancel_read(self) -> None:
        self._cancel = True
        if self.emulator is not None:
            self.emulator.wake_readers()

    def write(self, data) -> int:
        machine = self._check()
        data = to_bytes(data)
        if self.logger:
            self.logger.debug("write %r", data)
        if self.wire is not None:
            self.wire.send(data)
        else:
            machine.receive(data)
        return len(data)

    def reset_input_buffer(self) -> None:
        machine = self._check()
        if self.wire is not None:
            self.wire.take(1 << 30)
        machine.take_output()

    def reset_output_buffer(self) -> None:
        self._check()

    @property
    def out_waiting(self) -> int:
        self._check()
        return 0

    def _update_break_state(self) -> None:
        pass

    def _update_rts_state(self) -> None:
        pass

    def _update_dtr_state(self) -> None:
        pass

    @property
    def cts(self) -> bool:
        self._check()
        return True

    @property
    def dsr(self) -> bool:
        self._check()
        return True

    @property
    def ri(self) -> bool:
        self._check()
        return False

    @property
    def cd(self) -> bool:
        self._check()
        return True
