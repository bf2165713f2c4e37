"""Which edges are sewn together: candidates scored, then chosen jointly by an integer program.

A candidate seam is a run of consecutive edges on one piece against a run on another, the
second read backwards (two pieces laid right side to right side run opposite ways along a
seam). It is scored by how well the sewn lengths agree, whether the notch groups fall at the
same places with the same counts, how alike the two lines are (straight to straight, and laid
on each other, :mod:`solver.seams.shape`), whether two mirrored halves would meet off the
grain, and what the piece names say (:mod:`solver.seams.names`). The chosen set maximises
the matched length times the score, less a fixed cost per seam, with every edge sewn at
most once (scipy's ``milp``,
HiGHS): an edge with no good partner (a hem, a neckline, an opening) stays open because no
candidate pays for it.

Berthouzoz et al. (SIGGRAPH 2013, "Parsing sewing patterns into 3D garments",
:DOI:`10.1145/2461912.2461975`) pose the same choice as an integer program over edge pairs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from scipy.optimize import Bounds, LinearConstraint, milp

from solver.seams.couples import PAIR_COST_MM, piece_couples, split_conflicts
from solver.seams.junctions import (
    junction_conflicts,
    meeting_triples,
    order_conflicts,
    tube_meetings,
)
from solver.seams.marks import FileMarks
from solver.seams.names import name_affinity, name_parts
from solver.seams.outline import DART_TIP_DEG, MERGE_MM, SewPiece, sub_loop
from solver.seams.pivot import pivot_shares, reflex_corners, shape_by_parts
from solver.seams.runs import Run, candidate_runs, run_line
from solver.seams.shape import fit_and_overlap
from solver.seams.sides import TwinRows, twin_rows

__all__ = ["Run", "Seam", "candidate_runs", "choose_seams"]

LENGTH_TOL = 0.06  # relative difference of sewn lengths beyond which two runs never match
EASE_TOL = 0.1  # the same for two curved runs (ease: a sleeve cap is longer than its armhole)
CURVED = 0.95  # a run whose chord is less than this share of its length is curved
NOTCH_TOL = 0.06  # notch positions (share of the run) within this are the same notch
EASED_NOTCH_TOL = 0.1  # the same on two curved runs: a cap's ease is not spread evenly, so
# its notches sit further off their share of the run than on a straight seam
NOTCH_W = 0.6  # notch groups that match score this much (at most) ...
NOTCHED_EXTRA = 0.6  # ... and this much more inside both sides in a file that notches
# its seams (:class:`solver.seams.marks.FileMarks`): matching notches there are what a
# sewer goes by (from {0, 0.3, 0.6, 0.9, 1.4} on half 0 of the bench)
NOTCH_MIN_MM = 10.0  # but never less than this along the run (a short seam's share is tight)
MIN_SCORE = 0.55  # a candidate scoring less is never sewn
MEETING_MM = 240.0  # three seams that close where three pieces meet (a cap's break, the
# shoulder) earn this much matched length, 1.5 seams' cost (from {160, 240, 320} on half 0)
CLOSING_SCORE = 0.0  # a weaker candidate is a seam only where it closes such a triple
SHORT_MM = 60.0  # runs this short match many others by chance ...
SHORT_EXTRA = 0.8  # ... so they must score this much more
SEAM_COST_MM = 160.0  # each seam chosen costs this much matched length (score x mm): a
# long seam is preferred to the same line cut into short ones, each with its own partner
# found by chance (measured on half of the bench's garments, checked on the other half);
# :data:`PAIR_COST_MM` of it is paid once per two pieces sewn (:mod:`solver.seams.couples`)
STRAIGHT_W = 2.0  # weight of a difference in straightness (chord / length)
RMS_W = 10.0  # weight of the distance between the two lines laid on each other (/ length)
MIRROR_IOU = 0.8  # a piece laid on the other this much its mirror image: two halves
GRAIN_DEG = 30.0  # a centre line lies within this of the grain
GATHER_MAX = 3.0  # a seam gathered more than this (longer side / shorter) is not proposed:
# a skirt's fullness is 1.5-3 times its waist; a gather needs notches matched inside both
# sides, so 3 costs nothing where there are none (2 -> 3: Berkeley dress3 78.5 -> 94.1 %
# found, dress-draped 88.3 -> 98.7, no garment worse; before notches matched counted double,
# GarmentCode skirt_many_panels lost 20 points true with it)
GATHER_PENALTY = 0.0  # a gathered seam's length term is minus this (an equal length scores 1):
# its notches, matched, carry it alone (from {0, 0.15, 0.3} on half 0)
WHOLE_BONUS = 0.3  # both sides run corner to corner between pieces whose names say they
# meet (a shoulder): a seam ends where the lines turn, a chance pairing rarely does on both
SHOULDER_MM = 150.0  # a front and a back (named so) are mirror images across their
# shoulders: a seam this short between pieces of other kinds is no centre line
DART_BONUS = 0.6  # two equal legs at a sharp reflex tip: a dart, as sure as matching notches
BAND_KINDS = frozenset(("collar",))  # a neck rib or band, sewn stretched (a waistband or
# cuff too, knit, but a woven one's other edge then finds a stretched partner by chance:
# GarmentCode's pants 100 -> 92 % true with them)
BAND_STRETCH = (1.1, 1.45)  # a rib is cut ~70-90 % of the edge it is sewn to
BAND_SCORE = 0.3  # a stretched band, known by its name alone: too weak to be sewn but as
# the two halves of a meeting (a neck rib's halves on a front and a back neckline, met by
# the shoulder seam), which :data:`MEETING_MM` pays for


@dataclass(frozen=True)
class Seam:
    """Piece ``piece_a`` from ``a_start`` to ``a_end`` (arc mm, CCW) sewn to ``piece_b``
    from ``b_start`` to ``b_end``: ``a_start`` meets ``b_end`` and ``a_end`` meets ``b_start``."""

    piece_a: int
    a_start: float
    a_end: float
    piece_b: int
    b_start: float
    b_end: float
    length_mm: float
    confidence: float
    source: str = "inferred"
    matched: tuple[tuple[float, float], ...] = ()  # (arc on a, arc on b) of the notches
    # matched inside the seam: points sewn together, where lengths alone would put them apart

    def b_at(self, arc_a: np.ndarray) -> np.ndarray:
        """The arc of piece b sewn to each arc of piece a: in proportion between the
        seam's ends and the notches matched inside it (an eased side is not eased evenly)."""
        knots_a = [self.a_start, *(x for x, _ in self.matched), self.a_end]
        knots_b = [self.b_end, *(y for _, y in self.matched), self.b_start]  # b backwards
        return np.interp(arc_a, knots_a, knots_b)


