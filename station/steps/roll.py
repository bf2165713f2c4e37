"""The station's roll between bites (issue 35): the camera's view of the table window,
and the conveyor of the machine profile (`gcode.machine.ConveyorParams`) when it has one.

`station_roll` is what production cuts with; a simulation entry point hands the
pipeline its own roll (`station.simstation`), which must answer the same two questions:
how to advance the roll by N mm, and what the window looks like now.
"""

from __future__ import annotations

import numpy as np

from gcode.machine import Machine
from gcode.recovery import wait_at_rest
from gcode.session import ResponseReader
from gcode.stream import Streamer
from station.config import Config
from station.steps.capture import CameraOpener, photograph
from station.steps.cut import PortOpener, port_name
from station.steps.cutbites import Roll

#: seconds a conveyor's move may take beyond the time its length asks for
CONVEYOR_SLACK_S = 30.0


class CameraRoll:
    """The table window as the configured camera sees it, rectified to fabric mm, and the
    profile's conveyor (``feed`` None when the profile has none: the operator's hands)."""

    def __init__(self, config: Config, machine: Machine, open_camera: CameraOpener,
                 open_port: PortOpener) -> None:
        self.config, self.machine = config, machine
        self.open_camera, self.open_port = open_camera, open_port
        self.mm_per_px = 1.0
        self.feed = self._conveyor if machine.conveyor.kind else None

    def photograph(self) -> np.ndarray:
        _frame, rectified, mm_per_px, _truth = photograph(self.config, self.open_camera)
        self.mm_per_px = float(mm_per_px)
        return rectified

    def settle(self) -> None:
        """Wait until the controller has run what a daemon that died sent it: a conveyor's
        move runs on from the controller's buffers, and a photograph now would blur. GRBL
        reports Idle all through a dwell (a relay conveyor's), so first ``$G``, answered
        only once every line before it has run, then the motion's end
        (`gcode.recovery.wait_at_rest`). A controller that does not answer is left to
        the cut's own connection to report."""
        if self.feed is None:
            return
        x0, _, x1, _ = self.machine.work_area
        longest = (x1 - x0) / conveyor_mm_per_s(self.machine) + CONVEYOR_SLACK_S
        parsed: list[bool] = []
        with self.open_port(self.config) as port:
            reader = ResponseReader(port)
            reader.register_response("feedback", lambda r: parsed.append(r.kind == "gc"))
            port.write(b"$G\n")
            if reader.wait(lambda: any(parsed), longest):
                wait_at_rest(port)

    def _conveyor(self, mm: float) -> None:
        """Advance the roll by ``mm`` with the profile's conveyor, and wait until it has
        stopped (a ``G4 P0`` after it answers only once the planner is empty)."""
        conveyor, m = self.machine.conveyor, self.machine
        seconds = mm / conveyor_mm_per_s(m)
        with self.open_port(self.config) as port:
            streamer = Streamer(port, on_piece=None, name=port_name(self.config),
                                rx_buffer=m.rx_buffer, acceleration=m.acceleration,
                                rapid_feed=m.rapid_feed)
            streamer.connect(quiet=0.2)
            for line in [*conveyor.lines(mm), "G4 P0"]:
                answer, _ = streamer.command(line, timeout=abs(seconds) + CONVEYOR_SLACK_S)
                if answer.kind != "ok":
                    raise RuntimeError(f"the controller refused the conveyor's {line!r}: "
                                       f"{answer.raw}")


def conveyor_mm_per_s(machine: Machine) -> float:
    """How fast the profile's conveyor moves the roll (0: it has none)."""
    conveyor = machine.conveyor
    if not conveyor.kind:
        return 0.0
    return conveyor.feed / 60.0 if conveyor.kind == "axis" else conveyor.mm_per_s


def station_roll(config: Config, machine: Machine, open_camera: CameraOpener,
                 open_port: PortOpener) -> Roll:
    """The production roll: `CameraRoll`."""
    return CameraRoll(config, machine, open_camera, open_port)
