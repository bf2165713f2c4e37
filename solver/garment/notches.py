"""Notches: short slits from the cut line into the seam allowance where sewers match pieces.

A seam line gets a notch near both of its ends and balance notches between them, at most
``spacing_mm`` apart (about 20 cm on long seams: a sewer eases the seam between two marks
and the print meets again at each mark). As sewers read them, front seams get single
notches and back seams double ones (:func:`back_seam_lines`), so a back armhole is never
sewn to a front one. Stations are placed on
one side of the seam by arc length and carried to the twin side through the seam's own
edge pairing (edge a->b is sewn to a2->b2, a~a2 and b~b2 the same 3D points): the same
parameter on twin edges is the same 3D point, so twin notches always match, even where
the two sew lines differ in length. An end notch sits one allowance in from the seam's
end (at the corner itself a slit would run along the neighbouring edge).

Each notch starts on the cut line, where the sew line's outward normal at the station
meets it, and runs back along that normal (perpendicular to the sew line) at most half
the allowance deep, so it never reaches the sew line. Notches whose slit would come
closer to the sew line than a quarter of the allowance (crowded concave corners) are
dropped together with their twin.

A dart (a self-seam whose legs follow each other along the outline) is sewn shut, so it
gets no notches along its legs: one at each end of its mouth (they meet when it is sewn)
and a drill mark just before its point (:func:`dart_marks`).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import shapely

from solver.garment.allowance import CutLine, cut_lines, dart_runs
from solver.garment.mesh import connected_components, loop_edge_keys
from solver.garment.model import Garment
from solver.garment.symmetry import MirrorPair, fit_pairs, mirror_pairs, mirrored_edges
from solver.seams.names import name_parts

__all__ = ["DOUBLE_NOTCH_GAP_MM", "Notch", "back_seam_lines", "cut_ready", "dart_marks",
           "placement_lattice", "placement_pairs", "print_stations", "seam_notches"]


#: the two slits of a double notch lie this far apart along the cut line, mm
DOUBLE_NOTCH_GAP_MM = 6.0
LatticeCoords = Callable[[int, np.ndarray], np.ndarray]  # (piece, (k,2) uv) -> (k,2) frac


@dataclass
class Notch:
    """A slit from ``at`` (on the cut line) along ``direction`` (into the piece)."""

    piece: int
    at: np.ndarray  # (2,) pattern mm, on the cut line
    direction: np.ndarray  # (2,) unit, inward, perpendicular to the sew line
    depth: float  # mm, at most half the allowance
    sew_point: np.ndarray  # (2,) the sew-line point it marks
    seam_line: int
    station: int  # twin notches share (seam_line, station)
    edge: tuple[int, int] = (0, 0)  # the pattern edge (vertices) the sew point lies on
    t: float = 0.0  # ... at this fraction from edge[0] to edge[1]
    starts: np.ndarray | None = None  # (k,2) on the cut line: k slits (2: a double notch)

    @property
    def count(self) -> int:
        """1 for a single notch, 2 for a double one."""
        return 1 if self.starts is None else len(self.starts)

    def slits(self) -> list[tuple[np.ndarray, np.ndarray, float]]:
        """Each slit to cut: (start on the cut line, inward direction, depth)."""
        starts = [self.at] if self.starts is None else list(self.starts)
        return [(p, self.direction, self.depth) for p in starts]


def chain_seam_rows(rows: np.ndarray) -> np.ndarray:
    """Order the twin pairs of one seam line along side A (a->b of one follows the last)."""
    nxt = {int(a): k for k, a in enumerate(rows[:, 0])}
    ends = set(rows[:, 1].tolist())
    starts = [k for k, a in enumerate(rows[:, 0].tolist()) if a not in ends]
    k = starts[0] if starts else 0
    order = []
    seen = set()
    while k is not None and k not in seen:
        order.append(k)
        seen.add(k)
        k = nxt.get(int(rows[k, 1]))
    return rows[order] if len(order) == len(rows) else rows  # branching: keep file order


def _reference_side_first(uv: np.ndarray, rows: np.ndarray, forward) -> np.ndarray:
    """A seam line's twin rows chained, the longer side first: the stations are measured
    along it. Which side a file lists first is arbitrary (vertex numbers, and a seam of a
    piece with itself may list either side first row by row); the longer one is the same
    on a seam and on its mirror image, so a pair's notches mirror. ``forward(u, v)``
    tells whether edges u->v run as in their faces."""
    verts, local = np.unique(rows, return_inverse=True)
    local = local.reshape(rows.shape)
    _, comp = connected_components(len(verts), np.concatenate([local[:, :2], local[:, 2:]]))
    other = comp[local[:, 0]] != comp[local[0, 0]]  # a row listing the other side first
    rows = np.where(other[:, None], rows[:, [2, 3, 0, 1]], rows)
    as_in_face = forward(rows[:, 0], rows[:, 1])  # so that the first side chains
    rows = np.where(as_in_face[:, None], rows, rows[:, [1, 0, 3, 2]])

    def length(a: int, b: int) -> float:
        return float(np.hypot(*(uv[rows[:, b]] - uv[rows[:, a]]).T).sum())

    if length(2, 3) > length(0, 1) + 1e-6:
        rows = rows[:, [2, 3, 0, 1]]
    return chain_seam_rows(rows)


def _outward(uv: np.ndarray, a: np.ndarray, b: np.ndarray, forward: np.ndarray) -> np.ndarray:
    """(k,2) unit normals pointing away from the piece for edges a->b (forward: as in face)."""
    d = uv[b] - uv[a]
    d = d / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)[:, None]
    nrm = np.column_stack([d[:, 1], -d[:, 0]])
    return np.where(forward[:, None], nrm, -nrm)


def back_seam_lines(garment: Garment) -> set[int]:
    """Seam lines that get double notches: a back piece (by its name, as
    :func:`solver.seams.names.name_parts` reads it) sewn to no front piece, i.e. centre
    back, back armhole, back waistband; side and shoulder seams join a front and stay
    single, like every seam of pieces whose names say neither."""
    kinds = [name_parts(n)[0] for n in garment.piece_names]
    out = set()
    for line, s in enumerate(garment.seam_lines):
        both = kinds[s.piece_a] | kinds[s.piece_b]
        if "back" in both and "front" not in both:
            out.add(line)
    return out


def seam_notches(garment: Garment, cuts: list[CutLine], *, spacing_mm: float = 200.0,
                 depth_mm: float = 3.0, lattice_coords: LatticeCoords | None = None,
                 pairs: Sequence[MirrorPair] = ()) -> list[list[Notch]]:
    """Per piece, the notches of every seam line (pattern mm), twins on matching points.

    ``cuts`` (:func:`solver.garment.allowance.cut_lines`) carry the per-edge allowances
    they were made with. With ``lattice_coords`` (the
    print's fractional lattice coordinates of pattern points on a piece, from the
    placement) the balance notches go where the print's lattice lines cross the sew line
    (:func:`print_stations`), the match points a cutter lines a plaid up on, no closer
    than half the spacing (a fine print would otherwise notch every few centimetres).
    A seam line that is the mirror image of an earlier one through the mirror ``pairs``
    takes that line's notches mirrored (:func:`_mirror_sources`): measured on its own,
    a seam's stations depend on which side is measured and how it is meshed (a darted
    waist is three runs), and a pair's notches would not mirror. Back seams
    (:func:`back_seam_lines`, darts aside) get double notches.
    """
    g = garment
    darts = {line: (piece, run) for piece in range(g.n_pieces)
             for line, run in dart_runs(g, piece)}
    notcher = _Notcher(g, cuts, depth_mm, back_seam_lines(g) - set(darts))
    images = _edge_images(g, pairs)
    sources = _mirror_sources(g, images)
    for line in range(len(g.seam_lines)):
        if line in darts:
            notcher.dart(line, *darts[line])
        elif line in sources:
            notcher.mirrored(line, sources[line], images)
        else:
            notcher.measured(line, spacing_mm, lattice_coords)
    return notcher.out


class _Notcher:
    """The notches of one garment's seam lines as :func:`seam_notches` places them, with
    the per-edge allowances of its cut lines to look up."""

    def __init__(self, garment: Garment, cuts: list[CutLine], depth_mm: float,
                 double: set[int]) -> None:
        g = self.g = garment
        self.depth_mm = depth_mm
        self.double = double
        n = g.n_vertices
        loops = [lp for i in range(g.n_pieces) for lp in g.piece_loops(i)]
        keys = loop_edge_keys(loops, n)
        values = np.concatenate([a for c in cuts for a in (c.allowance, *c.hole_allowance)])
        order = np.argsort(keys)
        self.keys, self.values = keys[order], values[order]
        self.out: list[list[Notch]] = [[] for _ in range(g.n_pieces)]
        self.boundaries = [c.cut.boundary for c in cuts]
        self.sews = [shapely.Polygon(c.sew_outline, c.sew_holes) for c in cuts]

    def lookup(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Allowance of edge u-v and whether u->v runs as in its face."""
        keys, values, n = self.keys, self.values, self.g.n_vertices
        fk, bk = u * n + v, v * n + u
        fi = np.clip(np.searchsorted(keys, fk), 0, len(keys) - 1)
        bi = np.clip(np.searchsorted(keys, bk), 0, len(keys) - 1)
        fwd = keys[fi] == fk
        return np.where(fwd, values[fi], np.where(keys[bi] == bk, values[bi], 0.0)), fwd

    def emit(self, line: int, sides: list, ids: np.ndarray | None = None) -> np.ndarray:
        """Add the notches of stations (numbered ``ids``, default in order) that are clear
        on both twin sides; the numbers of those added."""
        made = [(piece, point, nrm, a, b, f, *_slits(point, nrm, w, self.boundaries[piece],
                                                      self.sews[piece], self.depth_mm))
                for piece, point, nrm, w, a, b, f in sides]
        both = made[0][-1] & made[1][-1]
        ids = np.arange(len(both)) if ids is None else ids
        for piece, point, nrm, a, b, f, at, depth, _ in made:
            starts = (_pair_along(self.boundaries[piece], at) if line in self.double
                      else [None] * len(at))
            for j in np.flatnonzero(both):
                self.out[piece].append(Notch(piece, at[j], -nrm[j], float(depth[j]), point[j],
                                             line, int(ids[j]), (int(a[j]), int(b[j])),
                                             float(f[j]), starts[j]))
        return ids[both]

    def twin_sides(self, rows: np.ndarray, k: np.ndarray, f: np.ndarray) -> list:
        """Both sides of stations at fraction ``f`` along twin rows ``rows[k]``."""
        g, sides = self.g, []
        for cols in ((0, 1), (2, 3)):
            a, b = rows[k, cols[0]], rows[k, cols[1]]
            w, fwd = self.lookup(a, b)
            point = g.uv[a] + f[:, None] * (g.uv[b] - g.uv[a])
            sides.append((int(g.piece_of_vertex[a[0]]), point, _outward(g.uv, a, b, fwd), w,
                          a, b, f))
        return sides

    def dart(self, line: int, piece: int, run: np.ndarray) -> None:
        """A dart: one notch at each end of its mouth, its legs sewn shut."""
        g = self.g
        loop = g.piece_loops(piece)[0]
        k = {int(v): j for j, v in enumerate(loop.tolist())}
        before = loop[k[int(run[0])] - 1]
        after = loop[(k[int(run[-1])] + 1) % len(loop)]
        sides = []
        for a, b, f in ((before, run[0], 1.0), (run[-1], after, 0.0)):
            a, b = np.array([a]), np.array([b])
            w, fwd = self.lookup(a, b)
            sides.append((piece, g.uv[b] if f else g.uv[a], _outward(g.uv, a, b, fwd), w,
                          a, b, np.array([f])))
        self.emit(line, sides)

    def mirrored(self, line: int, source: int, images: EdgeImages) -> None:
        """The mirror image of seam line ``source``'s notches; a mirror image not clear
        here (beside an unpaired piece) drops its original."""
        rows = self.g.seam_edges[self.g.seam_line_of_edge == line]
        k, f, ids = _mirrored_stations(rows, source, self.out, images)
        kept = self.emit(line, self.twin_sides(rows, k, f), ids) if len(k) else ids
        dropped = set(ids.tolist()) - set(kept.tolist())
        for notches in self.out:
            notches[:] = [n for n in notches
                          if n.seam_line != source or n.station not in dropped]

    def measured(self, line: int, spacing_mm: float,
                 lattice_coords: LatticeCoords | None) -> None:
        """Stations measured along the longer side: every ``spacing_mm`` inside the
        allowance at both ends, or on the print's lattice lines."""
        g = self.g
        rows = _reference_side_first(g.uv, g.seam_edges[g.seam_line_of_edge == line],
                                     lambda u, v: self.lookup(u, v)[1])
        pa, pb = g.uv[rows[:, 0]], g.uv[rows[:, 1]]
        seg = np.hypot(*(pb - pa).T)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        total = float(s[-1])
        if total <= 1e-9:
            return
        allow, _ = self.lookup(rows[:, 0], rows[:, 1])
        inset = min(float(allow.max()), total / 4)
        if lattice_coords is None:
            count = int(np.ceil((total - 2 * inset) / spacing_mm)) if spacing_mm > 0 else 1
            stations = np.linspace(inset, total - inset, max(count, 1) + 1)
        else:
            piece_a = int(g.piece_of_vertex[rows[0, 0]])
            f_a = lattice_coords(piece_a, g.uv[rows[:, 0]])
            f_b = lattice_coords(piece_a, g.uv[rows[:, 1]])
            stations = print_stations(s, f_a, f_b, inset, spacing_mm,
                                      min_gap=max(2.0 * float(allow.max()), spacing_mm / 2))
        k = np.clip(np.searchsorted(s, stations, side="right") - 1, 0, len(rows) - 1)
        f = np.clip((stations - s[k]) / np.maximum(seg[k], 1e-12), 0.0, 1.0)
        self.emit(line, self.twin_sides(rows, k, f))


