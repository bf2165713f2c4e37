"""The modelled serial line (`grblsim://?baud=N`): bytes take their transmission time in
each direction and queue behind the bytes before them, as on a real 8N1 UART."""

from __future__ import annotations

import time

import serial

import simulators.grbl  # noqa: F401  (registers grblsim://)

BAUD = 9600  # slow, so that the line's time dwarfs the host's scheduling noise
BYTE = 10.0 / BAUD


def open_line(baud: int | None = BAUD):
    extra = f"&baud={baud}" if baud else ""
    port = serial.serial_for_url(f"grblsim://?speed=1{extra}", timeout=0.02)
    deadline = time.monotonic() + 2.0
    banner = b""
    while b"Grbl" not in banner and time.monotonic() < deadline:
        banner += port.read(64)
    assert b"Grbl 1.1h" in banner
    return port


def read_until(port, count: bytes, n: int, timeout: float = 3.0) -> tuple[bytes, float]:
    """Read until ``count`` has appeared ``n`` times; (bytes, seconds it took)."""
    t = time.monotonic()
    data = b""
    while data.count(count) < n and time.monotonic() - t < timeout:
        data += port.read(64)
    return data, time.monotonic() - t


def test_answers_come_no_faster_than_the_line_carries_the_lines_and_the_oks():
    port = open_line()
    try:
        lines = b"G21\n" * 10  # 40 bytes: 41.7 ms at 9600 baud, then the last `ok\r\n`
        t = time.monotonic()
        port.write(lines)
        data, _ = read_until(port, b"ok\r\n", 10)
        took = time.monotonic() - t
        assert data.count(b"ok\r\n") == 10
        assert took >= (len(lines) + 4) * BYTE * 0.98, took
        assert port.wire.bytes_to_controller == len(lines)
        assert port.wire.bytes_to_host >= 40  # the ten `ok\r\n`
    finally:
        port.close()


def test_a_status_query_waits_behind_the_line_before_it_and_its_report_takes_its_time():
    port = open_line()
    try:
        line = b"G1 X0 Y0 F1000 (a comment that makes the line long: 64 b)\n"
        t = time.monotonic()
        port.write(line)
        port.write(b"?")
        data, _ = read_until(port, b">", 1)
        took = time.monotonic() - t
        report = data[data.index(b"<"):data.index(b">") + 3]
        # the `?` is picked off only once the whole line is through, then the report
        # (and the line's `ok`, which GRBL writes first) take their own time back
        assert took >= (len(line) + 1 + len(report) + 4) * BYTE * 0.98, (took, data)
    finally:
        port.close()


def test_without_a_baud_rate_the_link_is_instant():
    port = open_line(None)
    try:
        assert getattr(port, "wire", None) is None
        port.write(b"G21\n" * 10)
        assert port.in_waiting == 40  # the ten `ok\r\n` are there as the write returns
        data, _ = read_until(port, b"ok\r\n", 10)
        assert data.count(b"ok\r\n") == 10
    finally:
        port.close()
