"""Darts as a CAD marks them on a cut line, and the sew line's darts opened from those marks.

A pattern CAD does not cut a dart out: the cut line runs across the dart's mouth (with the
small peak, the take-up, that lies flat once the dart is sewn), a notch marks each leg
where it meets the cut line and a drill hole (layer 13) marks the tip, set back
:data:`DRILL_SETBACK_MM` (half an inch) towards the mouth so that the hole is hidden inside
the sewn dart. A sew line made by insetting such a cut line has no dart; the reader opens
it again from the marks: two notches close together with a drill hole on their
perpendicular bisector, well inside the piece.
"""

from __future__ import annotations

import numpy as np
import shapely

__all__ = ["DRILL_SETBACK_MM", "dart_cap", "open_darts"]

DRILL_SETBACK_MM = 12.7  # the drill hole lies this far short of the dart's tip
MAX_MOUTH_MM = 80.0  # wider pairs of notches are no dart's mouth
MIN_SLENDER = 2.0  # a dart is at least this many times longer than its mouth is wide
MAX_OFF_AXIS = 0.15  # drill hole off the mouth's perpendicular bisector, share of the length


def dart_cap(m1: np.ndarray, tip: np.ndarray, m2: np.ndarray) -> np.ndarray:
    """The take-up's peak: the point on the dart's centre line beyond the mouth such that the
    line m1 -> peak -> m2 lies straight when the dart is closed (each half turns by half the
    dart's angle)."""
    mid = 0.5 * (m1 + m2)
    axis = mid - tip
    axis /= max(float(np.linalg.norm(axis)), 1e-12)
    half_width = 0.5 * float(np.linalg.norm(m2 - m1))
    half_angle = np.arctan2(half_width, float(np.linalg.norm(mid - tip)))
    return mid + axis * half_width * np.tan(half_angle)


def _mouths(notches: np.ndarray, drills: np.ndarray) -> list[tuple[int, int, int]]:
    """(notch, notch, drill) index triples marking a dart: for each drill hole the pair of
    notches on whose perpendicular bisector it stands best, far enough from them (a dart
    is slender); a notch is used once."""
    out, used = [], set()
    for d, hole in enumerate(drills):
        best = None
        for i in range(len(notches)):
            for j in range(i + 1, len(notches)):
                w = float(np.linalg.norm(notches[j] - notches[i]))
                if i in used or j in used or not 1.0 < w <= MAX_MOUTH_MM:
                    continue
                axis = hole - 0.5 * (notches[i] + notches[j])
                length = float(np.linalg.norm(axis))
                off = abs(float(axis @ (notches[j] - notches[i]))) / w
                if length >= MIN_SLENDER * w and off <= MAX_OFF_AXIS * length and (
                        best is None or off / length < best[0]):
                    best = (off / length, i, j)
        if best is not None:
            used |= {best[1], best[2]}
            out.append((best[1], best[2], d))
    return out


def open_darts(sew: np.ndarray, notches: np.ndarray, drills: np.ndarray
               ) -> tuple[np.ndarray, int]:
    """The sew line (CCW ring, no repeated end) with every dart the marks show opened: the
    short arc between the two legs' ends replaced by leg, tip, leg; and how many."""
    notches = np.asarray(notches, float).reshape(-1, 2)
    drills = np.asarray(drills, float).reshape(-1, 2)
    ring = np.asarray(sew, float)
    poly = shapely.Polygon(ring)
    opened = 0
    for i, j, d in _mouths(notches, drills):
        if not poly.contains(shapely.Point(drills[d])):
            continue
        mid = 0.5 * (notches[i] + notches[j])
        axis = drills[d] - mid
        tip = drills[d] + axis / np.linalg.norm(axis) * DRILL_SETBACK_MM
        line = shapely.LinearRing(ring)
        s = sorted(line.project(shapely.Point(p)) for p in (notches[i], notches[j]))
        total = line.length
        if s[1] - s[0] > total / 2:  # the mouth is the short arc: start past the end
            s = [s[1], s[0] + total]
        cum = np.concatenate([[0], np.cumsum(np.linalg.norm(
            np.diff(np.vstack([ring, ring[:1]]), axis=0), axis=1))])
        keep = (cum[:-1] > s[1] - total) & (cum[:-1] < s[0]) | (cum[:-1] > s[1])
        ends = [np.asarray(line.interpolate(v % total).coords[0]) for v in s]
        order = np.argsort(np.where(cum[:-1] > s[1], cum[:-1] - total, cum[:-1])[keep])
        rest = ring[keep][order]
        ring = np.vstack([ends[1][None], rest, ends[0][None], tip[None]])
        poly = shapely.Polygon(ring)
        opened += 1
    return ring, opened