EdgeImages = dict[tuple[int, int], tuple[int, int]]


def _edge_images(garment: Garment, pairs: Sequence[MirrorPair]) -> EdgeImages:
    """Directed boundary edge a->b of a paired piece -> its partner's edge c->d at its
    mirror image (c the image of a), both ways round and both directions."""
    out: EdgeImages = {}
    for pair in pairs:
        for p in (pair, pair.turned()):
            for a, b, c, d in mirrored_edges(garment, p).tolist():
                out[(a, b)], out[(b, a)] = (c, d), (d, c)
    return out


def _mirror_sources(garment: Garment, images: EdgeImages) -> dict[int, int]:
    """Seam line -> the lower-numbered seam line whose paired sides its own sides are the
    mirror images of (the other half's copy of the seam); centre seams, which are their
    own mirror images, and seams between unpaired pieces have none."""
    g = garment
    line_of: dict[tuple[int, int], int] = {}
    for (a, b, a2, b2), line in zip(g.seam_edges.tolist(), g.seam_line_of_edge.tolist()):
        for u, v in ((a, b), (b, a), (a2, b2), (b2, a2)):
            line_of[(u, v)] = line
    out = {}
    for line in range(len(g.seam_lines)):
        rows = g.seam_edges[g.seam_line_of_edge == line]
        hits = [line_of.get(images[e], -1) for e in map(tuple, np.concatenate(
            [rows[:, :2], rows[:, 2:]]).tolist()) if e in images]
        if hits:
            source = Counter(hits).most_common(1)[0][0]
            if 0 <= source < line:
                out[line] = source
    return out


