"""The daemon's stream relay (station.cutting.stream_with_control) against the emulator: what
the streamer refuses before anything moves reaches the job, not a lost worker thread."""

from __future__ import annotations

import pytest
import serial

import simulators.grbl  # noqa: F401  (registers grblsim://)
from gcode.layout import layout_from_dict
from gcode.machine import default_machine
from gcode.program import build_program
from gcode.stream import Streamer, StreamError
from gcode.toolpath import build_toolpaths
from station.cutting import stream_with_control
from station.daemon import JobControl


def _square_program():
    machine = default_machine()
    data = {"version": 1, "units": "mm",
            "pieces": [{"id": "a", "outline": [[20, 20], [30, 20], [30, 30], [20, 30]]}]}
    return build_program(build_toolpaths(layout_from_dict(data, "relay"), machine), machine)


MACHINE = "130:1600,131:1000,110:12000,111:12000,120:1500,121:1500"  # the built-in profile's


@pytest.mark.parametrize("laser_mode,cut", [("32:0", False), ("32:1", True)])
def test_the_relay_raises_a_refusal_and_returns_a_cut(laser_mode, cut):
    port = serial.serial_for_url(f"grblsim://?speed=50&settings={laser_mode},{MACHINE}",
                                 timeout=0.02)
    streamer = Streamer(port)
    streamer.connect(quiet=0.05)
    program = _square_program()
    if cut:
        result = stream_with_control(streamer, program, JobControl(job_id=1))
        assert result.completed and result.pieces_cut == 1
    else:
        with pytest.raises(StreamError, match=r"laser mode.*\$32=0"):
            stream_with_control(streamer, program, JobControl(job_id=1))
        assert port.emulator.trace == []  # nothing moved
    port.close()
