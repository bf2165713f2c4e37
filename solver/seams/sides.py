"""Left and right: a seam on one side of a garment has its mirror twin on the other.

A left front and a right front, laid flat right side up, are each other's mirror image and
neither is its own (a piece with a handedness, unlike a back cut whole). Whatever is sewn
to one is sewn, mirrored, to the other: the left sleeve to the left front's armhole as the
right sleeve to the right's. So a candidate seam between pieces of two mirror pairs and its
twin between their partners (runs of the same lengths and notches) chosen together earn a
little more than each alone: the two sides of a garment are then sewn alike rather than
each by its own near tie of notch and length scores.

Pairs are taken where they are unambiguous: two pieces each other's mirror image within
:data:`PAIR_MISFIT`, each far from its own mirror image (:data:`CHIRAL_MISFIT`), and no
third piece as close to either, mirrored or not (a tee's four identical sleeve halves
have no one partner each, and gores no handedness).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solver.garment.symmetry import mirror_misfit
from solver.seams.outline import SewPiece
from solver.seams.runs import Run

__all__ = ["TwinRows", "mirror_partners", "mirror_twins", "twin_rows"]

PAIR_MISFIT = 0.006  # mirror images within this share of their size: a left and a right
# (Berkeley's flattened pairs 0.0001-0.0065, GarmentCode's 0.0006 at most)
CHIRAL_MISFIT = 4.0  # a piece's own mirror image misfits it by this many times the pair's
# misfit at least (a half-front 0.011-0.06; a back or a gore cut whole under 0.005) ...
CHIRAL_MIN = 0.008  # ... and by this share of its size at least
ALONE = 3.0  # any third piece misfits both by this many times the pair's misfit, mirrored
# or not (else the pairing is ambiguous: a tee's four sleeve halves 0.0004 from each other)
SAME_LENGTH = 0.02  # pieces whose sew lines differ by more than this share are no pair
TWIN_MM = 2.0  # a run and its mirror image differ in length by no more (or 1 %)
TWIN_REWARD_MM = 60.0  # a seam and its mirror twin chosen together earn this much matched
# length: the two sides of a garment sewn alike, not each by its own near tie ...
TWIN_MIN_MM = 100.0  # ... when both are this long at least (shorter twins, rewarded too,
# gave the Gerber tee's sleeve halves a second 86 mm seam each)


@dataclass(frozen=True)
class TwinRows:
    """Linear rows over the candidates ``x`` (n) and one binary unknown ``z`` per twin
    (1 only with both its candidates, worth ``reward`` each in the objective):
    ``on_candidates @ x + on_twins @ z <= upper``."""

    on_candidates: np.ndarray  # (r,n)
    on_twins: np.ndarray  # (r,t)
    upper: np.ndarray  # (r,)
    reward: np.ndarray  # (t,)

    @property
    def n_twins(self) -> int:
        return self.on_twins.shape[1]


def _misfits(pieces: list[SewPiece], i: int, j: int) -> tuple[float, float]:
    """(mirrored, direct) misfit of piece ``i`` fitted onto piece ``j``."""
    a, b = pieces[i].loop, pieces[j].loop
    return mirror_misfit(a, b), mirror_misfit((a * [-1.0, 1.0])[::-1], b)


def mirror_partners(pieces: list[SewPiece]) -> np.ndarray:
    """(n_pieces,) each piece's unambiguous mirror partner (see the module), -1 for none."""
    n = len(pieces)
    length = np.array([p.length for p in pieces])
    mirrored, direct = np.full((n, n), np.inf), np.full((n, n), np.inf)
    for i in range(n):
        for j in range(i + 1, n):
            if abs(length[i] - length[j]) <= SAME_LENGTH * max(length[i], length[j]):
                mirrored[i, j], direct[i, j] = _misfits(pieces, i, j)
                mirrored[j, i], direct[j, i] = mirrored[i, j], direct[i, j]
    closest = np.minimum(mirrored, direct)
    partner = np.full(n, -1)
    for i in range(n):
        j = int(np.argmin(mirrored[i]))
        m = mirrored[i, j]
        if m > PAIR_MISFIT or int(np.argmin(mirrored[j])) != i:
            continue
        others = np.delete(np.concatenate([closest[i], closest[j]]), [i, j, n + i, n + j])
        own = min(mirror_misfit(pieces[k].loop, pieces[k].loop) for k in (i, j))
        if own >= max(CHIRAL_MISFIT * m, CHIRAL_MIN) and (others > ALONE * m).all():
            partner[i] = j
    return partner


def twin_rows(pieces: list[SewPiece], runs: list[Run], pairs: np.ndarray) -> TwinRows:
    """The rows that let each twin's unknown be 1 only with both its candidates
    (:func:`mirror_twins`), each worth :data:`TWIN_REWARD_MM`."""
    twins = mirror_twins(pieces, runs, pairs)
    t = len(twins)
    on_x = np.zeros((2 * t, len(pairs)))
    on_z = np.zeros((2 * t, t))
    for half, member in ((0, twins[:, 0]), (t, twins[:, 1])):  # twin - member <= 0
        on_x[half + np.arange(t), member] = -1.0
        on_z[half + np.arange(t), np.arange(t)] = 1.0
    return TwinRows(on_x, on_z, np.zeros(2 * t), np.full(t, TWIN_REWARD_MM))


def mirror_twins(pieces: list[SewPiece], runs: list[Run], pairs: np.ndarray,
                 partner: np.ndarray | None = None) -> np.ndarray:
    """(t,2) indices into ``pairs``: a candidate between two mirror pairs' pieces and its
    twin between their partners, runs of the same lengths (within :data:`TWIN_MM`) and
    notches: a left sleeve's seam to the left front and the right's to the right front
    (not the seam between two partners: it is its own mirror image)."""
    partner = mirror_partners(pieces) if partner is None else partner
    ends = np.array([(runs[i].piece, runs[j].piece) for i, j in pairs.tolist()],
                    dtype=int).reshape(-1, 2)
    out = []
    for k, (p, q) in enumerate(ends.tolist()):
        if partner[p] < 0 or partner[q] < 0 or partner[p] == q:
            continue
        a, b = runs[pairs[k, 0]], runs[pairs[k, 1]]
        for m in np.flatnonzero(np.isin(ends[:, 0], partner[[p, q]])
                                & np.isin(ends[:, 1], partner[[p, q]])):
            c, d = runs[pairs[m, 0]], runs[pairs[m, 1]]
            c, d = (c, d) if c.piece == partner[p] else (d, c)  # either order in a pair
            if m > k and _alike(a, c) and _alike(b, d) and \
                    min(a.length, b.length) >= TWIN_MIN_MM:
                out.append((k, int(m)))
    return np.array(out, dtype=int).reshape(-1, 2)


def _alike(a: Run, b: Run) -> bool:
    """Whether two runs on mirror pieces could be each other's mirror image: the same
    length, counts of notches and ends at corners."""
    return (abs(a.length - b.length) <= max(TWIN_MM, 0.01 * a.length)
            and len(a.notches) == len(b.notches) and a.whole == b.whole)