def _mirrored_stations(rows: np.ndarray, source: int, out: list[list[Notch]],
                       images: EdgeImages) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stations of a seam line (its twin ``rows``) at the mirror images of the notches
    already made on seam line ``source``: per station the row, the fraction along it and
    the source's station number. A notch on edge a->b at t maps to t along the image
    c->d (c the image of a), the same point of the mirrored piece."""
    at_row = {}
    for r, (a, b, a2, b2) in enumerate(rows.tolist()):
        at_row[(a, b)], at_row[(b, a)] = (r, False), (r, True)
        at_row[(a2, b2)], at_row[(b2, a2)] = (r, False), (r, True)
    found: dict[int, tuple[int, float]] = {}
    for notch in (n for piece in out for n in piece if n.seam_line == source):
        image = images.get(notch.edge)
        if image in at_row and notch.station not in found:
            r, flipped = at_row[image]
            found[notch.station] = (r, 1.0 - notch.t if flipped else notch.t)
    ids = np.array(sorted(found), dtype=np.int64)
    k = np.array([found[i][0] for i in ids], dtype=np.int64)
    f = np.array([found[i][1] for i in ids], dtype=float)
    return k, f, ids


def cut_ready(garment: Garment, rules, placement=None,
              pairs: Sequence[MirrorPair] | None = None
              ) -> tuple[list[CutLine], list[list[Notch]]]:
    """Per piece the cut line and the notches with ``rules`` (AllowanceRules); with the
    placement and ``rules.notch_on_print`` the balance notches sit on the print's lattice
    lines. Mirror ``pairs`` get
    mirrored allowances and notches; by default the pairs the placement records, else
    the garment's own (:func:`~solver.garment.symmetry.mirror_pairs`)."""
    if pairs is None:
        pairs = placement_pairs(garment, placement)
    cuts = cut_lines(garment, rules, pairs)
    on_print = rules.notch_on_print and placement is not None and placement.fabric is not None
    lattice = placement_lattice(placement) if on_print else None
    return cuts, seam_notches(garment, cuts, spacing_mm=rules.notch_spacing_mm,
                              depth_mm=rules.notch_depth_mm, lattice_coords=lattice,
                              pairs=pairs)


