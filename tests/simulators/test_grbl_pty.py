"""`station sim-grbl --pty` serves the emulator to other processes using plain pyserial.

commands.md, Getting Started: "connect to Grbl using the serial terminal of your choice ...
Once connected you should get the Grbl-prompt, which looks like this: Grbl 1.1e ['$' for help]"
(1.1h here). The server runs in its own process, as an operator would start it.

pyserial flushes the input queue when it opens a tty, and the emulated board has no DTR
auto-reset, so a banner written before the open may be gone: like real senders, the client
sends a soft reset (0x18) and reads the banner that follows.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import serial

REPO = Path(__file__).resolve().parents[2]


def start_server(*args: str) -> tuple[subprocess.Popen, str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "station.cli", "sim-grbl", "--pty", *args],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    path = proc.stdout.readline().strip()
    if not path:
        proc.kill()
        raise AssertionError(f"no device path printed: {proc.stderr.read()}")
    return proc, path


def connect(path: Path, timeout: float = 2.0) -> serial.Serial:
    """Open the device, drop whatever the open raced with, reset and read the banner."""
    port = serial.Serial(str(path), 115200, timeout=timeout)
    time.sleep(0.1)
    port.reset_input_buffer()
    port.write(b"\x18")
    assert read_line(port) == ""
    assert read_line(port) == "Grbl 1.1h ['$' for help]"
    return port


def read_line(port: serial.Serial) -> str:
    raw = port.readline()
    assert raw.endswith(b"\r\n"), f"no complete line before the timeout: {raw!r}"
    return raw[:-2].decode()


def test_pty_works_with_plain_pyserial_from_another_process(tmp_path):
    """A sender in another process opens the device path like a real controller: the banner
    waits for it, `ok` answers lines, `?` reports status, and SIGTERM stops the server."""
    link = tmp_path / "ttyGRBL"
    proc, path = start_server("--speed", "100", "--link", str(link), "--setting", "10=3")
    try:
        assert Path(path).exists() and os.path.realpath(link) == path
        port = connect(link)
        try:
            port.write(b"$I\n")
            assert [read_line(port) for _ in range(3)][1:] == ["[OPT:V,15,128]", "ok"]
            port.write(b"G1 X-5 Y-2 F1000\nG4 P0\n")
            assert [read_line(port), read_line(port)] == ["ok", "ok"]
            port.write(b"?")
            report = read_line(port)
            assert report.startswith("<Idle|MPos:-5.000,-2.000,0.000|Bf:15,128|FS:0,0")
        finally:
            port.close()
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(5) == 0
        assert not link.exists()  # the symlink goes with the server
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_pty_disconnect_closes_the_device_and_reopens_behind_the_link(tmp_path):
    """`--disconnect-at LINE`: the device vanishes under the client (pyserial raises, as for an
    unplugged USB controller); the server opens a new pty behind the same symlink and prints its
    path, and the machine is found where it was."""
    link = tmp_path / "ttyGRBL"
    proc, _ = start_server("--speed", "100", "--link", str(link), "--disconnect-at", "2")
    try:
        port = connect(link, timeout=1)
        try:
            port.write(b"G1 X-3 F1000\n")
            assert read_line(port) == "ok"
            port.write(b"G1 X-6\n")
            with pytest.raises(serial.SerialException):
                for _ in range(250):
                    port.read(1)
                    port.write(b"?")
                    time.sleep(0.02)
        finally:
            port.close()
        new_path = proc.stdout.readline().strip()
        assert new_path and os.path.realpath(link) == new_path
        port = serial.Serial(str(link), 115200, timeout=2)
        try:
            port.write(b"G4 P0\n")
            assert read_line(port) == "ok"
            port.write(b"?")
            assert read_line(port).startswith("<Idle|MPos:-6.000,0.000,0.000")
        finally:
            port.close()
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            assert proc.wait(5) == 0
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()


def test_bad_option_is_one_line_error(capsys):
    """Bad input gets a clear, one-line error naming the fault (exit status 2)."""
    from station.cli import main

    assert main(["sim-grbl", "--pty", "--setting", "999=1"]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err == "station sim-grbl: error: --setting: $999 is not a GRBL 1.1 setting\n"
