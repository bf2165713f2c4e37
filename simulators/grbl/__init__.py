"""GRBL 1.1h emulator: a machine in simulated time behind a pyserial URL or a pseudo-terminal.

Importing this package registers the `grblsim://` URL scheme with pyserial::

    import serial, simulators.grbl
    port = serial.serial_for_url("grblsim://?speed=20", timeout=1)
    port.emulator.trace          # executed motion segments

See `protocol_grblsim.Serial` for the URL options (speed, name, fault injection).
"""

from __future__ import annotations

import serial

from simulators.grbl.emulator import GrblEmulator
from simulators.grbl.faults import Faults
from simulators.grbl.motion import Segment
from simulators.grbl.parser_state import GrblError
from simulators.grbl.registry import forget, get_or_create, lookup

__all__ = ["Faults", "GrblEmulator", "GrblError", "Segment", "forget", "get_or_create", "lookup"]

if __name__ not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append(__name__)
