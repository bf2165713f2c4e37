"""Where seams meet: pairs of candidate seams that no garment sews together.

Seams that meet at a point of one piece meet at one point of the other: two seams between
the same two pieces that end at one point of one piece but at two points of the other would
sew one point to two. And two that meet at one point of both, where both pieces turn a
sharp corner, would sew the pieces into a bag's corner (a front's hem to the back's hem
beside the side seam): a seam does not turn a sharp corner (:mod:`solver.seams.runs`), and
neither do two seams with the same two partners. Each such pair is one linear constraint
(at most one of the two) in the integer program.

And where a piece's line runs on smoothly from one seam into another with two other pieces
(a sleeve cap sewn to the back armhole, then on to the front armhole), those two pieces meet
there too: the back and the front are sewn together (their shoulder seam) from the two points
the cap's break is sewn to. Such a triple of seams is rewarded in the integer program: a cap
half given to the other side's armhole, or to a piece that does not meet the first, has no
seam closing the triple. Likewise a tube sleeve: its cap's two ends meet the top of the
side seam, so its underarm (the sleeve sewn to itself) joins the two points of the sleeve
that the side seam's top is sewn to; the four seams are rewarded together.
"""

from __future__ import annotations

import itertools
from collections import defaultdict

import numpy as np

from solver.seams.outline import MERGE_MM, SewPiece
from solver.seams.runs import SHARP_DEG, Run, by_couple

__all__ = ["junction_conflicts", "meeting_triples", "order_conflicts", "tube_meetings"]


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


def _ends(runs: list[Run], pairs: np.ndarray, lengths: list[float]
          ) -> list[tuple[int, int, float, bool, int, float]]:
    """Each candidate's two ends from either side: (candidate, piece, arc position, whether
    the run starts there, the other piece, the point of it sewn there)."""
    out = []
    for k, (i, j) in enumerate(pairs.tolist()):
        a, b = runs[i], runs[j]
        if a.piece == b.piece:
            continue
        la, lb = lengths[a.piece], lengths[b.piece]
        for x, y, lx, ly in ((a, b, la, lb), (b, a, lb, la)):
            out += [(k, x.piece, x.start % lx, True, y.piece, y.end % ly),
                    (k, x.piece, x.end % lx, False, y.piece, y.start % ly)]
    return out


def _close(x: float, y: float, length: float) -> bool:
    d = abs(x - y) % length
    return min(d, length - d) <= MERGE_MM


def meeting_triples(pieces: list[SewPiece], runs: list[Run], pairs: np.ndarray
                    ) -> np.ndarray:
    """(m,3) indices into ``pairs``: two candidates that follow each other along one piece's
    line where it turns no sharp corner, sewn there to a corner of each of two other pieces
    (an armhole turns into the shoulder), and a candidate between those two that ends at
    those two corners; the two are no copies of one piece."""
    lengths = [p.length for p in pieces]
    sharp = [p.corners(SHARP_DEG)[0] for p in pieces]
    corner = [p.corners()[0] for p in pieces]
    ends = _ends(runs, pairs, lengths)
    by_pieces: dict[tuple[int, int], list[tuple[int, float, float]]] = defaultdict(list)
    by_piece: dict[int, list[tuple[int, float, bool, int, float]]] = defaultdict(list)
    for k, p, s, starts, q, t in ends:
        by_pieces[(p, q)].append((k, s, t))
        if not _sharp(sharp[p], np.array([s]), lengths[p])[0] and \
                _sharp(corner[q], np.array([t]), lengths[q])[0]:
            by_piece[p].append((k, s, starts, q, t))
    out = set()
    for p, here in by_piece.items():
        for kx, s, starts, f, pf in here:
            if starts:
                continue  # x ends at the break, y starts there
            for ky, s2, starts2, b, pb in here:
                if not starts2 or len({p, f, b}) < 3 or not _close(s, s2, lengths[p]) \
                        or _copies(pieces[f], pieces[b]):
                    continue
                out |= {(kx, ky, kz) for kz, u, v in by_pieces[(f, b)]
                        if _close(u, pf, lengths[f]) and _close(v, pb, lengths[b])}
    return np.array(sorted(out), dtype=int).reshape(-1, 3)


def _copies(a: SewPiece, b: SewPiece) -> bool:
    """Whether two pieces are copies of one pattern piece (a left and a right): a cap's two
    armholes are a front and a back, never a piece and its mirror image."""
    return bool(a.family) and a.family == b.family


def _cap_halves(x: Run, y: Run, underarm: float, length: float, sharp: np.ndarray) -> bool:
    """Whether runs ``x`` then ``y`` of one piece are a short sleeve's cap halves: meeting
    where the line turns no sharp corner, each longer than the ``underarm``."""
    return (_close(x.end, y.start, length) and min(x.length, y.length) > underarm
            and not _sharp(sharp, np.array([x.end]), length)[0])


