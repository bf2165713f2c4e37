"""Whether two edges can be sewn as the pieces lie: laid along each other, do they agree?

Two edges sewn together meet along their whole length with the pieces on either side of
the seam. So the second edge, read backwards, is moved onto the first by the best rigid
motion (Kabsch, no reflection): how far it stays from the first (a sleeve cap follows its
armhole, a straight side its straight partner) and how much of the two pieces then overlap
(a centre line sewn to its mirror has the halves side by side; a hem laid on a shoulder
puts one piece over the other) say whether the seam is plausible.
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely import affinity

from solver.geometry import resample_polyline

__all__ = ["fit_and_overlap"]

SAMPLES = 24


def _kabsch(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation r and translation t with ``src @ r.T + t`` closest to ``dst``."""
    cs, cd = src.mean(0), dst.mean(0)
    u, _, vt = np.linalg.svd((src - cs).T @ (dst - cd))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1.0, d]) @ u.T
    return r, cd - r @ cs


def _length(line: np.ndarray) -> float:
    return max(float(np.linalg.norm(np.diff(line, axis=0), axis=1).sum()), 1e-9)


def fit_and_overlap(line_a: np.ndarray, poly_a: shapely.Polygon, line_b: np.ndarray,
                    poly_b: shapely.Polygon, *, gathered: bool = False
                    ) -> tuple[float, float, float]:
    """(RMS distance / length, overlapping share of the smaller piece, how much the moved
    piece b is piece a mirrored in the seam (intersection over union)) with ``line_b`` of
    b (read backwards) laid onto ``line_a`` of a; a ``gathered`` b is first scaled to a's
    length (gathers shorten it evenly)."""
    la = resample_polyline(line_a, SAMPLES - 1)
    lb = resample_polyline(line_b, SAMPLES - 1)[::-1]
    length = _length(line_a)
    if gathered:
        k = length / _length(line_b)
        c = lb.mean(0)
        lb = c + k * (lb - c)
        poly_b = affinity.scale(poly_b, k, k, origin=tuple(c))
    r, t = _kabsch(lb, la)
    rms = float(np.sqrt(((lb @ r.T + t - la) ** 2).sum(1).mean())) / length
    moved = affinity.affine_transform(poly_b, [r[0, 0], r[0, 1], r[1, 0], r[1, 1], t[0], t[1]])
    d = la[-1] - la[0]
    n = d / max(float(np.linalg.norm(d)), 1e-12)
    m = 2 * np.outer(n, n) - np.eye(2)  # reflection in the seam's chord
    off = la[0] - m @ la[0]
    image = affinity.affine_transform(poly_a, [m[0, 0], m[0, 1], m[1, 0], m[1, 1], *off])
    try:
        shared = poly_a.intersection(moved).area
        mirror = image.intersection(moved).area / max(image.union(moved).area, 1e-9)
    except shapely.errors.GEOSException:
        shared, mirror = 0.0, 0.0
    return rms, float(shared / max(min(poly_a.area, poly_b.area), 1e-9)), float(mirror)