def placement_pairs(garment: Garment, placement=None) -> list[MirrorPair]:
    """The mirror pairs an alignment kept: those its placement records, the operator's
    declarations, vetoes and ``--no-symmetry`` included (none when it kept none, so a veto
    is never undone here). Without an aligned placement (none, or the identity, which
    has no report), the pairs the garment shows."""
    if placement is not None and placement.report:
        return fit_pairs(garment, [p[:2] for p in placement.pairs])
    return mirror_pairs(garment)


def placement_lattice(placement) -> LatticeCoords:
    """The print's fractional lattice coordinates of pattern points, as ``placement``
    (:class:`solver.placement.Placement`) lays each piece on its fabric."""
    fabric = placement.fabric
    basis = np.column_stack([fabric.w1, fabric.w2])

    def coords(piece: int, uv: np.ndarray) -> np.ndarray:
        wp = placement.to_wallpaper(np.asarray(uv, float), np.full(len(uv), piece))
        return np.linalg.solve(basis, (wp - fabric.origin).T).T

    return coords


def print_stations(s: np.ndarray, f_start: np.ndarray, f_end: np.ndarray, inset: float,
                   spacing_mm: float, min_gap: float) -> np.ndarray:
    """Arc-length stations on one side of a seam: both ends (``inset`` in), every crossing of
    a lattice line of the print (a fractional coordinate passing an integer), none closer
    than ``min_gap`` to a kept one, and fill-ins so no gap exceeds ``spacing_mm``.

    ``s`` (k+1,) are the arc lengths of the edge ends; ``f_start``, ``f_end`` (k,2) the
    lattice coordinates of each edge's two ends.
    """
    total = float(s[-1])
    lo, hi = np.floor(np.minimum(f_start, f_end)), np.floor(np.maximum(f_start, f_end))
    cross = []
    for j in range(2):  # the two families of lattice lines
        n = (hi[:, j] - lo[:, j]).astype(int)
        edge = np.repeat(np.arange(len(n)), n)
        level = lo[edge, j] + 1 + (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n))
        span = f_end[edge, j] - f_start[edge, j]
        t = (level - f_start[edge, j]) / np.where(span == 0, 1.0, span)
        cross.append(s[edge] + t * (s[edge + 1] - s[edge]))
    cross = np.sort(np.concatenate(cross))
    cross = cross[(cross > inset + min_gap) & (cross < total - inset - min_gap)]
    # Greedy from either end, the better spread kept: a seam and its mirror image (the
    # left and right piece of a pair run their seams the opposite way) get the same notches.
    forward = _greedy_stations(cross, inset, total, min_gap)
    backward = [total - c for c in _greedy_stations(total - cross[::-1], inset, total,
                                                    min_gap)[::-1]]
    kept = min((forward, backward), key=_spread)
    out = [kept[0]]
    for a, b in zip(kept[:-1], kept[1:]):
        extra = int(np.ceil((b - a) / spacing_mm)) - 1 if spacing_mm > 0 else 0
        out += list(np.linspace(a, b, extra + 2)[1:])
    return np.asarray(out)


