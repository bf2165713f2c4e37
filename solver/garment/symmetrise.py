"""``--symmetrise``: a near mirror pair replaced by one pattern cut twice, the average of the two.

Pattern makers true up a left and a right piece that came out slightly different (drawn
by hand, relaxed by a simulator) into one piece cut once as drawn and once flipped. Here:

* the first piece's outline moves halfway towards the second's mirror image (closest
  points, the pair's mirror fit from `solver.garment.symmetry`), its interior following
  harmonically so no triangle flips;
* the second piece becomes the mirror image of that averaged mesh, vertex for vertex
  (triangles re-oriented), so every later step sees one pattern: alignment, reshaping
  (a permutation ties the halves), allowances and notches;
* the seams of the second piece are re-derived on the new mesh: each of its old seam edges
  is matched to the edge of the first piece that lies at its mirror image, so a seam to
  another symmetrised piece (or across the centre line) is the exact mirror of the first
  piece's seam, and a seam to an unpaired piece is re-sewn edge for edge;
* the second piece's drape is read off its old drape at the same places, and twin
  vertices share one 3D point;
* the pattern's own curves (a specification's Beziers and arcs) go with the first piece's
  edges and, mirrored, to the second's, so both are still cut on the curves.

A pair whose seams do not correspond edge for edge (different sampling along a seam) is
left as it is and reported, never forced.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.optimize import linear_sum_assignment
from scipy.sparse.linalg import spsolve
from scipy.spatial import cKDTree

from solver.garment.barycentric import barycentric_matrix
from solver.garment.mesh import connected_components
from solver.garment.model import Garment, build_garment
from solver.garment.symmetry import (
    FLIP,
    MirrorPair,
    fit_pairs,
    mirror_correspondence,
)
from solver.geometry import closest_on_polygon, signed_areas

_KEPT, _FIRST, _SECOND = 0, 1, 2
CUT_KEPT_MM = 0.5  # a file's cut line still holds its sew line moved this little


@dataclass(frozen=True)
class PieceMove:
    """How far symmetrising moved one piece's outline (mm) and changed its area (%)."""

    piece: int
    max_mm: float
    rms_mm: float
    area_change_pct: float

    def to_dict(self) -> dict:
        return {"piece": self.piece, "max_mm": round(self.max_mm, 3),
                "rms_mm": round(self.rms_mm, 3),
                "area_change_pct": round(self.area_change_pct, 3)}


@dataclass
class Symmetrised:
    """The symmetrised garment, its exact pairs, the moves and the pairs left alone."""

    garment: Garment
    pairs: list[MirrorPair]
    moves: list[PieceMove] = field(default_factory=list)
    skipped: list[tuple[int, int, str]] = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"pairs": [[p.first, p.second] for p in self.pairs],
                "moves": [m.to_dict() for m in self.moves],
                "skipped": [[i, j, why] for i, j, why in self.skipped]}

    def lines(self) -> list[str]:
        """One console line per symmetrised piece and per pair left alone."""
        out = [f"piece {m.piece} moved {m.max_mm:.2f} mm at most, {m.rms_mm:.2f} mm RMS, "
               f"area {m.area_change_pct:+.2f} %" for m in self.moves]
        out += [f"pair {i}~{j} not symmetrised: {why}" for i, j, why in self.skipped]
        return out


