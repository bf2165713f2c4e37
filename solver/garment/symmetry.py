"""Mirror pairs: left and right pieces of a garment, and the seams on its centre line.

Cutting rooms cut "a pair": one pattern piece, once as drawn and once flipped. Patterns
drawn by hand or relaxed by a cloth simulator are only nearly congruent (the Berkeley
pairs differ by 1-6 mm RMS), so two pieces form a pair when, after the best rigid fit of
one piece's mirror image onto the other, their outlines lie within ``tolerance`` of the
piece's size (its bounding-box diagonal) in RMS closest-point distance, *and* their seams
correspond: every seam span of one lands on a seam span of the other that is sewn to the
mirror partner of the same piece. A seam line joining the two pieces of a pair is a
centre seam (centre front or centre back).

The fit is correspondence-free: both outlines are resampled by arc length, every cyclic
start is scored at once (a vectorised 2D Procrustes), and the best start is refined by a
few closest-point (ICP) steps.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from solver.garment.model import Garment
from solver.geometry import FLIP, closest_on_polygon, resample_closed, rotation_matrix
from solver.jsonfile import read_json

#: Outline RMS distance, as a fraction of the piece's bounding-box diagonal, below which
#: two pieces count as mirror images.
MIRROR_TOLERANCE = 0.01
#: Fraction of the outline's length whose seam labels must correspond.
SEAM_AGREEMENT = 0.85
#: RMS distance, as a fraction of the piece's size, between a centre seam's edges mapped
#: by the mirror and their twins.
CENTRE_TOLERANCE = 0.03
_SAMPLES = 256
_ICP_STEPS = 4
#: Largest vertex gap, as a fraction of the piece's size, at which a second piece counts
#: as an exact mirrored copy of the first's mesh (a symmetrised pair, also after a file
#: round trip that rounds coordinates).
COPY_TOLERANCE = 1e-6

@dataclass(frozen=True)
class MirrorPair:
    """Piece ``second`` is the mirror image of piece ``first``.

    ``rotation`` (2,2) and ``translation`` (2,) map the mirrored first piece onto the
    second in pattern space: ``p_second = rotation @ FLIP @ p_first + translation``.
    """

    first: int
    second: int
    rms_mm: float
    size_mm: float
    rotation: np.ndarray
    translation: np.ndarray
    declared: bool = False

    @property
    def relative_rms(self) -> float:
        return self.rms_mm / self.size_mm

    def map_first_to_second(self, points: np.ndarray) -> np.ndarray:
        """(n,2) points of the first piece -> their mirror images on the second piece."""
        return (np.asarray(points, float) @ FLIP.T) @ self.rotation.T + self.translation

    def turned(self) -> MirrorPair:
        """The same pair read the other way: ``p_first = R FLIP p_second - R FLIP t``."""
        return MirrorPair(self.second, self.first, self.rms_mm, self.size_mm, self.rotation,
                          -self.rotation @ FLIP @ self.translation, self.declared)

    def to_dict(self) -> dict:
        return {"pieces": [self.first, self.second], "rms_mm": round(self.rms_mm, 3),
                "size_mm": round(self.size_mm, 3), "declared": self.declared}


def mirror_pairs(garment: Garment, *, tolerance: float = MIRROR_TOLERANCE,
                 declared: Iterable[Sequence[int]] = (),
                 vetoed: Iterable[Sequence[int]] = ()) -> list[MirrorPair]:
    """Left/right pairs of ``garment``, best fits first claimed (each piece in one pair).

    ``declared`` pairs are taken as they are (the fit is still computed so that later
    steps can map one piece onto the other); ``vetoed`` pairs are never formed.
    """
    n = garment.n_pieces
    declared = [_ordered(p, n) for p in declared]
    vetoed_set = {_ordered(p, n) for p in vetoed}
    out = fit_pairs(garment, declared)
    taken = {k for p in out for k in (p.first, p.second)}
    for pair in _candidates(garment, taken, vetoed_set, tolerance):
        if pair.first in taken or pair.second in taken:
            continue
        out.append(pair)
        taken.update((pair.first, pair.second))
    return _with_corresponding_seams(garment, out)


def _candidates(garment: Garment, taken: set[int], vetoed: set[tuple[int, int]],
                tolerance: float) -> list[MirrorPair]:
    """Every pair of pieces not ``taken`` nor ``vetoed`` whose mirrored outlines fit within
    ``tolerance``, best fit first."""
    n = garment.n_pieces
    outlines = [garment.piece_outline(i) for i in range(n)]
    area = np.abs(garment.piece_areas())
    candidates: list[MirrorPair] = []
    for i in range(n):
        for j in range(i + 1, n):
            if {i, j} & taken or (i, j) in vetoed:
                continue
            if abs(area[i] - area[j]) > 4 * tolerance * max(area[i], area[j]):
                continue  # area differs more than a 1 % outline offset allows
            size = max(_size(outlines[i]), _size(outlines[j]))
            rot, t, rms = _exact_or(garment, i, j, *_mirror_fit(outlines[i], outlines[j]))
            if rms <= tolerance * size:
                candidates.append(MirrorPair(i, j, rms, size, rot, t))
    return sorted(candidates, key=lambda p: p.relative_rms)


def _with_corresponding_seams(garment: Garment, pairs: list[MirrorPair]) -> list[MirrorPair]:
    """Seams must correspond under the pairing itself: the worst pair is dropped until
    they do (a skirt's front and back are congruent, but sewn to different pieces than a
    pair is). Declared pairs stay."""
    labels = _seam_partner_per_boundary_edge(garment)
    out = list(pairs)
    while True:
        sigma = _partner_map(out, garment.n_pieces)
        score = [1.0 if p.declared else _seams_correspond(garment, p, labels, sigma)
                 for p in out]
        worst = int(np.argmin(score)) if out else -1
        if worst < 0 or score[worst] >= SEAM_AGREEMENT:
            return out
        del out[worst]


def fit_pairs(garment: Garment, pairs: Iterable[Sequence[int]]) -> list[MirrorPair]:
    """The mirror fits of pairs given by the operator or recorded in a placement, taken as
    pairs whatever their fit (``declared``)."""
    n = garment.n_pieces
    out: list[MirrorPair] = []
    taken: set[int] = set()
    for i, j in (_ordered(p, n) for p in pairs):
        if i in taken or j in taken:
            raise ValueError(f"piece {i if i in taken else j} is in two mirror pairs")
        first, second = garment.piece_outline(i), garment.piece_outline(j)
        rot, t, rms = _exact_or(garment, i, j, *_mirror_fit(first, second))
        out.append(MirrorPair(i, j, rms, _size(first), rot, t, declared=True))
        taken.update((i, j))
    return out


def centre_seams(garment: Garment, pairs: Sequence[MirrorPair]) -> list[int]:
    """Seam lines on the garment's centre line: they join the two halves of a mirror pair
    and the mirror map takes each of their edges onto its own twin (the seam lies on the
    axis of symmetry), which a seam joining the halves elsewhere would not."""
    by_pieces = {frozenset((p.first, p.second)): p for p in pairs}
    g = garment
    out = []
    for k, line in enumerate(g.seam_lines):
        pair = by_pieces.get(frozenset((line.piece_a, line.piece_b)))
        if pair is None or line.piece_a == line.piece_b:
            continue
        edges = g.seam_edges[g.seam_line_of_edge == k]
        on_first = g.piece_of_vertex[edges[:, 0]] == pair.first
        here = np.where(on_first[:, None], edges[:, :2], edges[:, 2:])
        there = np.where(on_first[:, None], edges[:, 2:], edges[:, :2])
        moved = pair.map_first_to_second(g.uv[here.ravel()])
        gap = np.linalg.norm(moved - g.uv[there.ravel()], axis=1)
        if np.sqrt(np.mean(gap ** 2)) <= CENTRE_TOLERANCE * pair.size_mm:
            out.append(k)
    return out


def fold_pairs(garment: Garment) -> list[MirrorPair]:
    """Each piece cut on the fold (:attr:`Garment.folds`) as a pair with itself: the mirror
    across its fold line takes the piece onto itself, as a centre seam takes one half of
    a pair onto the other, so alignment keeps both with one rule. ``rms_mm`` measures how
    far the outline is from its own mirror image."""
    out = []
    for i, line in sorted(garment.folds.items()):
        a, b = np.asarray(line, float)
        d = (b - a) / np.linalg.norm(b - a)
        reflection = 2.0 * np.outer(d, d) - np.eye(2)
        outline = resample_closed(garment.piece_outline(i), _SAMPLES)
        gap, _ = cKDTree(outline).query((outline - a) @ reflection.T + a)
        out.append(MirrorPair(i, i, float(np.sqrt(np.mean(gap ** 2))), _size(outline),
                              reflection @ FLIP, a - reflection @ a, declared=True))
    return out


def mirror_correspondence(garment: Garment, pair: MirrorPair) -> np.ndarray | None:
    """For a pair whose second piece is a mirrored copy of the first's mesh (as
    `solver.garment.symmetrise` makes it): the first piece's vertex (global index) whose
    image each second-piece vertex is, in ``flatnonzero`` order; None for any other pair.

    The copy is recognised by its vertices, not trusted from a flag: a file round trip or
    a midpoint subdivision keeps it, and a pair that merely looks alike is refused.
    """
    first = np.flatnonzero(garment.piece_of_vertex == pair.first)
    second = np.flatnonzero(garment.piece_of_vertex == pair.second)
    if len(first) != len(second) or len(first) == 0:
        return None
    moved = pair.map_first_to_second(garment.uv[first])
    gap, near = cKDTree(moved).query(garment.uv[second])
    if gap.max() > COPY_TOLERANCE * pair.size_mm or len(np.unique(near)) != len(near):
        return None
    return first[near]


def mirrored_edges(garment: Garment, pair: MirrorPair) -> np.ndarray:
    """(k,4) rows ``[a, b, c, d]``: each boundary edge a->b of the pair's first piece (as in
    its face, holes included) and the second piece's boundary edge c->d at its mirror
    image, c the image of a (mirroring reverses the outline, so d->c runs as in its face).

    This is how the two halves of a pair are read as one pattern edge by edge: whatever
    is decided per edge (allowance, notches) is decided once for both. The match is the
    nearest edge midpoint under the pair's mirror: exact for a mirrored copy (a
    symmetrised pair), the nearest edge for halves meshed apart.
    """
    g = garment
    bhe = g.boundary_half_edges()
    mine = bhe[g.piece_of_vertex[bhe[:, 0]] == pair.first]
    theirs = bhe[g.piece_of_vertex[bhe[:, 0]] == pair.second]
    if len(mine) == 0 or len(theirs) == 0:
        return np.zeros((0, 4), np.int64)
    moved = pair.map_first_to_second(g.uv[mine].reshape(-1, 2)).reshape(-1, 2, 2)
    _, k = cKDTree(g.uv[theirs].mean(axis=1)).query(moved.mean(axis=1))
    c, d = theirs[k, 1], theirs[k, 0]  # the image of a->b runs d->c in its face
    swap = (np.linalg.norm(g.uv[c] - moved[:, 0], axis=1)
            > np.linalg.norm(g.uv[d] - moved[:, 0], axis=1))
    return np.column_stack([mine, np.where(swap, d, c), np.where(swap, c, d)])


def mirror_gap(pair: MirrorPair, a: np.ndarray, b: np.ndarray) -> float:
    """Largest distance (mm) between the closed polygon ``a`` (on the first piece) mapped
    by the pair's mirror and the closed polygon ``b`` (on the second), both ways: 0 when
    the two are exact mirror images, as a pair's outlines and cut lines must be."""
    moved = pair.map_first_to_second(np.asarray(a, float))
    b = np.asarray(b, float)
    return float(max(np.linalg.norm(closest_on_polygon(moved, b) - moved, axis=1).max(),
                     np.linalg.norm(closest_on_polygon(b, moved[::-1]) - b, axis=1).max()))


