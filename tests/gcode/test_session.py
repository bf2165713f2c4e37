"""The one GRBL reader: each line classified once, handed to the handler of its kind."""

from __future__ import annotations

import pytest
import serial

from gcode.session import KINDS, PortLost, ResponseReader


class _Wire:
    """A port that holds given bytes (read in pieces, as a serial line delivers them)."""

    def __init__(self, data: bytes, chunk: int = 7):
        self.data, self.chunk = bytearray(data), chunk

    @property
    def in_waiting(self) -> int:
        return min(len(self.data), self.chunk)

    def read(self, n: int) -> bytes:
        out = bytes(self.data[:n])
        del self.data[:n]
        return out


GRBL = (b"\r\nGrbl 1.1h ['$' for help]\r\n[MSG:'$H'|'$X' to unlock]\r\nok\r\nerror:20\r\n"
        b"<Idle|MPos:1.000,2.000,0.000|FS:0,0>\r\nALARM:2\r\n$130=1600.000\r\n"
        b"[G54:0.000,0.000,0.000]\r\n<Idle|MPos:1.0\r\nok\r\n")


def test_every_line_goes_to_the_handler_of_its_kind():
    reader = ResponseReader(_Wire(GRBL))
    seen: list[tuple[str, str]] = []
    for group in set(KINDS.values()):
        reader.register_response(group, lambda r, g=group: seen.append((g, r.raw)))
    assert reader.wait(lambda: len(seen) >= 11, 1.0)
    assert [g for g, _ in seen] == ["empty", "banner", "feedback", "ok", "error", "status",
                                    "alarm", "settings", "parameters", "unknown", "ok"]
    assert seen[9][1] == "<Idle|MPos:1.0"  # a cut-off report is garbled, not a status


def test_a_raising_handler_leaves_the_rest_queued():
    reader = ResponseReader(_Wire(b"ok\r\nerror:9\r\nok\r\n", chunk=64))
    answers: list[str] = []

    def on_error(r):
        raise RuntimeError(r.raw)

    reader.register_response("ok", lambda r: answers.append(r.raw))
    reader.register_response("error", on_error)
    with pytest.raises(RuntimeError, match="error:9"):
        reader.pump()
    assert answers == ["ok"]
    with reader.handlers(error=None):  # a temporary handler set, restored afterwards
        reader.pump()
    assert answers == ["ok", "ok"]
    assert reader._handlers["error"] is on_error


def test_unknown_group_and_lost_port():
    reader = ResponseReader(serial.serial_for_url("loop://", timeout=0.01))
    with pytest.raises(ValueError, match="unknown response group"):
        reader.register_response("okay", print)
    reader.port.close()
    with pytest.raises(PortLost, match="read failed"):
        reader.pump()
