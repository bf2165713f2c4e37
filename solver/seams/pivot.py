"""Seams that pivot: one side turns a reflex corner that its partner runs smoothly past.

A flared panel flattened (a skirt's gore, a godet's slit) has a seam side that turns sharply
inward where the piece opens into a fan, while the piece sewn to it runs smooth: the sewer
pivots at the corner. Laid on each other whole, two such sides agree in nothing but length
and notches (one folds, the other does not), so their shapes are compared piece by piece,
either side of the pivot: each part laid on its own, as a sewer lays one stretch at a time.
"""

from __future__ import annotations

import numpy as np
import shapely

from solver.seams.outline import MERGE_MM, SewPiece
from solver.seams.runs import SHARP_DEG, Run
from solver.seams.shape import fit_and_overlap

__all__ = ["pivot_shares", "reflex_corners", "shape_by_parts"]

SAME_SHARE = 0.02  # pivots this close (share of the seam) are one: both sides turn there


def reflex_corners(piece: SewPiece, tip_deg: float) -> np.ndarray:
    """Arc positions at which the piece's line turns a reflex corner sharper than
    :data:`~solver.seams.runs.SHARP_DEG` (where a run would end at a convex one) but no
    dart's tip (``tip_deg``)."""
    at, turn = piece.corners(SHARP_DEG)
    return at[(turn < 0) & (turn > -tip_deg)]


def pivot_shares(corners: np.ndarray, length: float, run: Run) -> list[float]:
    """Shares of the run's sewn length at the piece's reflex ``corners`` inside it (the
    piece's line ``length`` long); none for a run that skips darts."""
    if run.skips or not len(corners):
        return []
    u = np.concatenate([corners - run.start, corners + length - run.start])
    u = u[(u > MERGE_MM) & (u < run.length - MERGE_MM)]
    return sorted((u / run.length).tolist())


def _cut(line: np.ndarray, shares: list[float]) -> list[np.ndarray]:
    """The polyline cut at the given shares of its length (sorted, inside (0, 1))."""
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(line, axis=0), axis=1))])
    bounds = [0.0, *(s * cum[-1] for s in shares), cum[-1]]
    parts = []
    for s0, s1 in zip(bounds[:-1], bounds[1:], strict=True):
        inner = (cum > s0) & (cum < s1)
        at = np.array([s0, s1])
        ends = np.column_stack([np.interp(at, cum, line[:, 0]), np.interp(at, cum, line[:, 1])])
        parts.append(np.vstack([ends[:1], line[inner], ends[1:]]))
    return parts


def _straightness(line: np.ndarray) -> float:
    length = float(np.linalg.norm(np.diff(line, axis=0), axis=1).sum())
    return float(np.linalg.norm(line[-1] - line[0])) / max(length, 1e-9)


def shape_by_parts(line_a: np.ndarray, poly_a: shapely.Polygon, line_b: np.ndarray,
                   poly_b: shapely.Polygon, shares: list[float], *, gathered: bool = False
                   ) -> tuple[float, float, float, float]:
    """(difference in straightness, RMS distance / length, overlapping share, mirror IoU) of
    the two sides compared part by part between the pivots at ``shares`` of ``line_a``
    (sorted; ``line_b`` runs the other way: a's share u meets b's 1 - u), weighted by
    length."""
    shares = [u for k, u in enumerate(shares) if SAME_SHARE < u < 1 - SAME_SHARE
              and (k == 0 or u - shares[k - 1] > SAME_SHARE)]
    parts_a = _cut(line_a, shares)
    parts_b = _cut(line_b, [1.0 - s for s in reversed(shares)])[::-1]
    weight = np.diff([0.0, *shares, 1.0])
    terms = np.array([(abs(_straightness(pa) - _straightness(pb)),
                       *fit_and_overlap(pa, poly_a, pb, poly_b, gathered=gathered))
                      for pa, pb in zip(parts_a, parts_b, strict=True)])
    return tuple(float(v) for v in weight @ terms)