def cut_mismatch(pair: MirrorPair, cuts: Sequence, notches: Sequence) -> tuple[float, float]:
    """How far a pair's cut is from mirroring (mm): the :func:`mirror_gap` of the two cut
    lines, and the largest distance from a notch (``at``, on the cut line) of either piece
    to the nearest mirrored notch of the other (inf when their numbers differ).

    ``cuts`` and ``notches`` are per piece, as `solver.garment.notches.cut_ready` gives
    them; a cutting room checks a pair this way, one piece laid flipped on the other.
    """
    cut = mirror_gap(pair, cuts[pair.first].outline, cuts[pair.second].outline)
    a = np.array([n.at for n in notches[pair.first]], float).reshape(-1, 2)
    b = np.array([n.at for n in notches[pair.second]], float).reshape(-1, 2)
    if len(a) != len(b):
        return cut, float("inf")
    if len(a) == 0:
        return cut, 0.0
    d = np.linalg.norm(pair.map_first_to_second(a)[:, None] - b[None], axis=2)
    return cut, float(max(d.min(axis=1).max(), d.min(axis=0).max()))


def _exact_or(g: Garment, i: int, j: int, rot: np.ndarray, t: np.ndarray, rms: float
              ) -> tuple[np.ndarray, np.ndarray, float]:
    """The outline fit, replaced by the exact map when piece j is a mirrored copy of piece
    i's mesh: the outline fit is only as good as its resampling (~1e-3 of the size), and a
    symmetrised pair must map vertex onto vertex."""
    first = np.flatnonzero(g.piece_of_vertex == i)
    second = np.flatnonzero(g.piece_of_vertex == j)
    if len(first) != len(second) or rms > MIRROR_TOLERANCE * _size(g.piece_outline(i)):
        return rot, t, rms
    a = g.uv[first] @ FLIP.T
    _, near = cKDTree(a @ rot.T + t).query(g.uv[second])
    if len(np.unique(near)) != len(near):
        return rot, t, rms
    rot2, t2 = _procrustes(a[near], g.uv[second])
    gap = np.linalg.norm(a[near] @ rot2.T + t2 - g.uv[second], axis=1)
    if gap.max() > COPY_TOLERANCE * _size(g.piece_outline(i)):
        return rot, t, rms
    return rot2, t2, float(np.sqrt(np.mean(gap ** 2)))