def _notch_score(a: Run, b: Run) -> float:
    """Up to +1 when the notch groups match (b read backwards), -1 when they disagree, 0
    when neither run has any. The notches at the ends count too: a's start meets b's end."""
    if a.end_notches != b.end_notches[::-1]:
        return -1.0
    if not a.notches and not b.notches:
        return 1.0 if any(a.end_notches) else 0.0
    mirrored = sorted((1.0 - s, c) for s, c in b.notches)
    if len(mirrored) != len(a.notches):
        return -1.0
    tol = EASED_NOTCH_TOL if min(a.straightness, b.straightness) < CURVED else NOTCH_TOL
    tol = max(tol, NOTCH_MIN_MM / min(a.length, b.length))
    worst = 0.0
    for (sa, ca), (sb, cb) in zip(a.notches, mirrored, strict=True):
        if abs(sa - sb) > tol or ca != cb:
            return -1.0
        worst = max(worst, abs(sa - sb) / tol)
    return 1.0 - worst ** 2  # the closer the notches, the surer (ease moves them a little)


def _length_score(a: Run, b: Run) -> tuple[float, bool]:
    """(the length term: 1 for equal sewn lengths, 0 at the tolerance, -1 beyond; whether
    the longer side is gathered onto the shorter, which only notches on both can tell)."""
    rel = abs(a.length - b.length) / max(a.length, b.length)
    curved = min(a.straightness, b.straightness) < CURVED
    tol = EASE_TOL if curved else LENGTH_TOL  # a sleeve cap is eased into its armhole
    if rel <= tol:
        return 1.0 - (rel / tol) ** 2, False
    gather = (a.notches and b.notches and a.piece != b.piece
              and max(a.length, b.length) <= GATHER_MAX * min(a.length, b.length))
    return (-GATHER_PENALTY, True) if gather else (-1.0, False)