def symmetrise(garment: Garment, pairs: Sequence[MirrorPair]) -> Symmetrised:
    """Copy of ``garment`` in which each pair's second piece is the mirrored first piece,
    both the average of the two; pairs whose seams cannot be re-derived are skipped."""
    todo = _one_side_first(garment, [p for p in pairs
                                     if mirror_correspondence(garment, p) is None])
    done = [p for p in pairs if mirror_correspondence(garment, p) is not None]
    skipped: list[tuple[int, int, str]] = []
    averaged: dict[int, np.ndarray] = {}
    for p in list(todo):
        try:
            averaged[p.first] = _averaged_first(garment, p)
        except _Skip as why:
            skipped.append((p.first, p.second, str(why)))
            todo.remove(p)
    while todo:
        try:
            out = _rebuilt(garment, todo, averaged)
        except _Skip as why:
            reason, bad = why.args
            todo = [p for p in todo if p is not bad]
            skipped.append((bad.first, bad.second, reason))
            continue
        given = {frozenset((p.first, p.second)): p for p in pairs}  # as the caller reads them
        exact = [MirrorPair(q.first, q.second, 0.0, q.size_mm, q.rotation, q.translation,
                            declared=True)
                 for q in (given[frozenset((p.first, p.second))] for p in todo)]
        moves = _moves(garment, out, todo)
        out.cut_outlines = _carried_cut_lines(garment, todo, moves)
        return Symmetrised(out, sorted(done + exact, key=lambda p: p.first), moves,
                           _sorted(skipped))
    return Symmetrised(garment.copy(), done, [], _sorted(skipped))


def _sorted(skipped: list[tuple[int, int, str]]) -> list[tuple[int, int, str]]:
    return sorted((min(i, j), max(i, j), why) for i, j, why in skipped)


def symmetrise_as_recorded(garment: Garment, record) -> Symmetrised:
    """The pattern a placement was made on: ``record`` is its report's ``"symmetrise"``
    entry (`Symmetrised.to_dict`), whose pairs are symmetrised again (deterministic)."""
    pairs = record.get("pairs") if isinstance(record, dict) else None
    if not isinstance(pairs, list) or not all(
            isinstance(p, list) and len(p) == 2 and all(
                isinstance(k, int) and not isinstance(k, bool) for k in p) for p in pairs):
        raise ValueError('the "symmetrise" record must hold "pairs": [[i, j], ...] (piece '
                         "indices)")
    return symmetrise(garment, fit_pairs(garment, pairs))


def _one_side_first(g: Garment, pairs: list[MirrorPair]) -> list[MirrorPair]:
    """The pairs turned so that their first pieces lie on one side of the body.

    A seam between two pairs then joins two first pieces (and, mirrored, two second ones),
    and the first pieces' seams are what the second pieces are re-sewn from: a sleeve sewn
    to a front of the other half would need both halves' samplings of one seam to agree.
    The sides are found by walking the seams between pairs (a two-colouring).
    """
    pairs = sorted(pairs, key=lambda p: min(p.first, p.second))
    index = {k: n for n, p in enumerate(pairs) for k in (p.first, p.second)}
    side = {k: int(k == p.second) for p in pairs for k in (p.first, p.second)}
    links: dict[int, list[tuple[int, int]]] = {n: [] for n in range(len(pairs))}
    for line in g.seam_lines:
        a, b = line.piece_a, line.piece_b
        if a in index and b in index and index[a] != index[b]:
            parity = side[a] ^ side[b]  # 1: joins a first piece to a second one
            links[index[a]].append((index[b], parity))
            links[index[b]].append((index[a], parity))
    flip: dict[int, int] = {}
    for start in range(len(pairs)):
        if start in flip:
            continue
        # each group of linked pairs: its lowest-numbered piece first (whatever the order or
        # the way round the pairs were given in), so the result is the same every time
        flip[start] = int(pairs[start].first > pairs[start].second)
        stack = [start]
        while stack:
            n = stack.pop()
            for m, parity in links[n]:
                if m not in flip:
                    flip[m] = flip[n] ^ parity
                    stack.append(m)
    return [p.turned() if flip[n] else p for n, p in enumerate(pairs)]


class _Skip(Exception):
    """A pair that cannot be symmetrised: (reason, pair)."""


# ---------------------------------------------------------------------- the average


def _local_faces(g: Garment, piece: int) -> tuple[np.ndarray, np.ndarray]:
    """The piece's vertices (global indices) and its faces in their local numbering."""
    verts = np.flatnonzero(g.piece_of_vertex == piece)
    local = np.full(g.n_vertices, -1)
    local[verts] = np.arange(len(verts))
    return verts, local[g.faces[g.piece_of_face() == piece]]


