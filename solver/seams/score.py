"""Inferred seams scored against known ones: the share of the true seam length found between
the right two pieces at the right place, and the share of the inferred length that is true.

Both sets are sampled as point correspondences (a point on piece A sewn to a point on piece
B, every :data:`STEP_MM`); a sample counts when the other set has one between the same two
pieces within :data:`TOL_MM` on both sides, so a seam found on the wrong pieces, the wrong
edge or with the wrong length scores nothing for the part that is wrong.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from solver.seams.match import Seam
from solver.seams.outline import SewPiece, arc_position, point_at

__all__ = ["Correspondence", "SeamScore", "onto", "sample_seams", "score_seams"]

STEP_MM = 5.0
TOL_MM = 10.0


@dataclass
class Correspondence:
    """Sampled seams: piece pair (k,2), points on the first (k,2) and second (k,2), and the
    length each sample stands for (k,)."""

    pieces: np.ndarray
    a: np.ndarray
    b: np.ndarray
    weight: np.ndarray

    @staticmethod
    def join(parts: list[Correspondence]) -> Correspondence:
        if not parts:
            z = np.zeros((0, 2))
            return Correspondence(np.zeros((0, 2), dtype=int), z, z, np.zeros(0))
        return Correspondence(*(np.concatenate([getattr(p, f) for p in parts])
                                for f in ("pieces", "a", "b", "weight")))


@dataclass(frozen=True)
class SeamScore:
    true_mm: float
    inferred_mm: float
    recall: float  # share of the true length found
    precision: float  # share of the inferred length that is true


def sample_seams(seams: list[Seam], pieces: list[SewPiece]) -> Correspondence:
    """Point correspondences along inferred seams (``a_start`` meets ``b_end``, matched
    notches meet: :meth:`Seam.b_at`)."""
    parts = []
    for s in seams:
        pa, pb = pieces[s.piece_a], pieces[s.piece_b]
        n = max(int(np.ceil(s.length_mm / STEP_MM)), 1)
        u = (np.arange(n) + 0.5) / n
        arc_a = s.a_start + u * (s.a_end - s.a_start)
        a, b = point_at(pa, arc_a), point_at(pb, s.b_at(arc_a))
        parts.append(Correspondence(np.tile([s.piece_a, s.piece_b], (n, 1)), a, b,
                                    np.full(n, s.length_mm / n)))
    return Correspondence.join(parts)


def onto(c: Correspondence, pieces: list[SewPiece]) -> Correspondence:
    """``c`` drawn on other lines of the same pieces (a net pattern's sew line, read
    inset) carried to the nearest point of each piece's line."""
    a, b = c.a.copy(), c.b.copy()
    for side, pts in ((0, a), (1, b)):
        for k in np.unique(c.pieces[:, side]):
            rows = c.pieces[:, side] == k
            pts[rows] = point_at(pieces[k], arc_position(pieces[k], pts[rows]))
    return Correspondence(c.pieces, a, b, c.weight)


def _covered(c: Correspondence, ref: Correspondence) -> np.ndarray:
    """(k,) whether each sample of ``c`` has a sample of ``ref`` between the same pieces,
    near it on both sides (either order of the two pieces)."""
    hit = np.zeros(len(c.weight), dtype=bool)
    if not len(ref.weight) or not len(c.weight):
        return hit
    # 4-D points: the two sides side by side, with the pieces ordered the same way
    for flip in (False, True):
        rp = ref.pieces[:, ::-1] if flip else ref.pieces
        ra, rb = (ref.b, ref.a) if flip else (ref.a, ref.b)
        for pair in {tuple(p) for p in c.pieces.tolist()}:
            mine = np.flatnonzero((c.pieces == pair).all(1))
            theirs = np.flatnonzero((rp == pair).all(1))
            if not len(theirs):
                continue
            tree = cKDTree(np.hstack([ra[theirs], rb[theirs]]))
            d, _ = tree.query(np.hstack([c.a[mine], c.b[mine]]))
            hit[mine] |= d <= TOL_MM * np.sqrt(2)
    return hit


def score_seams(truth: Correspondence, inferred: Correspondence) -> SeamScore:
    """Recall and precision of ``inferred`` against ``truth`` by sewn length."""
    found = _covered(truth, inferred)
    right = _covered(inferred, truth)
    t, i = float(truth.weight.sum()), float(inferred.weight.sum())
    return SeamScore(t, i, float(truth.weight[found].sum()) / t if t else 1.0,
                     float(inferred.weight[right].sum()) / i if i else 1.0)