def _band(piece: SewPiece) -> bool:
    """Whether the piece's name says it is a neck rib or band (:data:`BAND_KINDS`)."""
    return bool(name_parts(piece.name)[0] & BAND_KINDS)


def _stretched(a: Run, b: Run, pieces: list[SewPiece]) -> bool:
    """Whether the shorter run is a straight edge of a band stretched onto the longer run of
    a piece that is no band, by :data:`BAND_STRETCH`."""
    short, long_ = sorted((a, b), key=lambda r: r.length)
    ratio = long_.length / short.length
    return (_band(pieces[short.piece]) and not _band(pieces[long_.piece])
            and short.straightness >= 0.98
            and BAND_STRETCH[0] <= ratio <= BAND_STRETCH[1])


def _score(a: Run, b: Run, pieces: list[SewPiece], polys: list[shapely.Polygon],
           marks: FileMarks, reflex: list[np.ndarray]) -> float:
    """How plausible sewing run ``a`` to run ``b`` (read backwards) is: about 2 for a sure
    seam, below :data:`MIN_SCORE` for none. The cheap terms first; the two pieces are laid
    on each other only for a candidate that could still pass (part by part where either
    side pivots at one of its piece's ``reflex`` corners)."""
    if _stretched(a, b, pieces):  # a straight rib takes the shape of its edge, and a neck's
        # centre notch has no twin on a rib cut without: neither shape nor notches tell
        names = name_affinity(pieces[a.piece].name, pieces[b.piece].name)
        return BAND_SCORE if names > 0 else -1.0
    s, gathered = _length_score(a, b)
    if s <= -1.0:
        return -1.0
    notch = 0.0 if a.piece == b.piece else _notch_score(a, b)  # a dart's notches: its legs
    if gathered and notch <= 0:
        return -1.0  # a gathered seam is known by its notches alone
    matched = NOTCH_W + (NOTCHED_EXTRA if marks.notched and a.notches and b.notches else 0.0)
    s += matched * notch if notch >= 0 else 1.5 * notch
    pivots = _pivots(a, b, pieces, reflex)  # compared part by part below
    s -= 0.0 if pivots else STRAIGHT_W * abs(a.straightness - b.straightness)
    names = name_affinity(pieces[a.piece].name, pieces[b.piece].name)
    s += names + (WHOLE_BONUS if a.whole and b.whole and names > 0 else 0.0)
    if a.piece != b.piece:  # a dart's legs end at its mouth's notches
        s -= marks.penalty(a, b)
    if s < min(MIN_SCORE, CLOSING_SCORE):  # no shape can lift it to a seam; one that
        return s  # could still close a meeting is scored whole, its halves' penalty too
    lines = (run_line(pieces[a.piece], a), polys[a.piece], run_line(pieces[b.piece], b),
             polys[b.piece])
    if pivots:
        straight, rms, overlap, mirror = shape_by_parts(*lines, pivots, gathered=gathered)
        s -= STRAIGHT_W * straight
    else:
        rms, overlap, mirror = fit_and_overlap(*lines, gathered=gathered)
    if a.piece == b.piece:  # a dart folds its piece onto itself: overlap says nothing
        return s - RMS_W * rms + DART_BONUS
    return s - RMS_W * rms - 3.0 * overlap - _halves_penalty(pieces, a, b, mirror)


