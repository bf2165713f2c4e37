"""Watchdogs on what the machine does while it cuts, judged in machine time.

GRBL has no checksum: one flipped bit on the wire turns ``G1X173.9Y67.1`` into the valid
``F1X173.9Y67.1`` (feed 1 mm/min with the beam on) and ``Y829`` into ``Y929``. What was
sent proves nothing, so every status report is held against the program:

* the head stays within ``deviation_mm`` of the program's path (any motion);
* while the beam is on, the reported laser value (``FS:`` second field) is one the program
  asks for (times the spindle override);
* while the beam is on, the reported feed reaches the programmed cutting feed within the
  time the profile's acceleration ($120/$121) needs, and never exceeds it.

Polls are scheduled in machine time: ``watch_mm`` of travel at the fastest programmed
cutting feed, divided by ``time_scale`` (simulated seconds per wall second: 1 on a real
GRBL, the emulator's ``speed`` on ``grblsim://``). A deviation is therefore seen within
``deviation_mm + watch_mm`` of travel at any emulator speed, as long as the host keeps up
with its own schedule.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np
from scipy.spatial import cKDTree

from gcode.grbl import Status

__all__ = ["Breach", "StopReason", "Watchdog", "poll_interval"]


class StopReason(str, Enum):
    """Why a stream ended (a ``str`` so that results compare and serialise as text)."""

    DONE = "done"
    CHECKED = "checked"
    ERROR = "error"
    ALARM = "alarm"
    RESET = "reset"
    GARBLED = "garbled"
    UNMATCHED = "unmatched"
    OFF_PATH = "off_path"
    FEED = "feed"
    POWER = "power"
    TIMEOUT = "timeout"
    DISCONNECT = "disconnect"
    STOPPED = "stopped"
    INTERRUPTED = "interrupted"

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True)
class Breach:
    """A watchdog's finding: why to stop, in one sentence, and the program line (0-based,
    or None) nearest to where the head was."""

    reason: StopReason
    detail: str
    line: int | None


def poll_interval(fastest_feed: float, time_scale: float, *, watch_mm: float = 0.5,
                  shortest: float = 2e-4, longest: float = 0.2) -> float:
    """Wall seconds between status polls so that the head moves at most ``watch_mm``
    between two reports at ``fastest_feed`` (mm/min), on a machine whose time runs
    ``time_scale`` times the wall clock."""
    if fastest_feed <= 0 or not math.isfinite(fastest_feed):
        return longest
    wall = watch_mm / (fastest_feed / 60.0 * max(time_scale, 1e-9))
    return float(min(max(wall, shortest), longest))


class Watchdog:
    """Judges each status report against the program; ``check`` returns a Breach or None.

    ``path`` is the program's motion sampled at most ``step`` mm apart, ``path_line`` the
    program line of each sample; ``feeds`` and ``powers`` are what beam-on moves ask for
    (empty for a knife: then only the path is watched).
    """

    def __init__(self, path: np.ndarray, path_line: np.ndarray | None,
                 feeds: tuple[float, ...], powers: tuple[float, ...], acceleration: float, *,
                 time_scale: float = 1.0, deviation_mm: float = 0.5, watch_mm: float = 0.5,
                 step: float = 1.0):
        self.path = np.asarray(path, float).reshape(-1, 2)
        self.path_line = (np.asarray(path_line, int) if path_line is not None
                          else np.full(len(self.path), -1))
        self.feeds = tuple(feeds)
        self.powers = np.asarray(powers, float)
        self.time_scale = float(time_scale)
        self.deviation = float(deviation_mm)
        self.step = float(step)
        self.interval = poll_interval(max(self.feeds, default=0.0), self.time_scale,
                                      watch_mm=watch_mm)
        slow = min(self.feeds, default=0.0) / 60.0
        # a corner's braking and re-acceleration, plus two polls of latency, in machine time
        self.feed_allowance = 3.0 * slow / max(acceleration, 1e-9) + 0.1 \
            + 2.0 * self.interval * self.time_scale
        self._tree = cKDTree(self.path) if len(self.path) else None
        self._slow_since: float | None = None
        self._overrides = (100, 100, 100)
        self.last_line: int | None = None
        self.reports = 0

    def start_from(self, here: np.ndarray | None) -> None:
        """The first rapid starts wherever the head is: add that leg to the path."""
        if here is None or not len(self.path):
            return
        k = max(1, int(math.ceil(float(np.hypot(*(self.path[0] - here))) / self.step)))
        leg = here + (self.path[0] - here) * np.linspace(0.0, 1.0, k + 1)[:, None]
        self.path = np.vstack([leg, self.path])
        first = int(self.path_line[0]) if len(self.path_line) else -1
        self.path_line = np.concatenate([np.full(len(leg), first), self.path_line])
        self._tree = cKDTree(self.path)

    def distance(self, xy: np.ndarray) -> tuple[float, int]:
        """Exact distance from ``xy`` to the sampled path's polyline, and the nearest sample."""
        if self._tree is None:
            return math.inf, -1
        near = self._tree.query_ball_point(xy, self.deviation + self.step)
        if not near:
            d, k = self._tree.query(xy)
            return float(d), int(k)
        idx = np.unique(np.clip(np.r_[np.asarray(near) - 1, near], 0, len(self.path) - 2))
        a, b = self.path[idx], self.path[idx + 1]
        ab = b - a
        t = np.clip(np.einsum("ij,ij->i", xy - a, ab)
                    / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0.0, 1.0)
        d = np.hypot(*(a + t[:, None] * ab - xy).T)
        j = int(np.argmin(d))
        return float(d[j]), int(idx[j] + (t[j] > 0.5))

    def check(self, st: Status, xy: np.ndarray | None, wall: float) -> Breach | None:
        """Judge one report received at wall time ``wall`` (seconds, monotonic)."""
        self.reports += 1
        if st.overrides is not None:
            self._overrides = st.overrides
        moving = st.state in ("Run", "Hold", "Jog")
        if xy is not None and moving:
            d, k = self.distance(xy)
            if k >= 0 and d <= self.deviation:
                self.last_line = int(self.path_line[k]) if self.path_line[k] >= 0 else None
            if d > self.deviation:
                return Breach(StopReason.OFF_PATH, f"head at X{xy[0]:.3f} Y{xy[1]:.3f} is "
                              f"{d:.2f} mm off the program's path (corrupted line?)",
                              self.last_line)
        beam_on = st.state == "Run" and (st.speed or 0.0) > 0 and len(self.powers) > 0
        if not beam_on:
            self._slow_since = None
            return None
        feed_ovr, _, spindle_ovr = (v / 100.0 for v in self._overrides)
        power = float(st.speed or 0.0)
        if np.min(np.abs(self.powers * spindle_ovr - power)) > 0.5:
            allowed = ", ".join(f"S{p:g}" for p in self.powers)
            return Breach(StopReason.POWER, f"laser at S{power:g} while the program asks for "
                          f"{allowed} (corrupted S word?)", self.last_line)
        feed = float(st.feed or 0.0)
        low, high = min(self.feeds) * feed_ovr, max(self.feeds) * feed_ovr
        if feed > high * 1.02 + 1.0:
            return Breach(StopReason.FEED, f"beam on at F{feed:g}, above the program's "
                          f"cutting feed F{high:g} (corrupted line?)", self.last_line)
        now = wall * self.time_scale
        if feed >= 0.9 * low:
            self._slow_since = None
        elif self._slow_since is None:
            self._slow_since = now
        elif now - self._slow_since > self.feed_allowance:
            return Breach(StopReason.FEED, f"beam on at F{feed:g} for "
                          f"{now - self._slow_since:.2f} s of machine time: the programmed "
                          f"F{low:g} is reached within {self.feed_allowance:.2f} s "
                          "(corrupted F word?)", self.last_line)
        return None
