"""How fast GRBL 1.1 may go along a program's path: the corners cap the speed.

GRBL's planner limits the speed through every junction of two blocks by its junction
deviation ``$11`` (planner.c): with ``cos_theta = -u_in . u_out`` and
``sin_half = sqrt((1 - cos_theta) / 2)``, the junction speed squared is at most
``a * $11 * sin_half / (1 - sin_half)``; straight on it is unlimited, a reversal stops.
Between junctions the head speeds up and brakes at ``a``, so at a distance ``d`` from a
junction it can go no faster than ``sqrt(v_j^2 + 2 a d)``. A path of short segments with
sharp corners (a star, a wavy edge in 0.3 mm lines) is cut far below its programmed feed
by a perfectly healthy machine; the feed watchdog must expect that, and no more.

A program line that is not a move between two moves (M4/M5, G4, a comment) is taken as a
stop: GRBL syncs on a spindle change and a dwell, and the cap only needs to err low.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["DEFAULT_JUNCTION_DEVIATION", "CornerSpeeds", "junction_speed_sq"]

#: GRBL's default $11 (mm), used when the controller's own was not read.
DEFAULT_JUNCTION_DEVIATION = 0.01


def junction_speed_sq(u_in: np.ndarray, u_out: np.ndarray, acceleration: float,
                      deviation: float) -> np.ndarray:
    """GRBL's largest junction speed squared ((mm/s)^2) between unit directions ``u_in``
    and ``u_out`` ((n, 2) each): inf straight on, 0 for a reversal."""
    cos_theta = -np.einsum("ij,ij->i", u_in, u_out)
    sin_half = np.sqrt(np.clip(0.5 * (1.0 - cos_theta), 0.0, 1.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        v2 = acceleration * deviation * sin_half / (1.0 - sin_half)
    v2 = np.where(cos_theta < -0.999999, np.inf, v2)
    return np.where(cos_theta > 0.999999, 0.0, v2)


class CornerSpeeds:
    """The speed cap along a sampled path: every junction between consecutive motion
    lines (``path_line`` of each sample, in program order), and a stop at every other
    line boundary and at both ends. ``along`` is each sample's distance along the path."""

    def __init__(self, path: np.ndarray, path_line: np.ndarray, along: np.ndarray,
                 acceleration: float, deviation: float = DEFAULT_JUNCTION_DEVIATION):
        self.acceleration = float(acceleration)
        knots_s, knots_v2 = [], []
        if len(path) >= 2:
            ends = np.flatnonzero(path_line[:-1] != path_line[1:])  # a line's last sample
            ends = ends[(ends >= 1) & (ends + 2 < len(path))]
            a, b = path_line[ends], path_line[ends + 1]
            u_in = _unit(path[ends] - path[ends - 1])
            u_out = _unit(path[ends + 2] - path[ends + 1])
            # both sides of the junction are real moves of consecutive program lines
            same_in = path_line[ends - 1] == a
            same_out = path_line[ends + 2] == b
            moving = (np.hypot(*u_in.T) > 0) & (np.hypot(*u_out.T) > 0)
            v2 = junction_speed_sq(u_in, u_out, self.acceleration, float(deviation))
            joined = (b == a + 1) & (a >= 0) & same_in & same_out & moving
            v2 = np.where(joined, v2, 0.0)
            knots_s = [along[ends], along[[0, -1]]]
            knots_v2 = [v2, np.zeros(2)]
        s = np.concatenate(knots_s) if knots_s else np.zeros(0)
        order = np.argsort(s, kind="stable")
        self.s = s[order]
        self.v2 = (np.concatenate(knots_v2) if knots_v2 else np.zeros(0))[order]

    def cap(self, lo: float, hi: float, fastest: float) -> float:
        """The highest speed (mm/s) GRBL may reach anywhere in [lo, hi] mm along the
        path, at most ``fastest`` (mm/s)."""
        reach = fastest * fastest / (2.0 * self.acceleration)  # beyond it no corner matters
        i = int(np.searchsorted(self.s, lo - reach, "left"))
        j = int(np.searchsorted(self.s, hi + reach, "right"))
        if i >= j:
            return fastest
        s, v2 = self.s[i:j], self.v2[i:j]
        gap = np.maximum(np.maximum(lo - s, s - hi), 0.0)
        return min(fastest, math.sqrt(float(np.min(v2 + 2.0 * self.acceleration * gap))))


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.hypot(*v.T)
    return np.where(n[:, None] > 1e-9, v / np.maximum(n, 1e-12)[:, None], 0.0)