def _pivots(a: Run, b: Run, pieces: list[SewPiece], reflex: list[np.ndarray]) -> list[float]:
    """Shares of run a at which either side pivots (:mod:`solver.seams.pivot`)."""
    if a.piece == b.piece:
        return []
    u = pivot_shares(reflex[a.piece], pieces[a.piece].length, a)
    u += [1.0 - v for v in pivot_shares(reflex[b.piece], pieces[b.piece].length, b)]
    return sorted(u)


def _halves_penalty(pieces: list[SewPiece], a: Run, b: Run, mirror: float) -> float:
    """What sewing two pieces that are halves of one (copies, or mirror images in the seam)
    costs: only a centre line, along the grain, joins them."""
    pa, pb = pieces[a.piece], pieces[b.piece]
    copies = bool(pa.family) and pa.family == pb.family
    shoulder = _other_kinds(pa, pb) and a.length <= SHOULDER_MM
    if (copies or (mirror > MIRROR_IOU and not shoulder)) and not _along_grain(pa, a):
        # (unnamed pieces may as well be identical gores, which do meet so)
        return 2.0 if copies else (1.0 if _named(pa, pb) else 0.5)
    if copies:  # a left and a right are rarely sewn to each other, and then only along a
        # centre line, where they are mirror images (a back cut twice, sewn at the centre)
        return 0.5 if mirror > MIRROR_IOU else 2.0
    return 0.0


def _other_kinds(a: SewPiece, b: SewPiece) -> bool:
    """Whether the names say the two pieces are different kinds (a front and a back)."""
    ka, kb = name_parts(a.name)[0], name_parts(b.name)[0]
    return bool(ka and kb and not ka & kb)


def _named(*pieces: SewPiece) -> bool:
    """Whether any of the pieces' names says what or where the piece is."""
    return any(any(name_parts(p.name)) for p in pieces)


def _along_grain(piece: SewPiece, run: Run) -> bool:
    """Whether the run's chord lies within :data:`GRAIN_DEG` of the piece's grain line."""
    if piece.grain is None:
        return True
    ends = sub_loop(piece, run.start, run.end)[[0, -1]]
    d, g = ends[1] - ends[0], piece.grain[1] - piece.grain[0]
    cos = abs(float(d @ g)) / max(float(np.linalg.norm(d) * np.linalg.norm(g)), 1e-12)
    return cos >= np.cos(np.radians(GRAIN_DEG))


def _disjoint(a: Run, b: Run, length: float) -> bool:
    """Whether two runs of one piece share no part of its line."""
    return all(min(a.end, b.end + lap) - max(a.start, b.start + lap) <= 1e-6
               for lap in (-length, 0.0, length))


def _dart(a: Run, b: Run, length: float, tips: np.ndarray) -> bool:
    """Whether two runs of one piece are the legs of a dart: disjoint, meeting at one end,
    a sharp reflex corner of the outline (the tip). Other seams of a piece to itself (a
    tube sleeve's underarm) are not proposed: on flat patterns they pair a piece's
    mirror-image sides far too often."""
    if not _disjoint(a, b, length):
        return False
    meet = [x for x, y in ((a.end, b.start), (b.end, a.start))
            for lap in (-length, 0.0, length) if abs(x - y - lap) < MERGE_MM]
    return any(np.min(np.abs(np.mod(tips - m + length / 2, length) - length / 2)) < MERGE_MM
               for m in meet) if len(tips) else False