def _inverse_map(p: MirrorPair, points: np.ndarray) -> np.ndarray:
    """Second-piece points -> the first piece's frame (M^-1 q)."""
    return (np.asarray(points, float) - p.translation) @ p.rotation @ FLIP


def _averaged_first(g: Garment, p: MirrorPair) -> np.ndarray:
    """(n_i,2) the first piece's vertices moved halfway to the second's mirror image."""
    verts, faces = _local_faces(g, p.first)
    local = np.full(g.n_vertices, -1)
    local[verts] = np.arange(len(verts))
    boundary = np.concatenate(g.piece_loops(p.first))
    pts = g.uv[boundary]
    best = np.full(len(pts), np.inf)
    target = pts.copy()
    for loop in g.piece_loops(p.second):
        q = closest_on_polygon(pts, _inverse_map(p, g.uv[loop]))
        d = np.linalg.norm(q - pts, axis=1)
        closer = d < best
        best[closer], target[closer] = d[closer], q[closer]
    disp = _harmonic(len(verts), faces, local[boundary], target - pts)
    new = g.uv[verts] + 0.5 * disp
    if (signed_areas(new, faces) <= 0).any():
        raise _Skip("averaging the outlines would fold a triangle")
    return new


def _harmonic(n: int, faces: np.ndarray, fixed: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(n,2) field equal to ``values`` at ``fixed`` vertices, harmonic (graph Laplacian)
    inside: the interior follows the outline smoothly."""
    out = np.zeros((n, 2))
    out[fixed] = values
    free = np.setdiff1d(np.arange(n), fixed)
    if len(free) == 0:
        return out
    e = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    adj = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    adj = ((adj + adj.T) > 0).astype(float)
    lap = sp.diags(np.asarray(adj.sum(axis=1)).ravel()) - adj
    lap = lap.tocsr()
    rhs = -(lap[free][:, fixed] @ out[fixed])
    out[free] = np.asarray(spsolve(lap[free][:, free].tocsc(), rhs)).reshape(-1, 2)
    return out


# ---------------------------------------------------------------------- the new garment


def _rebuilt(g: Garment, pairs: Sequence[MirrorPair], averaged: dict[int, np.ndarray]
             ) -> Garment:
    """The garment with each pair's second piece replaced by the mirrored averaged first."""
    n_pieces = g.n_pieces
    role = np.full(n_pieces, _KEPT)
    pair_of = {}
    for p in pairs:
        role[p.first], role[p.second] = _FIRST, _SECOND
        pair_of[p.first] = pair_of[p.second] = p
    new_index = np.full(g.n_vertices, -1)  # old vertex of a kept/first piece -> new
    mirror_index = np.full(g.n_vertices, -1)  # old vertex of a first piece -> its copy
    uv_parts, face_parts, xyz_parts = [], [], []
    span: dict[int, tuple[int, int]] = {}  # piece -> its new vertex range
    offset = 0
    for k in range(n_pieces):
        if role[k] == _SECOND:
            p = pair_of[k]
            verts, faces = _local_faces(g, p.first)
            uv_k = p.map_first_to_second(averaged[p.first])
            mirror_index[verts] = offset + np.arange(len(verts))
            faces = faces[:, [0, 2, 1]]  # mirroring reverses the orientation
            xyz_k = None if g.xyz is None else _drape_at(g, p, uv_k)
        else:
            verts, faces = _local_faces(g, k)
            uv_k = averaged[k] if role[k] == _FIRST else g.uv[verts]
            new_index[verts] = offset + np.arange(len(verts))
            xyz_k = None if g.xyz is None else g.xyz[verts]
        uv_parts.append(uv_k)
        face_parts.append(faces + offset)
        xyz_parts.append(xyz_k)
        span[k] = (offset, offset + len(verts))
        offset += len(verts)
    uv = np.concatenate(uv_parts)
    faces = np.concatenate(face_parts)
    twins = _new_twins(g, pairs, role, new_index, mirror_index)
    _check_seams(pairs, twins, span, offset)
    _, point = connected_components(offset, np.concatenate([twins[:, [0, 2]], twins[:, [1, 3]]]))
    xyz = None
    if g.xyz is not None:
        xyz = np.concatenate(xyz_parts)
        count = np.bincount(point, minlength=point.max() + 1)[:, None]
        shared = np.zeros((point.max() + 1, 3))
        np.add.at(shared, point, xyz)
        xyz = (shared / count)[point]  # twins meet at one 3D point
    grainlines, notches = _marks(g, pairs, averaged)
    out = build_garment(uv, faces, point, xyz=xyz, source=g.source, kind=g.kind,
                        units_in_file=g.units_in_file, scale_recovered=g.scale_recovered,
                        piece_names=list(g.piece_names), grainlines=grainlines,
                        notches=notches, twins=twins, panel_frames=g.panel_frames,
                        edge_curves=_carried_curves(g, new_index, mirror_index))
    _keep_seam_lines(g, out)
    return out


def _carried_curves(g: Garment, new_index: np.ndarray, mirror_index: np.ndarray
                    ) -> dict[tuple[int, int], np.ndarray]:
    """The pattern's own curves (:attr:`Garment.edge_curves`) on the new mesh, so the cut
    line still follows them: a kept or first piece keeps its own (chord coordinates bend
    with its averaged chords), a second piece takes its first's, mirrored. A reflection
    keeps each point's share ``s`` along the chord and flips its side ``h``."""
    out = {}
    for (a, b), rel in g.edge_curves.items():
        if new_index[a] >= 0 and new_index[b] >= 0:
            out[(int(new_index[a]), int(new_index[b]))] = rel
        if mirror_index[a] >= 0 and mirror_index[b] >= 0:
            out[(int(mirror_index[a]), int(mirror_index[b]))] = rel * np.array([1.0, -1.0])
    return out


def _carried_cut_lines(g: Garment, pairs: Sequence[MirrorPair], moves: list[PieceMove]
                       ) -> dict[int, np.ndarray]:
    """The cut lines a file drew (:attr:`Garment.cut_outlines`) where symmetrising left
    the sew lines in place, as it does a CAD's left and right (mirror copies already): a
    piece not symmetrised keeps its own, a pair's second takes its first's, mirrored. A
    pair moved farther than :data:`CUT_KEPT_MM` is cut on the station's allowance."""
    moved = {m.piece: m.max_mm for m in moves}
    out = {i: ring for i, ring in g.cut_outlines.items() if i not in moved}
    for p in pairs:
        if p.first in g.cut_outlines and max(moved.get(p.first, 0.0),
                                             moved.get(p.second, 0.0)) <= CUT_KEPT_MM:
            out[p.first] = g.cut_outlines[p.first]
            out[p.second] = p.map_first_to_second(g.cut_outlines[p.first])[::-1]
    return out


def _keep_seam_lines(old: Garment, new: Garment) -> None:
    """Give the new garment's seam lines the old numbers, names and weights (in place).

    Lines are numbered by their first seam edge, which moves when a piece is re-meshed;
    ``--weights`` and allowances name lines by number or name, so each new line takes
    those of the old line between the same pieces that lies nearest (the centres of their
    edges).
    """
    def centres(g: Garment) -> np.ndarray:
        mid = g.uv[g.seam_edges].mean(axis=1)  # (E,2) centre of each twin row
        count = np.bincount(g.seam_line_of_edge, minlength=len(g.seam_lines))
        return np.column_stack([np.bincount(g.seam_line_of_edge, mid[:, k],
                                            len(g.seam_lines)) for k in range(2)]) \
            / np.maximum(count, 1)[:, None]

    if len(old.seam_lines) != len(new.seam_lines):
        return
    at_old, at_new = centres(old), centres(new)
    key_old = [(s.piece_a, s.piece_b) for s in old.seam_lines]
    key_new = [(s.piece_a, s.piece_b) for s in new.seam_lines]
    number = np.full(len(key_new), -1)
    for key in set(key_new):
        ks_new = [k for k, x in enumerate(key_new) if x == key]
        ks_old = [k for k, x in enumerate(key_old) if x == key]
        if len(ks_new) != len(ks_old):
            return
        cost = np.linalg.norm(at_new[ks_new][:, None] - at_old[ks_old][None], axis=2)
        rows, cols = linear_sum_assignment(cost)
        number[np.asarray(ks_new)[rows]] = np.asarray(ks_old)[cols]
    new.seam_line_of_edge = number[new.seam_line_of_edge]
    new.seam_lines = list(old.seam_lines)


def _drape_at(g: Garment, p: MirrorPair, uv_new: np.ndarray) -> np.ndarray:
    """3D positions of the second piece's old drape at its new vertices."""
    verts, faces = _local_faces(g, p.second)
    return barycentric_matrix(uv_new, g.uv[verts], faces) @ g.xyz[verts]


def _new_twins(g: Garment, pairs: Sequence[MirrorPair], role: np.ndarray,
               new_index: np.ndarray, mirror_index: np.ndarray) -> np.ndarray:
    """(E',4) twin rows of the new garment, in its vertex numbering.

    Every old seam side on a second piece is replaced by the first piece's edge at its
    mirror image; a row then stands for itself ("own") and, when none of its sides is on
    an unpaired piece, for its mirror image too. Both are emitted, duplicates merged;
    rows with both sides on second pieces are left out, as the mirror images of rows
    between first pieces give them in the first piece's sampling.
    """
    rows = g.seam_edges
    own = np.full(rows.shape, -1)
    mirror = np.full(rows.shape, -1)
    paired_row = np.ones(len(rows), bool)
    on_second = np.ones(len(rows), bool)
    for side in (slice(0, 2), slice(2, 4)):
        a = rows[:, side]
        r = role[g.piece_of_vertex[a[:, 0]]]
        first_like = np.where(r[:, None] == _SECOND, _matched_first_edge(g, pairs, a, r), a)
        own[:, side] = np.where(r[:, None] == _SECOND, mirror_index[first_like],
                                new_index[first_like])
        mirror[:, side] = np.where(r[:, None] == _SECOND, new_index[first_like],
                                   mirror_index[first_like])
        paired_row &= r != _KEPT
        on_second &= r == _SECOND
    # rows between second pieces are the mirror images of rows between first pieces
    keep = ~on_second
    out = np.concatenate([own[keep], mirror[paired_row & keep]])
    n = int(max(new_index.max(), mirror_index.max())) + 1
    e1 = np.minimum(out[:, 0], out[:, 1]) * n + np.maximum(out[:, 0], out[:, 1])
    e2 = np.minimum(out[:, 2], out[:, 3]) * n + np.maximum(out[:, 2], out[:, 3])
    key = np.column_stack([np.minimum(e1, e2), np.maximum(e1, e2)])
    _, first = np.unique(key, axis=0, return_index=True)
    return out[np.sort(first)]


def _matched_first_edge(g: Garment, pairs: Sequence[MirrorPair], edges: np.ndarray,
                        role: np.ndarray) -> np.ndarray:
    """(E,2) for edges on a second piece: the first piece's boundary edge at their mirror
    image, its ends in the same order; other rows are returned as they are.

    The outer outlines are cut into spans where the seam line changes (seam ends, open
    edges), the spans of the two pieces are matched in order around the outline (the
    cyclic shift that brings their ends closest), and the edges within two matched spans
    of equal edge count in order: k-th to k-th, as twin edges along a seam are sewn, so
    that how the two meshes space their vertices along a seam does not matter. Edges on
    holes, and on spans of different counts, take the nearest edge (a clash then makes
    `_check_seams` leave the pair alone).
    """
    out = edges.copy()
    bhe = g.boundary_half_edges()
    piece = g.piece_of_vertex
    for p in pairs:
        rows = np.flatnonzero((role == _SECOND) & (piece[edges[:, 0]] == p.second))
        if len(rows) == 0:
            continue
        table = _outline_correspondence(g, p)
        key = edges[rows, 0] * g.n_vertices + edges[rows, 1]
        hit = np.isin(key, table[:, 0])
        order = np.argsort(table[:, 0])
        found = table[order[np.searchsorted(table[order, 0], key[hit])], 1:]
        out[rows[hit]] = found
        rest = rows[~hit]
        if len(rest) == 0:
            continue
        cand = bhe[piece[bhe[:, 0]] == p.first]
        ends = _inverse_map(p, g.uv[edges[rest].ravel()]).reshape(-1, 2, 2)
        _, k = cKDTree(g.uv[cand].mean(axis=1)).query(ends.mean(axis=1))
        c = cand[k]
        swap = (np.linalg.norm(g.uv[c[:, 0]] - ends[:, 0], axis=1)
                > np.linalg.norm(g.uv[c[:, 1]] - ends[:, 0], axis=1))
        out[rest] = np.where(swap[:, None], c[:, ::-1], c)
    return out


def _outline_correspondence(g: Garment, p: MirrorPair) -> np.ndarray:
    """(k,3) rows ``[a * V + b, c, d]``: directed outline edge a->b of the second piece
    (both directions listed) and the first piece's edge c->d at its mirror image, a~c."""
    loop_i = g.piece_loops(p.first)[0]
    loop_j = g.piece_loops(p.second)[0][::-1]  # mirrored: now runs the way loop_i does
    spans_i, spans_j = _spans(g, loop_i), _spans(g, loop_j)
    if len(spans_i) != len(spans_j):
        raise _Skip("its outlines have different seam spans", p)
    back_j = _inverse_map(p, g.uv[loop_j])
    starts_i = g.uv[loop_i[spans_i[:, 0]]]
    starts_j = back_j[spans_j[:, 0]]
    rolls = (np.arange(len(spans_j))[:, None] + np.arange(len(spans_j))[None]) % len(spans_j)
    cost = np.linalg.norm(starts_j[rolls] - starts_i[None], axis=2).sum(axis=1)
    spans_j = spans_j[rolls[int(np.argmin(cost))]]  # the cyclic match of all span ends
    alike = spans_i[:, 1] == spans_j[:, 1]  # others are left to the nearest edge
    spans_i, spans_j = spans_i[alike], spans_j[alike]
    steps = np.arange(spans_i[:, 1].max(initial=0))
    within = (steps[None] < spans_i[:, 1:2]).ravel()
    k_i = (spans_i[:, :1] + steps[None]).ravel()[within] % len(loop_i)
    k_j = (spans_j[:, :1] + steps[None]).ravel()[within] % len(loop_j)
    a, b = loop_j[k_j], loop_j[(k_j + 1) % len(loop_j)]
    c, d = loop_i[k_i], loop_i[(k_i + 1) % len(loop_i)]
    n = g.n_vertices
    return np.concatenate([np.column_stack([a * n + b, c, d]),
                           np.column_stack([b * n + a, d, c])])


def _spans(g: Garment, loop: np.ndarray) -> np.ndarray:
    """(s,2) [first edge index, edge count] of the runs of equal seam line along a closed
    loop (edge k runs loop[k] -> loop[k+1]; -1 open)."""
    n = g.n_vertices
    se = g.seam_edges
    keys = np.concatenate([se[:, 0] * n + se[:, 1], se[:, 1] * n + se[:, 0],
                           se[:, 2] * n + se[:, 3], se[:, 3] * n + se[:, 2]])
    lines = np.tile(g.seam_line_of_edge, 4)
    order = np.argsort(keys)
    keys, lines = keys[order], lines[order]
    edge = loop * n + np.roll(loop, -1)
    lab = np.full(len(loop), -1)
    if len(keys):
        at = np.minimum(np.searchsorted(keys, edge), len(keys) - 1)
        lab = np.where(keys[at] == edge, lines[at], -1)
    change = np.flatnonzero(lab != np.roll(lab, 1))
    if len(change) == 0:
        return np.array([[0, len(loop)]])
    length = np.diff(np.append(change, change[0] + len(loop)))
    return np.column_stack([change, length])


def _check_seams(pairs: Sequence[MirrorPair], twins: np.ndarray,
                 span: dict[int, tuple[int, int]], n: int) -> None:
    """Every new edge sewn once, and each new second piece sewn along as many edges as its
    first piece: else the pair's seams did not correspond edge for edge."""
    keys = np.concatenate([np.minimum(twins[:, 0], twins[:, 1]) * n
                           + np.maximum(twins[:, 0], twins[:, 1]),
                           np.minimum(twins[:, 2], twins[:, 3]) * n
                           + np.maximum(twins[:, 2], twins[:, 3])])
    uniq, counts = np.unique(keys, return_counts=True)
    twice = np.zeros(n, bool)
    twice[uniq[counts > 1] // n] = True
    sewn = np.bincount(np.concatenate([twins[:, 0], twins[:, 2]]), minlength=n)
    for p in pairs:
        (lo_i, hi_i), (lo_j, hi_j) = span[p.first], span[p.second]
        if twice[lo_i:hi_i].any() or twice[lo_j:hi_j].any() \
                or sewn[lo_i:hi_i].sum() != sewn[lo_j:hi_j].sum():
            raise _Skip("its seams do not correspond edge for edge", p)


def _marks(g: Garment, pairs: Sequence[MirrorPair], averaged: dict[int, np.ndarray]):
    """Grain lines and notches: a first piece's move with its nearest vertex, mirrored
    onto the second piece (whose own marks are replaced when the first piece has some)."""
    grains = dict(g.grainlines)
    notches = {k: list(v) for k, v in g.notches.items()}
    for p in pairs:
        verts = np.flatnonzero(g.piece_of_vertex == p.first)
        tree = cKDTree(g.uv[verts])
        shift = averaged[p.first] - g.uv[verts]

        def moved(points, tree=tree, shift=shift):
            q = np.asarray(points, float).reshape(-1, 2)
            return q + shift[tree.query(q)[1]]

        if p.first in g.grainlines:
            a = moved(g.grainlines[p.first])
            grains[p.first] = tuple(tuple(map(float, x)) for x in a)
            grains[p.second] = tuple(tuple(map(float, x)) for x in p.map_first_to_second(a))
        if g.notches.get(p.first):
            a = moved(g.notches[p.first])
            notches[p.first] = [tuple(map(float, x)) for x in a]
            notches[p.second] = [tuple(map(float, x)) for x in p.map_first_to_second(a)]
    return grains, notches


# ---------------------------------------------------------------------- the report


def _moves(old: Garment, new: Garment, pairs: Sequence[MirrorPair]) -> list[PieceMove]:
    """Per symmetrised piece: its old outline vertices' distance to its new outline."""
    area_old, area_new = old.piece_areas(), new.piece_areas()
    out = []
    for p in pairs:
        for k in (p.first, p.second):
            pts = old.uv[np.concatenate(old.piece_loops(k))]
            d = np.full(len(pts), np.inf)
            for loop in new.piece_loops(k):
                q = closest_on_polygon(pts, new.uv[loop])
                d = np.minimum(d, np.linalg.norm(q - pts, axis=1))
            out.append(PieceMove(k, float(d.max()), float(np.sqrt(np.mean(d ** 2))),
                                 100.0 * (area_new[k] / area_old[k] - 1.0)))
    return sorted(out, key=lambda m: m.piece)