def _greedy_stations(cross: np.ndarray, inset: float, total: float,
                     min_gap: float) -> list[float]:
    """Both ends and each crossing at least ``min_gap`` past the last one kept."""
    kept = [inset]
    for c in cross:
        if c - kept[-1] >= min_gap:
            kept.append(float(c))
    if total - inset - kept[-1] < min_gap and len(kept) > 1:
        kept.pop()
    kept.append(total - inset)
    return kept


def _spread(stations: list[float]) -> tuple[int, float]:
    """Order of preference, the same read from either end: more stations, then the more
    even (smaller sum of squared gaps, to the micrometre)."""
    gaps = np.diff(stations)
    return -len(stations), round(float(np.sum(gaps ** 2)), 3)


def _pair_along(boundary, at: np.ndarray) -> np.ndarray:
    """(k,2,2) the two slit starts of double notches centred on ``at`` (k,2): half
    :data:`DOUBLE_NOTCH_GAP_MM` either way along the cut line."""
    s = shapely.line_locate_point(boundary, shapely.points(at))
    half = DOUBLE_NOTCH_GAP_MM / 2
    two = np.column_stack([s - half, s + half]) % max(boundary.length, 1e-12)
    pts = shapely.get_coordinates(shapely.line_interpolate_point(boundary, two.ravel()))
    return pts.reshape(len(at), 2, 2)