def _pairs(runs: list[Run], lengths: list[float], tips: list[np.ndarray],
           bands: list[bool] | None = None) -> np.ndarray:
    """(k,2) indices of run pairs whose lengths agree within tolerance, or within
    :data:`GATHER_MAX` when both have notches (a gathered seam), or a band's run (``bands``:
    per piece) shorter by :data:`BAND_STRETCH`: on two pieces, or the two legs of a dart on
    one piece."""
    length = np.array([r.length for r in runs])
    piece = np.array([r.piece for r in runs])
    notched = np.array([bool(r.notches) for r in runs])
    band = np.array([bool(bands and bands[r.piece]) for r in runs], dtype=bool)
    order = np.argsort(length)
    ls = length[order]
    out = []
    for k, i in enumerate(order.tolist()):
        eased = ls[k] / (1 - max(LENGTH_TOL, EASE_TOL))
        hi = np.searchsorted(ls, ls[k] * GATHER_MAX if notched[i] or band[i] else eased,
                             side="right")
        j = order[k + 1:hi]
        same = piece[j] == piece[i]
        stretched = band[i] & ~band[j] & (length[j] <= ls[k] * BAND_STRETCH[1])
        ok = ~same & ((length[j] <= eased) | notched[j] | stretched)  # longer: gathered,
        # notched both, or a band stretched onto it
        ok[same] = [_dart(runs[i], runs[m], lengths[piece[i]], tips[piece[i]])
                    for m in j[same].tolist()]
        j = j[ok]
        out.append(np.column_stack([np.full(len(j), i), j]))
    return np.vstack(out) if out else np.zeros((0, 2), dtype=int)


def _edges_of(run: Run, cuts: np.ndarray, length: float) -> list[int]:
    """The run's edges (indices into its piece's breakpoints) but the darts it skips."""
    edges = [(run.first + k) % len(cuts) for k in range(run.count)]
    if not run.skips:
        return edges
    out = []
    for e in edges:
        mid = cuts[e] + 0.5 * ((cuts[(e + 1) % len(cuts)] - cuts[e]) % length or length)
        if not any(d0 <= mid + lap <= d1 for d0, d1 in run.skips for lap in (0.0, length)):
            out.append(e)
    return out


def _overlaps(run: Run, seam: Seam, length: float) -> bool:
    """Whether ``run`` shares more than :data:`MERGE_MM` of its piece's line with ``seam``."""
    spans = [(seam.a_start, seam.a_end)] if seam.piece_a == run.piece else []
    spans += [(seam.b_start, seam.b_end)] if seam.piece_b == run.piece else []
    for s0, s1 in spans:
        for lap in (-length, 0.0, length):
            if min(run.end, s1 + lap) - max(run.start, s0 + lap) > MERGE_MM:
                return True
    return False


def choose_seams(pieces: list[SewPiece], runs: list[Run], cuts: list[np.ndarray], *,
                 fixed: list[Seam] = (), vetoed: set[frozenset[int]] = frozenset()
                 ) -> list[Seam]:
    """The jointly best set of seams (each edge sewn at most once), with confidences;
    ``fixed`` seams (declared by the operator) are kept and their edges taken, no seam is
    made between a ``vetoed`` pair of pieces."""
    runs = [r for r in runs if not any(_overlaps(r, f, pieces[r.piece].length) for f in fixed)]
    tips = [pos[turn < -DART_TIP_DEG] for pos, turn in (p.corners(DART_TIP_DEG)
                                                         for p in pieces)]
    pairs = _pairs(runs, [p.length for p in pieces], tips, [_band(p) for p in pieces])
    if vetoed:
        pieces_of = np.array([r.piece for r in runs], dtype=int).reshape(-1)
        keep = [frozenset((int(pieces_of[i]), int(pieces_of[j]))) not in vetoed
                for i, j in pairs.tolist()]
        pairs = pairs[np.array(keep, dtype=bool)] if len(pairs) else pairs
    return list(fixed) + _solve(pieces, runs, cuts, pairs)


