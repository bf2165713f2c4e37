"""Planner blocks and their motion in simulated time (feed, acceleration, junction speeds).

The planner follows GRBL's model closely enough that a job takes a realistic time: each block has
a nominal speed (feed or rapid, limited by `$110`-`$112` along its direction and scaled by the
overrides), an acceleration limited by `$120`-`$122` along its direction, and a maximum entry
speed from the junction-deviation rule (`$11`). Exit speeds come from a backward pass over the
queued blocks (the last one must stop); the running block is integrated piecewise analytically
(accelerate / cruise / brake), so any speed-up factor gives the same path and timing.

The speed of the step segment GRBL's stepper has *prepared* ahead of the one executing is
modelled here from that integration (`speed_ahead`): it is what `FS:` reports, and what M4
scales the laser with (`simulators.grbl.laser`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

_EPS = 1e-9


class Segment(NamedTuple):
    """One executed motion (mm, mm/min); `power` is the spindle/laser power actually applied."""

    x0: float
    y0: float
    x1: float
    y1: float
    feed: float
    power: float
    rapid: bool
    z0: float = 0.0
    z1: float = 0.0
    jog: bool = False
    complete: bool = True


@dataclass
class Block:
    start: np.ndarray
    end: np.ndarray
    unit: np.ndarray
    length: float
    feed: float | None  # mm/min, None = rapid
    max_rate: float  # mm/min along the direction
    accel: float  # mm/s^2 along the direction
    junction_v2: float  # (mm/s)^2, maximum entry speed squared
    jog: bool = False
    spindle: str = "M5"
    speed: float = 0.0
    line_number: int = 0
    done: float = 0.0
    elapsed: float = 0.0  # simulated seconds spent moving along it
    traced_to: np.ndarray | None = None  # end of its part already in the trace
    # its motion since it was last traced: (elapsed, done, duration, v0, acc, v1) per step
    chunks: list[tuple[float, ...]] = field(default_factory=list)

    @property
    def remaining(self) -> float:
        return max(self.length - self.done, 0.0)

    def nominal(self, feed_ovr: float, rapid_ovr: float) -> float:
        """Nominal speed in mm/s under the current overrides (jogs ignore feed overrides)."""
        if self.feed is None:
            rate = self.max_rate * rapid_ovr / 100.0
        elif self.jog:
            rate = min(self.feed, self.max_rate)
        else:
            rate = min(self.feed * feed_ovr / 100.0, self.max_rate)
        return rate / 60.0


def make_block(
    start: np.ndarray,
    end: np.ndarray,
    feed: float | None,
    settings: dict[int, float],
    previous: Block | None,
    **extra,
) -> Block | None:
    """Build a block from start to end (None when it has zero length, as GRBL drops it)."""
    delta = np.asarray(end, float) - np.asarray(start, float)
    length = float(np.linalg.norm(delta))
    if length < 1e-6:
        return None
    unit = delta / length
    comp = np.abs(unit)
    active = comp > 1e-12
    rates = np.array([settings[110], settings[111], settings[112]], float)
    accels = np.array([settings[120], settings[121], settings[122]], float)
    max_rate = float(np.min(rates[active] / comp[active]))
    accel = float(np.min(accels[active] / comp[active]))
    junction_v2 = 0.0
    if previous is not None:
        cos_theta = -float(np.dot(previous.unit, unit))
        if cos_theta < -0.999999:  # straight on
            junction_v2 = math.inf
        elif cos_theta < 0.999999:
            sin_half = math.sqrt(0.5 * (1.0 - cos_theta))
            a_j = min(accel, previous.accel)
            junction_v2 = a_j * float(settings[11]) * sin_half / (1.0 - sin_half)
    return Block(np.asarray(start, float).copy(), np.asarray(end, float).copy(), unit, length,
                 feed, max_rate, accel, junction_v2, **extra)


def exit_speed(blocks: list[Block], feed_ovr: float, rapid_ovr: float) -> float:
    """Planned exit speed (mm/s) of blocks[0]: a backward pass, the last block stops."""
    entry_next = 0.0
    for k in range(len(blocks) - 1, 0, -1):
        b, prev = blocks[k], blocks[k - 1]
        limit = min(math.sqrt(b.junction_v2), b.nominal(feed_ovr, rapid_ovr),
                    prev.nominal(feed_ovr, rapid_ovr))
        entry_next = min(limit, math.sqrt(entry_next**2 + 2.0 * b.accel * b.remaining))
    return entry_next


def phase(v: float, d: float, vn: float, ve: float, a: float, hold: bool) -> tuple[float, float]:
    """Current motion phase of a block as (acceleration mm/s^2, duration s).

    v: current speed, d: distance left, vn: nominal speed, ve: planned exit speed,
    a: acceleration limit. A feed hold brakes at `a` regardless of the plan.
    """
    if hold:
        if v <= _EPS:
            return 0.0, 0.0
        if v * v > 2.0 * a * d:  # reaches the end of the block while braking
            return -a, (v - math.sqrt(max(v * v - 2.0 * a * d, 0.0))) / a
        return -a, v / a
    ve = min(ve, vn)
    d_brake = max(v * v - ve * ve, 0.0) / (2.0 * a)
    if d <= d_brake * (1.0 + 1e-9) + _EPS:
        if v <= ve + _EPS:
            return 0.0, d / v if v > _EPS else 0.0
        return -(v * v - ve * ve) / (2.0 * d), 2.0 * d / (v + ve)
    if v < vn - _EPS:
        v_peak = math.sqrt((2.0 * a * d + v * v + ve * ve) / 2.0)
        v_top = min(vn, v_peak)
        if v_top - v <= _EPS:  # at the peak: brake from here to the end
            return -(v * v - ve * ve) / (2.0 * d), 2.0 * d / (v + ve)
        return a, (v_top - v) / a
    if v > vn + _EPS:  # an override lowered the nominal speed
        return -a, min((v - vn) / a, 2.0 * (d - d_brake) / (v + vn))
    d_cruise = d - max(vn * vn - ve * ve, 0.0) / (2.0 * a)
    return 0.0, max(d_cruise, 0.0) / vn


def speed_ahead(blocks: list[Block], v: float, lead: float, feed_ovr: float, rapid_ovr: float,
                hold: bool) -> tuple[float, int]:
    """(speed mm/s, index into ``blocks``) where the motion will be ``lead`` seconds from now.

    GRBL prepares step segments ahead of the one executing, and both the speed that ``FS:``
    reports (``st_get_realtime_rate`` returns ``prep.current_speed``) and the M4 laser value
    (``sys.spindle_speed``) are those of the last segment prepared, not of the head. The
    motion is integrated forward on a copy of the plan; past the last block the speed is 0.
    """
    done, k = blocks[0].done, 0
    for _ in range(4 * len(blocks) + 4):
        if k >= len(blocks) or lead <= _EPS:
            break
        b = blocks[k]
        d = max(b.length - done, 0.0)
        if d <= 1e-7:
            k, done = k + 1, 0.0
            continue
        vn, ve = b.nominal(feed_ovr, rapid_ovr), exit_speed(blocks[k:], feed_ovr, rapid_ovr)
        acc, duration = phase(v, d, vn, ve, b.accel, hold)
        if duration <= 0.0:  # at rest in a feed hold: nothing is prepared ahead
            break
        tt = min(lead, duration)
        s = min(max(v * tt + 0.5 * acc * tt * tt, 0.0), d)
        v, lead, done = max(v + acc * tt, 0.0), lead - tt, done + s
        if d - s <= 1e-7 and acc < 0 and not hold:
            v = min(ve, vn)
    if k >= len(blocks):
        return 0.0, len(blocks) - 1
    return v, k
