"""GRBL 1.1's spindle and laser values: what a step segment gets, and what the trace shows.

In laser mode (``$32=1``) the beam is on only in G1/G2/G3 motion. Under M4 GRBL computes
each 10 ms step segment's value from the speed at the segment's end, relative to the
programmed feed (stepper.c: ``rpm *= current_speed * inv_rate``; laser_mode.md: "adjust laser
power based on the current speed relative to the programmed rate"), so the value ramps with
every acceleration and the segment that brakes to a stop runs dark; M3 holds S. Then the
spindle override and ``$30``/``$31`` apply as in ``spindle_compute_pwm_value``.
"""

from __future__ import annotations

import math

import numpy as np

import simulators.grbl.codes as C
from simulators.grbl.motion import Block

__all__ = ["is_dynamic", "power_pieces", "segment_ends", "segment_value", "spindle_value"]


def spindle_value(s: float, override: float, settings: dict[int, float]) -> float:
    """The value GRBL applies and reports for a programmed ``s``: scaled by the spindle
    override (%), 0 stays off, anything else held within $31..$30."""
    s = s * override / 100.0
    if s <= 0:
        return 0.0
    return min(max(s, float(settings[31])), float(settings[30]))


def is_dynamic(b: Block, laser_mode: bool) -> bool:
    """M4 in laser mode on a feed move: the value follows the speed (stepper.c's
    ``is_pwm_rate_adjusted``)."""
    return laser_mode and b.spindle == "M4" and b.feed is not None and not b.jog


def segment_value(b: Block, v: float, override: float, settings: dict[int, float]) -> float:
    """The laser-mode value of a step segment of ``b`` ending at speed ``v`` (mm/s): 0 off
    G1/G2/G3 motion, S x speed / F under M4 (the programmed F: feed overrides do not change
    it), S under M3."""
    if b.feed is None or b.spindle == "M5" or b.jog:
        return 0.0
    s = b.speed * (v * 60.0 / b.feed if b.spindle == "M4" else 1.0)
    return spindle_value(s, override, settings)


def power_pieces(b: Block, p0: np.ndarray, p1: np.ndarray, override: float,
                 settings: dict[int, float]) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """Block ``b`` from ``p0`` to ``p1`` under M4 as (from, to, value) pieces: one per run
    of step segments of equal value, from the motion recorded since it was last traced."""
    along, speed = segment_ends(b.chunks, C.DT_SEGMENT)
    value = np.array([segment_value(b, v, override, settings) for v in speed[1:]])
    keep = np.append(np.flatnonzero(np.diff(value) != 0), len(value) - 1)
    ends = along[np.append(0, keep + 1)]
    points = [p0, *(b.start + b.unit * e for e in ends[1:-1]), p1]
    return [(q0, q1, float(value[k])) for q0, q1, k in zip(points[:-1], points[1:], keep,
                                                            strict=True)
            if np.linalg.norm(q1[:2] - q0[:2]) > 1e-9]


def segment_ends(chunks: list[tuple[float, ...]], dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Distances along a block (mm from its start) where its step segments end, and the speed
    (mm/s) at each end, from the motion ``chunks`` recorded since it was last traced.

    GRBL cuts a block into segments of ``dt`` seconds from the block's start and computes each
    segment's M4 laser power from the speed at its end (stepper.c, ``prep.current_speed``
    after the segment's ramp). The first distance is where the chunks begin.
    """
    if not chunks:
        return np.zeros(0), np.zeros(0)
    ends_s, ends_v = [np.array([chunks[0][1]])], [np.array([chunks[0][3]])]
    for n, (elapsed, done, duration, v0, acc, v1) in enumerate(chunks):
        # grid points (k dt) within the chunk; a chunk often ends on one, up to rounding
        k = np.arange(math.floor(elapsed / dt + 1e-6) + 1,
                      math.floor((elapsed + duration) / dt + 1e-6) + 1)
        t = np.minimum(k * dt - elapsed, duration)
        t = t[t > 1e-9]
        if n == len(chunks) - 1 and not (len(t) and t[-1] >= duration - 1e-9):
            t = np.append(t, duration)  # where the trace ends: the block's end, or a stop
        ends_s.append(done + v0 * t + 0.5 * acc * t * t)
        ends_v.append(np.where(t >= duration - 1e-9, v1, np.maximum(v0 + acc * t, 0.0)))
    return np.concatenate(ends_s), np.concatenate(ends_v)