def _slits(point: np.ndarray, nrm: np.ndarray, w: np.ndarray, boundary, sew, depth_mm: float
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where each outward ray from the sew line meets the cut line, the slit depth there,
    and whether the slit keeps clear of the sew line (a quarter of the allowance)."""
    reach = 3.0 * np.maximum(w, 1e-6)
    rays = shapely.linestrings(np.stack([point + 1e-6 * nrm, point + reach[:, None] * nrm], 1))
    hits = shapely.intersection(rays, boundary)
    coords, owner = shapely.get_coordinates(hits, return_index=True)
    t = np.full(len(point), np.inf)
    np.minimum.at(t, owner, np.hypot(*(coords - point[owner]).T))
    found = np.isfinite(t)
    t = np.where(found, t, 0.0)
    depth = np.minimum(depth_mm, np.minimum(w, t) / 2)
    at = point + t[:, None] * nrm
    clear = shapely.distance(shapely.linestrings(np.stack([at, at - depth[:, None] * nrm], 1)),
                             sew)
    ok = found & (w > 0) & (depth > 0) & (clear >= 0.25 * w - 1e-9)
    return at, depth, ok


def dart_marks(garment: Garment, piece: int, inset_mm: float = 10.0) -> np.ndarray:
    """(k,2) drill marks, one per dart of ``piece``: ``inset_mm`` before the dart's point
    on its centre line (hidden in the seam once sewn), as pattern makers mark darts."""
    g = garment
    marks = []
    for _, run in dart_runs(g, piece):
        mouth = 0.5 * (g.uv[run[0]] + g.uv[run[-1]])
        tip = g.uv[run[int(np.argmax(np.hypot(*(g.uv[run] - mouth).T)))]]
        d = mouth - tip
        length = float(np.hypot(*d))
        if length > 1e-9:
            marks.append(tip + min(inset_mm, length / 4) * d / length)
    return np.asarray(marks, float).reshape(-1, 2)