def _run_on(runs: list[Run], pair: np.ndarray, piece: int) -> Run:
    """The side of candidate ``pair`` on ``piece``."""
    return next(runs[i] for i in pair if runs[i].piece == piece)


def tube_meetings(pieces: list[SewPiece], runs: list[Run], pairs: np.ndarray,
                  tubes: np.ndarray) -> np.ndarray:
    """(m,4) indices into ``pairs``: x starting at one point of a piece and y ending at
    another, x and y a cap's two halves (:func:`_cap_halves`; a skirt's sides sewn into a
    tube under a waist split in two would look the same, but its sides are longer), sewn at
    those two points to corners of two other pieces, a candidate z between those two that
    ends at those corners, and a candidate u among ``tubes`` (indices of candidates of one
    piece with itself) that joins the first two points."""
    lengths = [p.length for p in pieces]
    sharp = [p.corners(SHARP_DEG)[0] for p in pieces]
    by_pieces, by_piece = _ends_at_corners(pieces, runs, pairs)
    out = set()
    for ku in tubes.tolist():
        a, b = runs[pairs[ku, 0]], runs[pairs[ku, 1]]
        p, length = a.piece, lengths[a.piece]
        for u1, u2 in ((a.end, b.start), (b.end, a.start)):
            xs = [e for e in by_piece[p] if e[2] and _close(e[1], u1, length)]
            ys = [e for e in by_piece[p] if not e[2] and _close(e[1], u2, length)]
            for (kx, _, _, f, pf), (ky, _, _, g, pg) in itertools.product(xs, ys):
                if len({p, f, g}) == 3 and not _copies(pieces[f], pieces[g]) and _cap_halves(
                        _run_on(runs, pairs[kx], p), _run_on(runs, pairs[ky], p),
                        max(a.length, b.length), length, sharp[p]):
                    out |= {(kx, ky, kz, ku) for kz, v, w in by_pieces[(f, g)]
                            if _close(v, pf, lengths[f]) and _close(w, pg, lengths[g])}
    return np.array(sorted(out), dtype=int).reshape(-1, 4)


def _ends_at_corners(pieces: list[SewPiece], runs: list[Run], pairs: np.ndarray):
    """Candidates' ends by (piece, other piece): (candidate, position, other's position);
    and by piece where the other piece has a corner: (candidate, position, whether the run
    starts there, other piece, other's position)."""
    lengths = [p.length for p in pieces]
    corner = [p.corners()[0] for p in pieces]
    by_pieces: dict[tuple[int, int], list[tuple[int, float, float]]] = defaultdict(list)
    by_piece: dict[int, list[tuple[int, float, bool, int, float]]] = defaultdict(list)
    for k, p, s, starts, q, t in _ends(runs, pairs, lengths):
        by_pieces[(p, q)].append((k, s, t))
        if _sharp(corner[q], np.array([t]), lengths[q])[0]:
            by_piece[p].append((k, s, starts, q, t))
    return by_pieces, by_piece


def order_conflicts(pieces: list[SewPiece], runs: list[Run], pairs: np.ndarray) -> np.ndarray:
    """(m,3) indices into ``pairs``: three candidates between the same two pieces, apart on
    both, that run round one piece in the same order as round the other. Two pieces laid
    face to face meet along their seams in reverse order (a front's side seam, shoulder,
    shoulder, side seam are the back's side seam, shoulder, shoulder, side seam the other way
    round); the same order would cross them (a right shoulder sewn to the left one)."""
    out = []
    for (pa, pb), cands in by_couple(runs, pairs).items():
        la, lb = pieces[pa].length, pieces[pb].length
        for (k1, a1, b1), (k2, a2, b2), (k3, a3, b3) in itertools.combinations(cands, 3):
            if not all(_apart(x, y, la) for x, y in ((a1, a2), (a1, a3), (a2, a3))) or \
                    not all(_apart(x, y, lb) for x, y in ((b1, b2), (b1, b3), (b2, b3))):
                continue
            if _turn(a1, a2, a3, la) == _turn(b1, b2, b3, lb):
                out.append((k1, k2, k3))
    return np.array(out, dtype=int).reshape(-1, 3)


def _apart(x: Run, y: Run, length: float) -> bool:
    """Whether two runs of one piece share no more than a point of its line."""
    return all(min(x.end, y.end + lap) - max(x.start, y.start + lap) <= MERGE_MM
               for lap in (-length, 0.0, length))


def _turn(x: Run, y: Run, z: Run, length: float) -> bool:
    """Whether the runs' middles come x, y, z going round the line (else x, z, y)."""
    mx, my, mz = (0.5 * (r.start + r.end) for r in (x, y, z))
    return (my - mx) % length < (mz - mx) % length
