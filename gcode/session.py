"""One reader for everything GRBL sends, dispatching each line to the handler of its kind.

Modelled on Klipper's serial layer (``klippy/serialhdl.py``, ``register_response``): the
reader owns the port's input, splits it into lines, classifies each line once
(:func:`gcode.grbl.parse_response`) and hands it to the handler registered for its kind.
An operation (connecting, a command, a status query, the streaming loop) registers the
handlers it needs for as long as it runs and waits until its condition holds; everything
else goes to the standing handlers. A handler may raise to end the wait: lines read but
not yet dispatched stay queued for the next wait, so no answer is ever lost.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from gcode.grbl import Response, parse_response

__all__ = ["KINDS", "PortLost", "ResponseReader"]

#: Handler groups by response kind, as the issue names them.
KINDS: dict[str, str] = {
    "ok": "ok", "error": "error", "alarm": "alarm", "status": "status", "banner": "banner",
    "msg": "feedback", "gc": "feedback", "help": "feedback", "ver": "feedback",
    "opt": "feedback", "echo": "feedback", "feedback": "feedback", "startup_exec": "feedback",
    "setting": "settings", "startup_line": "settings", "param": "parameters",
    "unknown": "unknown", "empty": "empty",
}

Handler = Callable[[Response], None]


class PortLost(Exception):
    """Reading or writing the port failed: the controller is gone (cable, power, USB)."""


class ResponseReader:
    """Reads ``port`` (anything with ``read``, ``in_waiting``) and dispatches by kind."""

    def __init__(self, port) -> None:
        self.port = port
        self._buf = b""
        self._lines: deque[str] = deque()
        self._handlers: dict[str, Handler] = {}
        self.last_rx = time.monotonic()

    def register_response(self, group: str, handler: Handler | None) -> None:
        """Send every response of ``group`` (a value of KINDS) to ``handler`` (None: drop)."""
        if group not in set(KINDS.values()):
            raise ValueError(f"unknown response group {group!r}")
        if handler is None:
            self._handlers.pop(group, None)
        else:
            self._handlers[group] = handler

    @contextmanager
    def handlers(self, **by_group: Handler | None) -> Iterator[None]:
        """Register handlers for the duration of a ``with`` block, then restore the old."""
        old = {g: self._handlers.get(g) for g in by_group}
        for g, h in by_group.items():
            self.register_response(g, h)
        try:
            yield
        finally:
            for g, h in old.items():
                self.register_response(g, h)

    def _read(self) -> None:
        try:
            n = self.port.in_waiting
            data = self.port.read(n if n else 1)
        except Exception as exc:  # serial.SerialException, OSError, PortNotOpenError
            raise PortLost(f"read failed: {exc}") from exc
        if data:
            self.last_rx = time.monotonic()
            self._buf += data
            *lines, self._buf = self._buf.split(b"\n")
            self._lines.extend(ln.rstrip(b"\r").decode("ascii", errors="replace")
                               for ln in lines)

    def pump(self) -> None:
        """Read once (waiting at most the port's timeout) and dispatch every whole line."""
        if not self._lines:
            self._read()
        while self._lines:
            r = parse_response(self._lines.popleft())
            handler = self._handlers.get(KINDS.get(r.kind, "unknown"))
            if handler is not None:
                handler(r)

    def wait(self, done: Callable[[], bool], timeout: float,
             between: Callable[[], None] | None = None) -> bool:
        """Pump until ``done()`` (True) or ``timeout`` seconds (False); ``between`` runs
        before each read (polls, sends)."""
        end = time.monotonic() + timeout
        while not done():
            if time.monotonic() >= end:
                return False
            if between is not None:
                between()
            self.pump()
        return True
