"""Serve an emulated GRBL controller on a pseudo-terminal, so any sender can open it.

The slave side is put in raw mode with echo off (as Klipper's util.create_pty does) and kept open
by the server, so output written before a client connects (the banner) waits in the tty queue
like bytes on a real serial line. An optional symlink gives the device a stable path; after an
injected disconnect the pty is closed (clients see the port vanish) and a new one is opened
behind the same symlink.
"""

from __future__ import annotations

import contextlib
import os
import select
import termios
import threading
import tty
from collections.abc import Callable

from simulators.grbl.emulator import GrblEmulator

MAX_PENDING_OUTPUT = 1 << 16  # bytes held while the tty queue is full; beyond that, dropped


class PtyBridge:
    """Copies bytes between a pty master and an emulator until stopped."""

    def __init__(self, emulator: GrblEmulator, link: str | None = None):
        self.emulator = emulator
        self.link = link
        self.master = self.slave = -1
        self.path = ""
        self._pending = bytearray()
        self._open()

    def _open(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)
        attrs = termios.tcgetattr(slave)
        attrs[3] &= ~(termios.ECHO | termios.ECHONL | termios.ICANON)
        termios.tcsetattr(slave, termios.TCSANOW, attrs)
        os.set_blocking(master, False)
        self.master, self.slave = master, slave
        self.path = os.ttyname(slave)
        if self.link:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.link)
            os.symlink(self.path, self.link)

    def _close_fds(self) -> None:
        for fd in (self.master, self.slave):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self.master = self.slave = -1

    def close(self) -> None:
        self._close_fds()
        if self.link:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.link)

    def serve(self, stop: threading.Event, on_reopen: Callable[[str], None] | None = None,
              poll: float = 0.002) -> None:
        """Run until `stop` is set; `on_reopen(path)` is called after a disconnect re-opens."""
        generation = self.emulator.generation
        while not stop.is_set():
            if not self.emulator.connected or self.emulator.generation != generation:
                self._close_fds()  # the port disappears
                if stop.wait(0.5):
                    break
                generation = self.emulator.connect()
                self._pending.clear()
                self._open()
                if on_reopen:
                    on_reopen(self.path)
                continue
            readable, _, _ = select.select([self.master], [], [], poll)
            if readable:
                try:
                    data = os.read(self.master, 4096)
                except (BlockingIOError, InterruptedError):
                    data = b""
                except OSError:
                    data = b""
                if data:
                    self.emulator.receive(data)
            self._pending += self.emulator.take_output()
            if self._pending:
                try:
                    n = os.write(self.master, self._pending)
                    del self._pending[:n]
                except (BlockingIOError, InterruptedError):
                    pass
                except OSError:
                    self._pending.clear()
                if len(self._pending) > MAX_PENDING_OUTPUT:
                    del self._pending[:-MAX_PENDING_OUTPUT]