# ---------------------------------------------------------------------- fitting


def _ordered(pair: Sequence[int], n: int) -> tuple[int, int]:
    if len(pair) != 2:
        raise ValueError(f"a mirror pair names two pieces, got {list(pair)}")
    i, j = (int(x) for x in pair)
    if not (0 <= i < n and 0 <= j < n) or i == j:
        raise ValueError(f"mirror pair {[i, j]} must name two different pieces of 0..{n - 1}")
    return (min(i, j), max(i, j))


def _size(outline: np.ndarray) -> float:
    span = outline.max(axis=0) - outline.min(axis=0)
    return float(np.hypot(*span))


def _procrustes(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation and translation taking rows of ``a`` closest to rows of ``b``."""
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    h = (a - ca).T @ (b - cb)
    ang = np.arctan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1])
    rot = rotation_matrix(ang)
    return rot, cb - rot @ ca


def mirror_misfit(first: np.ndarray, second: np.ndarray) -> float:
    """RMS distance of the ``first`` outline's mirror image, best fitted, from ``second``, as
    a share of the larger one's size (bounding-box diagonal)."""
    return _mirror_fit(first, second)[2] / max(_size(first), _size(second))


def _mirror_fit(first: np.ndarray, second: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Best rigid map of the mirrored ``first`` outline onto ``second``: (R, t, RMS mm)."""
    a = resample_closed(first @ FLIP.T, _SAMPLES)[::-1]  # mirroring reverses the orientation
    b = resample_closed(second, _SAMPLES)
    n = len(a)
    shifted = b[(np.arange(n)[:, None] + np.arange(n)[None, :]) % n]  # every cyclic start
    a0 = a - a.mean(axis=0)
    b0 = shifted - shifted.mean(axis=1, keepdims=True)
    h = np.einsum("ni,snj->sij", a0, b0)
    ssd = (a0 ** 2).sum() + (b0 ** 2).sum(axis=(1, 2)) - 2 * np.hypot(
        h[:, 0, 0] + h[:, 1, 1], h[:, 0, 1] - h[:, 1, 0])
    rot, t = _procrustes(a, shifted[int(np.argmin(ssd))])
    for _ in range(_ICP_STEPS):
        moved = a @ rot.T + t
        rot, t = _procrustes(a, closest_on_polygon(moved, second))
    moved = a @ rot.T + t
    there = np.linalg.norm(moved - closest_on_polygon(moved, second), axis=1)
    back = resample_closed(second, _SAMPLES)
    back_dist = np.linalg.norm(back - closest_on_polygon(back, moved[::-1]), axis=1)
    rms = float(np.sqrt(0.5 * (np.mean(there ** 2) + np.mean(back_dist ** 2))))
    return rot, t, rms


# ---------------------------------------------------------------------- seam structure


def _seam_partner_per_boundary_edge(g: Garment) -> dict[tuple[int, int], int]:
    """Boundary edge (a, b) -> the piece it is sewn to (-1 for an open edge)."""
    out: dict[tuple[int, int], int] = {}
    pv = g.piece_of_vertex
    for a, b, a2, b2 in g.seam_edges.tolist():
        out[(a, b)] = out[(b, a)] = int(pv[a2])
        out[(a2, b2)] = out[(b2, a2)] = int(pv[a])
    return out


def _partner_map(pairs: Sequence[MirrorPair], n: int) -> np.ndarray:
    sigma = np.arange(n)
    for p in pairs:
        sigma[p.first], sigma[p.second] = p.second, p.first
    return sigma


def _edge_labels(g: Garment, piece: int, labels: dict[tuple[int, int], int]
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Outline segments of ``piece`` (start, end) and the piece each is sewn to (-1: open)."""
    loop = g.piece_loops(piece)[0]
    nxt = np.roll(loop, -1)
    lab = np.array([labels.get((a, b), -1)
                    for a, b in zip(loop.tolist(), nxt.tolist())], dtype=np.int64)
    return g.uv[loop], g.uv[nxt], lab


def _seams_correspond(g: Garment, pair: MirrorPair, labels: dict[tuple[int, int], int],
                      sigma: np.ndarray) -> float:
    """Length fraction of the first piece's outline whose label matches on the second.

    A span sewn to piece k must land on a span sewn to sigma(k) (k's mirror partner, or k
    itself when unpaired) or, when k is unpaired, on one sewn to another unpaired piece (a
    partner pair that is not congruent enough to be found); open spans land on open spans.
    """
    a0, a1, lab_a = _edge_labels(g, pair.first, labels)
    b0, b1, lab_b = _edge_labels(g, pair.second, labels)
    mid = pair.map_first_to_second(0.5 * (a0 + a1))
    seg = b1 - b0
    rel = mid[:, None, :] - b0[None]
    t = np.clip(np.einsum("nkj,kj->nk", rel, seg) / np.maximum((seg * seg).sum(1), 1e-300), 0, 1)
    dist = ((rel - t[..., None] * seg[None]) ** 2).sum(-1)
    landed = lab_b[np.argmin(dist, axis=1)]
    expected = np.where(lab_a >= 0, sigma[np.maximum(lab_a, 0)], -1)
    unpaired = np.append(sigma == np.arange(len(sigma)), False)  # index -1: open edge
    both_unpaired = (lab_a >= 0) & (landed >= 0) & unpaired[lab_a] & unpaired[landed]
    length = np.linalg.norm(a1 - a0, axis=1)
    agree = (landed == expected) | both_unpaired
    return float(length[agree].sum() / max(length.sum(), 1e-300))


# ---------------------------------------------------------------------- operator's pairs


def read_pairs_file(path, garment: Garment) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """Declared and vetoed pairs from P.json: ``{"pairs": [[i, j], ...], "not_pairs": [...]}``.

    Pieces are named by index or by name (as `station inspect` lists them). Errors name the
    file, in one line.
    """
    return pairs_from_dict(read_json(path), garment, str(path))


def pairs_from_dict(data, garment: Garment, where: str
                    ) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """Declared and vetoed pairs from ``{"pairs": [...], "not_pairs": [...]}`` (a P.json's
    content or a job option); ``where`` names the source in the one-line errors."""
    if not isinstance(data, dict) or not set(data) <= {"pairs", "not_pairs"}:
        raise ValueError(f'{where}: expected {{"pairs": [[i, j], ...], "not_pairs": [...]}}')
    names = {name: i for i, name in enumerate(garment.piece_names)}

    def piece(value) -> int:
        if isinstance(value, str) and value in names:
            return names[value]
        if isinstance(value, int) and not isinstance(value, bool) \
                and 0 <= value < garment.n_pieces:
            return value
        raise ValueError(f"{where}: no piece {value!r} (pieces 0..{garment.n_pieces - 1} "
                         "or their names)")

    def pairs(key: str) -> list[tuple[int, int]]:
        value = data.get(key, [])
        if not isinstance(value, list) or not all(
                isinstance(p, list) and len(p) == 2 for p in value):
            raise ValueError(f"{where}: {key!r} must be a list of [piece, piece] pairs")
        out = [(piece(a), piece(b)) for a, b in value]
        for a, b in out:
            if a == b:
                raise ValueError(f"{where}: pair {[a, b]} names one piece twice")
        return out

    return pairs("pairs"), pairs("not_pairs")