def _solve(pieces: list[SewPiece], runs: list[Run], cuts: list[np.ndarray],
           pairs: np.ndarray) -> list[Seam]:
    """The integer program over the candidate ``pairs`` of ``runs``."""
    polys = [shapely.Polygon(p.loop).buffer(0) for p in pieces]
    marks = FileMarks.of(pieces)
    reflex = [reflex_corners(p, DART_TIP_DEG) for p in pieces]
    scores = np.array([_score(runs[i], runs[j], pieces, polys, marks, reflex)
                       for i, j in pairs.tolist()])
    shortest = np.array([min(runs[i].length, runs[j].length) for i, j in pairs.tolist()])
    strong = scores >= MIN_SCORE + SHORT_EXTRA * (shortest < SHORT_MM)  # short ones tie often
    bands = np.array([_stretched(runs[i], runs[j], pieces) for i, j in pairs.tolist()],
                     dtype=bool).reshape(-1) & (scores >= 0)
    tubes = _tube_pairs(runs, [p.length for p in pieces])
    pairs, scores, triples = _with_closing(
        pieces, runs, np.vstack([pairs, tubes]),
        np.concatenate([scores, [_tube_score(runs[i], runs[j]) for i, j in tubes.tolist()]]),
        np.concatenate([strong, np.zeros(len(tubes), bool)]), len(pairs),
        np.concatenate([bands, np.zeros(len(tubes), bool)]))
    if not len(pairs):
        return []
    offset = np.concatenate([[0], np.cumsum([len(c) for c in cuts])])
    rows, cols = [], []
    for k, (i, j) in enumerate(pairs.tolist()):
        for r in (runs[i], runs[j]):
            for e in _edges_of(r, cuts[r.piece], pieces[r.piece].length):
                rows.append(offset[r.piece] + e)
                cols.append(k)
    a = np.zeros((int(offset[-1]), len(pairs)))
    a[rows, cols] = 1.0
    la, lb = [runs[i].length for i in pairs[:, 0]], [runs[j].length for j in pairs[:, 1]]
    band = np.array([_stretched(runs[i], runs[j], pieces) for i, j in pairs.tolist()])
    covered = np.where(band, np.maximum(la, lb), np.minimum(la, lb))  # a band covers its edge
    couple = piece_couples(pieces, runs, pairs)
    weight = scores * covered - SEAM_COST_MM + PAIR_COST_MM * (couple >= 0)
    x = _program(a, weight, [junction_conflicts(pieces, runs, pairs),
                             order_conflicts(pieces, runs, pairs),
                             split_conflicts(pieces, runs, pairs),
                             _one_band_meeting(runs, pairs, band, triples)],
                 triples, couple,
                 twin_rows(pieces, runs, pairs))
    if x is None:
        return []
    chosen = np.flatnonzero(x[:len(pairs)] > 0.5)
    return [s for k in chosen for s in _seams(runs[pairs[k, 0]], runs[pairs[k, 1]], scores[k],
                                              _rival(k, pairs, scores, a))]


