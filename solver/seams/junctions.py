"""Where seams meet: pairs of candidate seams that no garment sews together.

Seams that meet at a point of one piece meet at one point of the other: two seams between
the same two pieces that end at one point of one piece but at two points of the other would
sew one point to two. And two that meet at one point of both, where both pieces turn a
sharp corner, would sew the pieces into a bag's corner (a front's hem to the back's hem
beside the side seam): a seam does not turn a sharp corner (:mod:`solver.seams.runs`), and
neither do two seams with the same two partners. Each such pair is one linear constraint
(at most one of the two) in the integer program.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from solver.seams.outline import MERGE_MM, SewPiece
from solver.seams.runs import SHARP_DEG, Run

__all__ = ["junction_conflicts"]


def _near(x: np.ndarray, length: float) -> np.ndarray:
    """(k,k) whether arc positions ``x`` are within :data:`MERGE_MM` of each other."""
    d = np.abs(x[:, None] - x[None, :])
    return np.minimum(d, length - d) <= MERGE_MM


def _sharp(positions: np.ndarray, x: np.ndarray, length: float) -> np.ndarray:
    """(k,) whether each arc position of ``x`` is at one of the sharp corners ``positions``."""
    if not len(positions):
        return np.zeros(len(x), bool)
    d = np.abs(x[:, None] - positions[None, :])
    return (np.minimum(d, length - d) <= MERGE_MM).any(1)


def junction_conflicts(pieces: list[SewPiece], runs: list[Run], pairs: np.ndarray
                       ) -> np.ndarray:
    """(m,2) indices into ``pairs`` of candidates that cannot both be seams: between the same
    two pieces, they end at one point of one piece and at two points of the other (one
    point sewn to two), or at one point of each that is a sharp corner of both."""
    sharp = [p.corners(SHARP_DEG)[0] for p in pieces]
    groups: dict[tuple[int, int], list[tuple[int, float, float]]] = defaultdict(list)
    for k, (i, j) in enumerate(pairs.tolist()):
        a, b = runs[i], runs[j]
        if a.piece == b.piece:
            continue
        if a.piece > b.piece:
            a, b = b, a  # a seam reads the same from either side
        la, lb = pieces[a.piece].length, pieces[b.piece].length
        groups[(a.piece, b.piece)] += [(k, a.start % la, b.end % lb), (k, a.end % la,
                                                                        b.start % lb)]
    out = []
    for (pa, pb), ends in groups.items():
        k, sa, sb = (np.array(v) for v in zip(*ends, strict=True))
        same_a, same_b = _near(sa, pieces[pa].length), _near(sb, pieces[pb].length)
        corner = _sharp(sharp[pa], sa, pieces[pa].length) & _sharp(sharp[pb], sb,
                                                                   pieces[pb].length)
        bad = (same_a ^ same_b) | (same_a & same_b & corner[:, None] & corner[None, :])
        x, y = np.nonzero(np.triu(bad, 1))
        out.append(np.column_stack([k[x], k[y]])[k[x] != k[y]])
    if not out:
        return np.zeros((0, 2), dtype=int)
    return np.unique(np.sort(np.vstack(out), axis=1), axis=0)
