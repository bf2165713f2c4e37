"""Progress bars on the console for a job the daemon is running.

The daemon publishes each running job's step and progress in its status answer (the
fraction done, and while cutting the seconds left); these helpers poll it and draw one
bar per step on stderr, redrawn in place on a terminal and one line per step otherwise.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from station.control import DaemonBusy, request

FINAL_STATES = ("done", "failed", "aborted", "paused", "interrupted")
#: how long (s) a follower keeps asking a daemon that does not answer in time: one step
#: may hold it for tens of seconds on a loaded machine (the demo's reshape, at load 6)
BUSY_PATIENCE_S = 120.0


def follow(sock: Path | Callable[[int], dict[str, Any]], job: int, stream=None,
           interval: float = 0.2) -> dict[str, Any]:
    """Poll the daemon and draw a progress bar per step until the job stops; its status.

    ``sock`` is the daemon's control socket, or a function giving a job's status (the
    fleet console's, which reads the shared store).
    """
    def status_of(job: int) -> dict[str, Any]:
        return sock(job) if callable(sock) else request(sock, "status", job=job)["job"]

    bar = ProgressBar(stream or sys.stderr)
    answered = time.monotonic()
    while True:
        try:
            status = status_of(job)
        except DaemonBusy:  # a step holding the daemon on a loaded machine: ask again
            if time.monotonic() - answered > BUSY_PATIENCE_S:
                raise
            continue
        answered = time.monotonic()
        if status["state"] in FINAL_STATES:
            bar.finish(status["state"] + (f": {status['reason']}" if status["reason"] else ""))
            return status
        progress = status.get("progress") or {}
        bar.show(step_label(progress) or status["state"], progress.get("fraction"),
                 progress.get("seconds_left"), _pieces(status, progress))
        time.sleep(interval)


def step_label(progress: dict[str, Any]) -> str:
    """The running step as the operator reads it: ``cutting, bite 2 of 3`` while a
    marker longer than the table is cut bite by bite (each bite its own bar)."""
    step = progress.get("step") or ""
    return f"{step}, bite {progress['bite']}" if step and progress.get("bite") else step


def _pieces(status: dict[str, Any], progress: dict[str, Any]) -> str:
    if progress.get("step") != "cutting":
        return ""
    total = sum(status["pieces"].values())
    return f"{status['pieces']['cut']}/{total} pieces" + garment_counts(status)


def garment_counts(status: dict[str, Any]) -> str:
    """`` (tee-S-1 6/6, tee-M-1 2/6)``: an order's pieces cut per garment ('' otherwise)."""
    per = status.get("garments") or {}
    return (" (" + ", ".join(f"{g} {c['cut']}/{c['total']}" for g, c in per.items()) + ")"
            if per else "")


class ProgressBar:
    """One line per step, redrawn in place on a terminal (a line per step otherwise)."""

    def __init__(self, stream) -> None:
        self.stream = stream
        self.tty = hasattr(stream, "isatty") and stream.isatty()
        self.step: str | None = None
        self.started = time.monotonic()

    def show(self, step: str, fraction: float | None, eta: float | None, extra: str = ""
             ) -> None:
        now = time.monotonic()
        if step != self.step:
            if self.step is not None:
                self._line(self.step, 1.0, None, f"{now - self.started:5.1f} s", final=True)
            self.step, self.started = step, now
            if not self.tty:
                print(f"  {step} ...", file=self.stream, flush=True)
        if self.tty:
            left = f"ETA {eta:4.0f} s" if eta is not None else f"{now - self.started:5.1f} s"
            self._line(step, fraction, left, extra)

    def _line(self, step: str, fraction: float | None, left: str | None, extra: str,
              final: bool = False) -> None:
        if not self.tty:
            return
        width = 30
        if fraction is None:  # no measure of progress: a moving block
            k = int(time.monotonic() * 8) % width
            bar = "." * k + "###" + "." * max(0, width - k - 3)
            bar = bar[:width]
            pct = "    "
        else:
            n = int(round(min(max(fraction, 0.0), 1.0) * width))
            bar = "#" * n + "." * (width - n)
            pct = f"{100 * fraction:3.0f}%"
        text = f"\r  {step:<14} [{bar}] {pct} {left or ''} {extra}"
        self.stream.write(text.ljust(78) + ("\n" if final else ""))
        self.stream.flush()

    def finish(self, message: str) -> None:
        if self.step is not None:
            self._line(self.step, 1.0, None,
                       f"{time.monotonic() - self.started:5.1f} s", final=True)
        print(f"  {message}", file=self.stream, flush=True)