def _with_closing(pieces: list[SewPiece], runs: list[Run], pairs: np.ndarray,
                  scores: np.ndarray, strong: np.ndarray, n_tube: int, bands: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """The strong candidates, and the weak ones (scoring at least :data:`CLOSING_SCORE`)
    that close a meeting of two strong ones (a shoulder between a front and a back that
    mirror each other across it, unnamed; a tube sleeve's underarm: ``pairs`` from
    ``n_tube`` on) or of two stretched ``bands`` (a neck rib's halves), with the meetings
    (index arrays into the kept)."""
    idx = np.flatnonzero(strong | (scores >= CLOSING_SCORE))
    ok = strong[idx]
    half = ok | bands[idx]
    tubes = np.flatnonzero(idx >= n_tube)
    groups = [meeting_triples(pieces, runs, pairs[idx]),  # a band's halves meet here,
              tube_meetings(pieces, runs, pairs[idx], tubes)]  # not round a sleeve's tube
    groups = [g[h[g[:, 0]] & h[g[:, 1]]] for g, h in zip(groups, (half, ok), strict=True)
              if len(g)]
    keep = ok.copy()
    for g in groups:
        keep[g.reshape(-1)] = True
    new = np.cumsum(keep) - 1
    return pairs[idx[keep]], scores[idx[keep]], [new[g] for g in groups]


def _one_band_meeting(runs: list[Run], pairs: np.ndarray, band: np.ndarray,
                      groups: list[np.ndarray]) -> np.ndarray:
    """(r,4) rows: the halves of two meetings of stretched bands on one band piece, never
    all four. A folded rib's two raw edges are sewn together onto one neckline; its second
    edge would otherwise find the armholes, as long and meeting at the side seam as the
    neckline's halves do at the shoulder."""
    rows: list[tuple[int, ...]] = []
    if not groups:
        return np.zeros((0, 4), dtype=int)
    halves = [g[:2] for g in groups[0].tolist() if band[g[0]] and band[g[1]]]
    piece = [min((runs[i] for i in pairs[h[0]]), key=lambda r: r.length).piece for h in halves]
    for i, (x1, y1) in enumerate(halves):
        for j in range(i + 1, len(halves)):
            if piece[i] == piece[j] and not {x1, y1} & set(halves[j]):
                rows.append((x1, y1, *halves[j]))
    return np.array(rows, dtype=int).reshape(-1, 4)


def _program(a: np.ndarray, weight: np.ndarray, conflicts: list[np.ndarray],
             groups: list[np.ndarray], couple: np.ndarray, twins: TwinRows
             ) -> np.ndarray | None:
    """Solve: maximise the chosen candidates' weights plus :data:`MEETING_MM` per meeting
    all chosen (one variable per meeting, at most each of its members; ``groups``: (m,k)
    arrays of members), less :data:`PAIR_COST_MM` per two pieces sewn (one variable per
    ``couple`` index, at least each of its candidates), each edge sewn at most once (``a``:
    edges x candidates), never all k of a row of ``conflicts`` ((r,k) arrays), plus the
    ``twins``' rewards (:mod:`solver.seams.sides`)."""
    n = len(weight)
    member = np.concatenate([g.reshape(-1) for g in groups]) if groups else np.zeros(0, int)
    meeting = np.concatenate([np.repeat(np.arange(len(g)), g.shape[1]) + sum(
        len(h) for h in groups[:i]) for i, g in enumerate(groups)]) if groups else member
    m = sum(len(g) for g in groups)
    sewn = np.flatnonzero(couple >= 0)
    q = int(couple.max()) + 1 if len(sewn) else 0
    width = n + m + q + twins.n_twins
    c = np.zeros((sum(len(x) for x in conflicts), width))
    bound = np.concatenate([np.full(len(x), x.shape[1] - 1.0) for x in conflicts])
    rows = np.concatenate([np.repeat(np.arange(len(x)), x.shape[1]) + sum(
        len(y) for y in conflicts[:i]) for i, x in enumerate(conflicts)])
    c[rows, np.concatenate([x.reshape(-1) for x in conflicts])] = 1.0
    t = np.zeros((len(member) + len(sewn), width))  # meeting - member <= 0, and
    rows = np.arange(len(member))  # candidate - its pieces' pair <= 0
    t[rows, member] = -1.0
    t[rows, n + meeting] = 1.0
    rows = len(member) + np.arange(len(sewn))
    t[rows, sewn] = 1.0
    t[rows, n + m + couple[sewn]] = -1.0
    edges = np.hstack([a, np.zeros((len(a), width - n))])
    twin = np.hstack([twins.on_candidates, np.zeros((len(twins.upper), m + q)),
                      twins.on_twins])
    cost = [weight, np.full(m, MEETING_MM), np.full(q, -PAIR_COST_MM), twins.reward]
    res = milp(-np.concatenate(cost), integrality=np.ones(width), bounds=Bounds(0, 1),
               constraints=[LinearConstraint(edges, 0, 1), LinearConstraint(c, 0, bound),
                            LinearConstraint(t, -1, 0),
                            LinearConstraint(twin, -np.inf, twins.upper)],
               options={"time_limit": 20.0})
    return res.x


def _tube_pairs(runs: list[Run], lengths: list[float]) -> np.ndarray:
    """(k,2) runs of one piece that could be its two sides sewn into a tube (a sleeve's
    underarm): corner to corner each, apart, of one length and straightness."""
    whole = [k for k, r in enumerate(runs) if r.whole]
    out = [(i, j) for x, i in enumerate(whole) for j in whole[x + 1:]
           if runs[i].piece == runs[j].piece
           and _disjoint(runs[i], runs[j], lengths[runs[i].piece])
           and abs(runs[i].length - runs[j].length) <= LENGTH_TOL * runs[i].length
           and min(runs[i].straightness, runs[j].straightness) >= 0.98]
    return np.array(out, dtype=int).reshape(-1, 2)


def _tube_score(a: Run, b: Run) -> float:
    """A tube's two sides scored by their lengths and notches alone (the piece folds onto
    itself: overlap says nothing)."""
    notch = _notch_score(a, b)
    return _length_score(a, b)[0] + (NOTCH_W * notch if notch >= 0 else 1.5 * notch)


def _rival(k: int, pairs: np.ndarray, scores: np.ndarray, a: np.ndarray) -> float:
    """The best score of another candidate sharing an edge with candidate ``k`` and sewing
    an edge ``k`` does not (a part of the same seam is no other partner)."""
    shares = ((a[:, k:k + 1] * a).sum(0) > 0) & ~(a <= a[:, k:k + 1]).all(0)
    shares[k] = False
    return float(scores[shares].max()) if shares.any() else 0.0


def _seams(a: Run, b: Run, score: float, rival: float) -> list[Seam]:
    """A chosen candidate as seams: one, or one between each two darts either side skips
    (a seam is a stretch of line on each piece); confidence from its score and its margin
    over the best rival for the same edges (a near tie between two partners is unsure)."""
    margin = max(score - rival, 0.0)
    confidence = round(float(np.clip(score / 2.0, 0, 1) * np.clip(0.5 + margin, 0, 1)), 3)
    notches = _matched_notches(a, b)
    shares = sorted({0.0, 1.0, *(u / a.length for u in a.skip_offsets()),
                     *(1.0 - u / b.length for u in b.skip_offsets())})
    out = []
    for t0, t1 in zip(shares[:-1], shares[1:], strict=True):
        if t1 - t0 < 1e-9:
            continue
        out.append(Seam(a.piece, a.arc_at(t0 * a.length, after=True),
                        a.arc_at(t1 * a.length, after=False),
                        b.piece, b.arc_at((1 - t1) * b.length, after=True),
                        b.arc_at((1 - t0) * b.length, after=False),
                        0.5 * (t1 - t0) * (a.length + b.length), confidence,
                        matched=tuple((a.arc_at(u * a.length, after=True),
                                       b.arc_at((1 - v) * b.length, after=True))
                                      for u, v in notches if t0 < u < t1 and t0 < v < t1)))
    return out


def _matched_notches(a: Run, b: Run) -> list[tuple[float, float]]:
    """(share of a, share of b read backwards) of each notch inside the seam matched on
    both sides: a sewer pins them together, so the seam's points between follow them."""
    if a.piece == b.piece or not a.notches or _notch_score(a, b) < 0:
        return []
    return list(zip((s for s, _ in a.notches), sorted(1.0 - s for s, _ in b.notches),
                    strict=True))
