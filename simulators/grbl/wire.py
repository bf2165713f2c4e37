"""The serial line between a host and the emulated controller, at a real baud rate.

Without it the emulator takes every write at once and its answers are readable at once:
a sender's throughput, and the cost of its status polls, cannot be measured against the
line. With it (``grblsim://?baud=115200``) each direction is an 8N1 UART: a byte takes 10
bit times, bytes queue behind the ones written before them (a ``?`` written after a line
reaches GRBL only once that line is through), and the controller's answers and status
reports reach the host only after their own transmission time. Wall time: the wire's
speed is physical, whatever the machine's simulated ``speed``.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable

__all__ = ["SerialLine"]


class SerialLine:
    """Both directions of one connection. ``deliver(bytes)`` hands bytes to the controller
    (False once the connection is gone); ``collect(timeout)`` takes what the controller
    has written (b"" if nothing within ``timeout``)."""

    def __init__(self, baud: int, deliver: Callable[[bytes], bool],
                 collect: Callable[[float], bytes]):
        if not baud > 0:
            raise ValueError(f"baud must be > 0, got {baud!r}")
        self.byte_time = 10.0 / float(baud)
        self._deliver_to, self._collect_from = deliver, collect
        self._cond = threading.Condition()
        self._to_controller: deque[tuple[float, bytes]] = deque()
        self._to_host: deque[tuple[float, bytes]] = deque()
        self._arrived = bytearray()
        self._tx_free_at = self._rx_free_at = 0.0
        self.bytes_to_controller = 0  # counters: the line's load in each direction
        self.bytes_to_host = 0
        self._closed = False
        for target, name in ((self._deliver, "tx"), (self._collect, "rx")):
            threading.Thread(target=target, daemon=True, name=f"grblsim-wire-{name}").start()

    # ------------------------------------------------------------ host side
    def send(self, data: bytes) -> None:
        """The host writes: the bytes are on the wire until their last bit is through."""
        with self._cond:
            start = max(time.monotonic(), self._tx_free_at)
            self._tx_free_at = start + len(data) * self.byte_time
            self._to_controller.append((self._tx_free_at, bytes(data)))
            self.bytes_to_controller += len(data)
            self._cond.notify_all()

    def waiting(self) -> int:
        """Bytes that have reached the host and are not read yet."""
        with self._cond:
            self._land()
            return len(self._arrived)

    def take(self, size: int) -> bytes:
        with self._cond:
            self._land()
            data = bytes(self._arrived[:size])
            del self._arrived[:size]
            return data

    def wait(self, timeout: float) -> None:
        """Sleep until more bytes reach the host (or ``timeout`` seconds)."""
        with self._cond:
            self._land()
            if self._arrived or self._closed:
                return
            if self._to_host:
                timeout = min(timeout, max(self._to_host[0][0] - time.monotonic(), 0.0))
            self._cond.wait(timeout)
            self._land()

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    # ------------------------------------------------------------ the two directions
    def _land(self) -> None:
        now = time.monotonic()
        while self._to_host and self._to_host[0][0] <= now:
            self._arrived += self._to_host.popleft()[1]

    def _deliver(self) -> None:
        while True:
            with self._cond:
                while not self._to_controller and not self._closed:
                    self._cond.wait()
                if self._closed:
                    return
                at, data = self._to_controller[0]
            wait = at - time.monotonic()
            if wait > 0:
                time.sleep(wait)
            with self._cond:
                self._to_controller.popleft()
            if not self._deliver_to(data):
                return  # the connection is gone: like a cut cable, the rest is lost

    def _collect(self) -> None:
        while not self._closed:
            data = self._collect_from(0.05)
            if not data:
                continue
            with self._cond:
                for line in data.splitlines(keepends=True):  # an `ok` lands before a report
                    start = max(time.monotonic(), self._rx_free_at)
                    self._rx_free_at = start + len(line) * self.byte_time
                    self._to_host.append((self._rx_free_at, line))
                self.bytes_to_host += len(data)
                self._cond.notify_all()
