"""Two pieces sewn together: a front and a back meet at the side and at the shoulder.

The integer program pays :data:`PAIR_COST_MM` once for each two pieces it sews together,
so a second seam between pieces already sewn costs less than a seam between two more: a
tank's shoulder goes to the back whose side seam the front already takes, not to the other
back, which mirrors it as well (a crossed shoulder). Only a front and a back of the body,
or pieces whose names say nothing, are discounted so: a left and a right half of one kind
meet only at the centre, a sleeve or a band once. And one seam cut in two between the same
two pieces (both halves meeting at one point of each, where neither turns a corner) is the
same seam: never both halves, the whole is a candidate of its own.
"""

from __future__ import annotations

import numpy as np

from solver.garment.symmetry import mirror_misfit
from solver.seams.names import front_or_back, name_parts
from solver.seams.outline import MERGE_MM, SewPiece
from solver.seams.runs import SHARP_DEG, Run, by_couple

__all__ = ["PAIR_COST_MM", "piece_couples", "split_conflicts"]

PAIR_COST_MM = 60.0  # of each seam's cost, what is paid once per two pieces sewn together
# (from {0, 40, 60, 80, 100} on half 0 of the bench)
MIRROR_MISFIT = 0.005  # a left and a right half: mirror images within this share of their
# size (Berkeley's flattened halves 0.0001-0.0011; a front and a back half 0.011-0.02)


def piece_couples(pieces: list[SewPiece], runs: list[Run], pairs: np.ndarray) -> np.ndarray:
    """(k,) index of each candidate's two pieces among the candidates' piece pairs, -1 for a
    piece with itself (a dart, a tube) and for a left and a right half of one kind."""
    ends = [tuple(sorted((runs[i].piece, runs[j].piece))) for i, j in pairs.tolist()]
    twice = {(p, q): p != q and _meet_twice(pieces[p], pieces[q]) for p, q in set(ends)}
    index: dict[tuple[int, int], int] = {}
    return np.array([index.setdefault(e, len(index)) if twice[e] else -1 for e in ends],
                    dtype=int).reshape(-1)


def _meet_twice(a: SewPiece, b: SewPiece) -> bool:
    """Whether two pieces may meet along two seams: a front and a back of the body (at the
    side and the shoulder), or pieces whose names say nothing; not a left and a right half,
    nor a sleeve, collar or band (on the Gerber tee a sleeve half was sewn to the body's
    other shoulder as well as to its armhole)."""
    if _left_and_right(a, b):
        return False
    ra, rb = front_or_back(a.name), front_or_back(b.name)
    return (not any(name_parts(a.name)) and not any(name_parts(b.name))) or (
        ra is not None and rb is not None and not ra[0] | rb[0] and ra[1] != rb[1])


def _left_and_right(a: SewPiece, b: SewPiece) -> bool:
    """Whether two pieces are the left and right halves of one kind: copies of one pattern
    piece, named so (a left and a right front), or unnamed and each other's mirror image
    (within :data:`MIRROR_MISFIT`: a front and a back half, alike but for the neckline, are
    further apart)."""
    (ka, sa), (kb, sb) = name_parts(a.name), name_parts(b.name)
    if (bool(a.family) and a.family == b.family) or (
            bool(ka) and ka == kb and sa is not None and sb is not None and sa != sb):
        return True
    return (not any(name_parts(a.name)) and not any(name_parts(b.name))
            and abs(a.length - b.length) <= MIRROR_MISFIT * max(a.length, b.length)
            and mirror_misfit(a.loop, b.loop) <= MIRROR_MISFIT)


def _at(x: float, positions: np.ndarray, length: float) -> bool:
    """Whether arc position ``x`` lies within :data:`MERGE_MM` of one of ``positions``."""
    d = np.abs(np.mod(positions - x + length / 2, length) - length / 2)
    return bool(len(d)) and bool(d.min() <= MERGE_MM)


def split_conflicts(pieces: list[SewPiece], runs: list[Run], pairs: np.ndarray
                    ) -> np.ndarray:
    """(m,2) indices into ``pairs``: two candidates between the same two pieces, one
    following the other along both (``a`` ends where the other's ``a`` starts, and its
    ``b`` starts where the other's ``b`` ends), meeting where neither line turns a sharp
    corner."""
    sharp = [p.corners(SHARP_DEG)[0] for p in pieces]
    lengths = [p.length for p in pieces]
    out = []
    for (pa, pb), cands in by_couple(runs, pairs).items():
        la, lb = lengths[pa], lengths[pb]
        for k1, a1, b1 in cands:
            for k2, a2, b2 in cands:
                if k1 != k2 and _at(a1.end, np.array([a2.start]), la) and \
                        _at(b1.start, np.array([b2.end]), lb) and \
                        not _at(a1.end, sharp[pa], la) and not _at(b1.start, sharp[pb], lb):
                    out.append((min(k1, k2), max(k1, k2)))
    return np.array(sorted(set(out)), dtype=int).reshape(-1, 2)
