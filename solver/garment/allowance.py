"""Seam allowance: each piece's cut line, the sew line offset outward edge by edge.

The mesh outline is the sew line (seams meet there, so E_fit, alignment and reshaping stay
on it). A cutter needs the cut line: every boundary edge pushed outward by its own allowance,
the seam allowance on sewn edges, the hem or opening allowance on edges sewn to nothing.

Geometry, as a pattern maker draws it: each edge contributes the strip between itself and
its offset line (a quadrilateral); at a convex corner the two offset lines are extended to
meet (a mitre), and where that point lies farther than ``cap`` times the larger allowance
from the corner the mitre is cut square at that distance. The cut line is the outline of
the union of the piece with all strips and corner fills (shapely, one vectorised union):
a union of polygons is always a simple polygon, so darts and self-seams (whose strips
overlap) give a clean outline that never crosses itself, concave corners come out mitred
by the overlap itself, and no point lies farther than ``cap`` x allowance from the sew
line. Holes stay holes: their allowance eats into them, and one too small for it is cut on
its sew line; pockets the union closes off between overlapping strips are filled.

Which open edges are hems: open edges chain (through shared 3D points) into the garment's
openings. An opening that reaches the garment's top (neckline, waist, armhole) is finished
with a facing or band (``opening_mm``); every other opening (bottom, sleeve and leg ends)
is a hem (``hem_mm``), and so is an upright loop alone on its pieces (the cuff of a
sleeve held out level, which reaches the shoulder's height). Heights are along the drape's
up direction (:func:`drape_up`, or given) when the garment has a drape, else world y where
a specification places its panels around the body, else pattern y within each piece (flat
patterns are drawn upright).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import shapely

from solver.garment.curves import fine_loop
from solver.garment.drape import drape_up, limb_end_axes, open_edges
from solver.garment.mesh import edge_keys, loop_edge_keys
from solver.garment.model import Garment
from solver.garment.symmetry import MirrorPair, mirror_pairs, mirrored_edges

__all__ = ["AllowanceRules", "CutLine", "cut_lines", "dart_fills", "dart_runs", "drape_up",
           "edge_allowances", "limb_end_axes", "offset_outline", "open_edges", "pair_allowances"]


@dataclass(frozen=True)
class AllowanceRules:
    """Allowances in mm: class defaults, then per-name overrides.

    ``overrides`` keys: a seam-line index or name (as ``--weights`` takes them), ``"seam"``,
    ``"hem"``, ``"opening"`` (the class defaults), ``"open#K"`` (one opening, numbered as
    :func:`open_edges` numbers them) or ``"PIECE/open"`` (every open edge of a piece).
    Notches (:mod:`solver.garment.notches`) are ``notch_depth_mm`` deep (at most half the
    allowance) and at most ``notch_spacing_mm`` apart along a seam; with ``notch_on_print``
    (``--match-notches``) a placed garment's balance notches go on the print's lattice lines.
    """

    seam_mm: float = 10.0
    hem_mm: float = 20.0
    opening_mm: float = 10.0
    cap: float = 2.0
    overrides: Mapping[int | str, float] = field(default_factory=dict)
    notch_depth_mm: float = 3.0
    notch_spacing_mm: float = 200.0
    notch_on_print: bool = False
    source: str = ""  # the file the overrides came from, named when one names nothing

    def __post_init__(self) -> None:
        for name in ("seam_mm", "hem_mm", "opening_mm"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"allowance {name} must be finite and >= 0, got {v!r}")
        for key, v in self.overrides.items():
            _check_mm(key, v)
        if not self.cap >= 1.0:
            raise ValueError(f"allowance cap must be >= 1, got {self.cap!r}")

    def with_overrides(self, more: Mapping[int | str, float], source: str = ""
                       ) -> AllowanceRules:
        """Copy with ``more`` overrides on top (from the file ``source``, if given);
        ``seam``/``hem``/``opening`` set defaults."""
        merged = {**self.overrides, **more}
        base = {k: _check_mm(k, merged.pop(k)) for k in ("seam", "hem", "opening") if k in merged}
        return dataclasses.replace(self, seam_mm=base.get("seam", self.seam_mm),
                                   hem_mm=base.get("hem", self.hem_mm),
                                   opening_mm=base.get("opening", self.opening_mm),
                                   overrides=merged, source=source or self.source)

    def to_dict(self) -> dict:
        return {"seam_mm": self.seam_mm, "hem_mm": self.hem_mm,
                "opening_mm": self.opening_mm, "cap": self.cap,
                "overrides": {str(k): float(v) for k, v in self.overrides.items()},
                "notch_depth_mm": self.notch_depth_mm,
                "notch_spacing_mm": self.notch_spacing_mm,
                "notch_on_print": self.notch_on_print}


def _check_mm(key, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) \
            or value < 0:
        raise ValueError(f"allowance for {key!r} must be a number >= 0, got {value!r}")
    return float(value)


@dataclass
class CutLine:
    """One piece: sew line (outer CCW + holes), per-edge allowance, and the cut polygon."""

    sew: np.ndarray  # (n,2) outer sew line, CCW
    sew_holes: list[np.ndarray]
    allowance: np.ndarray  # (n,) mm, edge k runs sew[k] -> sew[k+1]
    hole_allowance: list[np.ndarray]
    cut: shapely.Polygon  # exterior CCW
    sew_curve: np.ndarray | None = None  # (m,2) outer sew line on the pattern's own curves
    sew_curve_edge: np.ndarray | None = None  # (m,) the sew edge k each of its points is on

    @property
    def outline(self) -> np.ndarray:
        """(m,2) cut line, CCW, first point not repeated."""
        return np.asarray(self.cut.exterior.coords)[:-1, :2]

    @property
    def sew_outline(self) -> np.ndarray:
        """(m,2) outer sew line as the cutter follows it: on the pattern's curves where
        the garment has them (:attr:`Garment.edge_curves`), else the mesh outline."""
        return self.sew if self.sew_curve is None else self.sew_curve

    @property
    def sew_outline_allowance(self) -> np.ndarray:
        """(m,) allowance of each edge of :attr:`sew_outline` (that of its sew edge)."""
        return self.allowance if self.sew_curve_edge is None else self.allowance[
            self.sew_curve_edge]

    @property
    def holes(self) -> list[np.ndarray]:
        return [np.asarray(r.coords)[:-1, :2] for r in self.cut.interiors]


def edge_allowances(garment: Garment, rules: AllowanceRules,
                    pairs: Sequence[MirrorPair] | None = None) -> list[list[np.ndarray]]:
    """Per piece, per loop of :meth:`Garment.piece_loops`, the (k,) allowance of each edge.

    Edge k of a loop runs from ``loop[k]`` to ``loop[k + 1]``. Unknown override keys are
    errors that list what exists. The two halves of each mirror pair (``pairs``, default
    :func:`~solver.garment.symmetry.mirror_pairs`) get one allowance per pair of mirrored
    edges (:func:`pair_allowances`).
    """
    g, n = garment, garment.n_vertices
    rules = rules.with_overrides({})  # "seam", "hem", "opening" keys become the defaults
    ov = dict(rules.overrides)
    names = {s.name: i for i, s in enumerate(g.seam_lines)}
    seam_mm = np.full(len(g.seam_lines), rules.seam_mm)
    edges, opening, is_hem = open_edges(g)
    open_mm = np.where(is_hem, rules.hem_mm, rules.opening_mm)
    piece_open: dict[int, float] = {}
    where = f"{rules.source}: " if rules.source else ""
    for key, value in ov.items():
        if isinstance(key, int) or (isinstance(key, str) and key in names):
            idx = names.get(key) if isinstance(key, str) else key
            if not 0 <= idx < len(seam_mm):
                raise ValueError(f"{where}no seam line {key!r} (there are {len(seam_mm)})")
            seam_mm[idx] = value
        elif key.startswith("open#") and key[5:].isdigit():
            k = int(key[5:])
            if not 0 <= k < len(open_mm):
                raise ValueError(f"{where}no opening {key!r} (there are {len(open_mm)}: "
                                 "open#0...)")
            open_mm[k] = value
        elif key.endswith("/open") and key[:-5] in g.piece_names:
            piece_open[g.piece_names.index(key[:-5])] = float(value)
        else:
            raise ValueError(f"{where}no seam line, opening or piece {key!r}; seam lines are "
                             f"{', '.join(names) or 'none'}, openings open#0..open#"
                             f"{len(open_mm) - 1}, pieces take PIECE/open")
    keys = np.concatenate([edge_keys(g.seam_edges[:, 0], g.seam_edges[:, 1], n),
                           edge_keys(g.seam_edges[:, 2], g.seam_edges[:, 3], n),
                           edge_keys(edges[:, 0], edges[:, 1], n)])
    values = np.concatenate([seam_mm[g.seam_line_of_edge], seam_mm[g.seam_line_of_edge],
                             open_mm[opening]])
    order = np.argsort(keys, kind="stable")
    keys, values = keys[order], values[order]
    is_open = np.zeros(len(keys), bool)
    is_open[np.flatnonzero(order >= 2 * len(g.seam_edges))] = True
    out = []
    for i in range(g.n_pieces):
        per_loop = []
        for loop in g.piece_loops(i):
            k = edge_keys(loop, np.roll(loop, -1), n)
            pos = np.clip(np.searchsorted(keys, k), 0, max(len(keys) - 1, 0))
            a = values[pos].copy() if len(keys) else np.full(len(loop), rules.opening_mm)
            if i in piece_open:
                a[is_open[pos]] = piece_open[i]
            per_loop.append(a)
        out.append(per_loop)
    return pair_allowances(g, out, mirror_pairs(g) if pairs is None else pairs)


def pair_allowances(garment: Garment, per_piece: list[list[np.ndarray]],
                    pairs: Sequence[MirrorPair]) -> list[list[np.ndarray]]:
    """``per_piece`` (as :func:`edge_allowances` gives it) with each pair of mirrored edges
    (:func:`~solver.garment.symmetry.mirrored_edges`) given the larger of its two
    allowances, so a pair's cut lines are mirror images.

    Left and right are one pattern cut twice, but their edges are classed one by one: the
    hem test reads heights off a drape that need not be symmetric (a simulated drape, or an
    up axis found across the body), and an override may name one half. Where the halves
    disagree the larger allowance wins: a cutter can trim cloth, not add it.
    """
    g, n = garment, garment.n_vertices
    loops = [lp for i in range(g.n_pieces) for lp in g.piece_loops(i)]
    keys = loop_edge_keys(loops, n)
    values = np.concatenate([a for per_loop in per_piece for a in per_loop]).astype(float)
    order = np.argsort(keys)
    for pair in pairs:
        for p in (pair, pair.turned()):  # both ways: halves meshed apart need not match 1:1
            rows = mirrored_edges(g, p)
            mine = order[np.searchsorted(keys, rows[:, 0] * n + rows[:, 1], sorter=order)]
            theirs = order[np.searchsorted(keys, rows[:, 3] * n + rows[:, 2], sorter=order)]
            both = np.maximum(values[mine], values[theirs])
            np.maximum.at(values, mine, both)
            np.maximum.at(values, theirs, both)
    sizes = [len(a) for per_loop in per_piece for a in per_loop]
    flat = iter(np.split(values, np.cumsum(sizes)[:-1]))
    return [[next(flat) for _ in per_loop] for per_loop in per_piece]


def offset_outline(loops: list[np.ndarray], allowances: list[np.ndarray], *,
                   cap: float = 2.0, extra: list | None = None) -> shapely.Polygon:
    """The cut polygon of a piece from its sew loops (outer CCW, holes CW) and allowances.

    Parameters
    ----------
    loops : list of (k,2) float arrays
        The piece lies on the left of every edge ``loop[k] -> loop[k + 1]``.
    allowances : list of (k,) float arrays
        Outward offset of each edge in mm (0: cut on the sew line).
    cap : float
        No point of a corner lies farther than ``cap`` x the larger allowance from it.
    extra : list of shapely polygons, optional
        More cloth to keep (the folded-in wedge of a dart, :func:`dart_fills`).
    """
    base = shapely.Polygon(loops[0], loops[1:])
    if not base.is_valid:
        base = shapely.make_valid(base)
    p = np.vstack(loops)
    a = np.concatenate(allowances).astype(float)
    nxt = np.concatenate([np.roll(np.arange(len(lp)), -1) + s for lp, s in
                          zip(loops, np.cumsum([0] + [len(lp) for lp in loops[:-1]]))])
    prv = np.empty_like(nxt)
    prv[nxt] = np.arange(len(nxt))
    d = p[nxt] - p
    length = np.hypot(d[:, 0], d[:, 1])
    t = d / np.maximum(length, 1e-12)[:, None]
    nrm = np.column_stack([t[:, 1], -t[:, 0]])  # right of the edge = away from the piece
    o0, o1 = p + a[:, None] * nrm, p[nxt] + a[:, None] * nrm
    ok = (a > 0) & (length > 1e-9)
    strips = shapely.polygons(np.stack([p, p[nxt], o1, o0, p], axis=1)[ok])
    # corner at vertex v between edge prv[v] and edge v: convex when the outline turns left
    ap, tp = a[prv], t[prv]
    cross = tp[:, 0] * t[:, 1] - tp[:, 1] * t[:, 0]
    e1, e2 = p + ap[:, None] * nrm[prv], o0  # end of the previous offset, start of this one
    convex = (cross > 1e-9) & (np.maximum(ap, a) > 0)
    rel = e2 - e1
    s = (rel[:, 0] * t[:, 1] - rel[:, 1] * t[:, 0]) / np.where(convex, cross, 1.0)
    mitre = e1 + s[:, None] * tp
    reach = cap * np.maximum(ap, a)
    over = np.hypot(*(mitre - p).T) > reach
    c1 = np.where(over[:, None], e1 + np.sqrt(np.maximum(reach**2 - ap**2, 0))[:, None] * tp,
                  mitre)
    c2 = np.where(over[:, None], e2 - np.sqrt(np.maximum(reach**2 - a**2, 0))[:, None] * t,
                  mitre)
    fills = shapely.convex_hull(shapely.multipoints(np.stack([p, e1, c1, c2, e2], 1)[convex]))
    whole = shapely.union_all(np.concatenate([[base], strips, fills,
                                              np.asarray(extra or [], dtype=object)]))
    if whole.geom_type != "Polygon":  # cannot happen for a connected piece; be safe
        whole = max(getattr(whole, "geoms", [whole]), key=lambda q: q.area)
    sew_holes = [shapely.Polygon(h) for h in loops[1:]]
    holes = [shapely.Polygon(r) for r in whole.interiors]
    kept = [r for r in holes if any(h.intersects(r) for h in sew_holes)]
    # a hole too small for its allowance stays a hole: it is cut on its sew line
    lost = [h for h in sew_holes if not any(h.intersects(r) for r in kept)]
    cut = shapely.Polygon(whole.exterior, [r.exterior for r in kept])
    if lost:
        cut = cut.difference(shapely.union_all(lost))
    cut = _clean(cut)
    return shapely.geometry.polygon.orient(cut, 1.0)


def _clean(poly: shapely.Polygon, eps: float = 0.01) -> shapely.Polygon:
    """Drop the hair-thin spikes a union of many touching pieces can leave (a vertex that
    goes out and comes back along the same line: valid in floating point, invalid once
    moved and rounded), and the collinear points; changes nothing wider than ``eps`` mm."""
    poly = shapely.set_precision(poly, 1e-6)  # near-zero sides make GEOS's mitre divide by 0
    opened = poly.buffer(-eps, join_style="mitre", mitre_limit=10.0).buffer(
        eps, join_style="mitre", mitre_limit=10.0)
    if opened.geom_type != "Polygon":
        opened = max(getattr(opened, "geoms", [poly]), key=lambda q: q.area)
    return shapely.simplify(shapely.set_precision(opened, 1e-6), 1e-4)


def dart_runs(garment: Garment, piece: int) -> list[tuple[int, np.ndarray]]:
    """The darts of ``piece``: (seam line, loop vertices from one leg's mouth end, through
    the tip, to the other's). A dart is a self-seam whose two legs follow each other along
    the outline."""
    g = garment
    loop = g.piece_loops(piece)[0]
    pos = {int(v): k for k, v in enumerate(loop.tolist())}
    out = []
    for line, sl in enumerate(g.seam_lines):
        if sl.piece_a != piece or sl.piece_b != piece:
            continue
        rows = g.seam_edges[g.seam_line_of_edge == line]
        ks = sorted(pos[int(v)] for v in np.unique(rows) if int(v) in pos)
        if len(ks) < 3:
            continue
        # the two legs are one run of the loop: the largest gap is the rest of the outline
        gaps = np.diff(np.concatenate([ks, [ks[0] + len(loop)]]))
        if len(loop) - int(gaps.max()) + 1 != len(ks):
            continue  # not one run: a self-seam that is no dart
        start = ks[(int(np.argmax(gaps)) + 1) % len(ks)]
        out.append((line, np.roll(loop, -start)[: len(ks)]))
    return out


def dart_fills(garment: Garment, piece: int, allowance: np.ndarray, cap: float) -> list:
    """The cloth a pattern maker keeps over each dart of ``piece``.

    A dart's two legs are sewn to each other; the wedge between them folds under, so the
    cut line runs across its mouth as if the dart were closed: keep the wedge and the strip
    over the mouth (the larger allowance of the edges beside it), clipped to ``cap`` x
    that allowance from the sew line so the bound of the corners holds here too.
    """
    g = garment
    loop = g.piece_loops(piece)[0]
    pos = {int(v): k for k, v in enumerate(loop.tolist())}
    sew = shapely.Polygon(g.uv[loop])
    out = []
    for _, run in dart_runs(g, piece):
        wedge = shapely.make_valid(shapely.Polygon(g.uv[run]))
        a, b = g.uv[run[0]], g.uv[run[-1]]
        mouth = b - a
        if np.hypot(*mouth) < 1e-9:
            continue
        nrm = np.array([mouth[1], -mouth[0]]) / np.hypot(*mouth)
        if np.dot(g.uv[run].mean(0) - a, nrm) > 0:  # the strip goes away from the dart's tip
            nrm = -nrm
        w = float(max(allowance[pos[int(run[0])] - 1], allowance[pos[int(run[-1])]]))
        strip = shapely.Polygon([a, b, b + w * nrm, a + w * nrm])
        out.append(shapely.union(wedge, strip).intersection(sew.buffer(cap * w)))  # round
    return out


def cut_lines(garment: Garment, rules: AllowanceRules | None = None,
              pairs: Sequence[MirrorPair] | None = None) -> list[CutLine]:
    """Every piece's sew line, per-edge allowances and cut line (pattern mm); the mirror
    ``pairs`` (default: found) get mirrored allowances (:func:`pair_allowances`).

    The cut line follows the pattern's own curves where the garment has them
    (:attr:`Garment.edge_curves`: a specification's Beziers and arcs, within
    :data:`~solver.garment.curves.CHORD_TOL_MM`), each fine segment offset by the
    allowance of the mesh edge it lies on; the sew line stays the mesh's outline, whose
    edges the allowances and notches are counted on. A piece whose file draws its cut line
    (:attr:`Garment.cut_outlines`) is cut there, each sew edge's allowance measured to it."""
    rules = rules or AllowanceRules()
    per_piece = edge_allowances(garment, rules, pairs)
    out = []
    for i in range(garment.n_pieces):
        ids = garment.piece_loops(i)
        loops = [garment.uv[lp] for lp in ids]
        if i in garment.cut_outlines:
            out.append(_file_cut(loops, garment.cut_outlines[i]))
            continue
        darts = dart_fills(garment, i, per_piece[i][0], rules.cap)
        fine = [fine_loop(garment.uv, lp, garment.edge_curves) for lp in ids]
        cut = offset_outline([pts for pts, _ in fine],
                             [a[edge] for (_, edge), a in zip(fine, per_piece[i])],
                             cap=rules.cap, extra=darts)
        curved = fine[0] if garment.edge_curves else (None, None)
        out.append(CutLine(loops[0], loops[1:], per_piece[i][0], per_piece[i][1:], cut,
                           *curved))
    return out


def _file_cut(loops: list[np.ndarray], outline: np.ndarray) -> CutLine:
    """The cut line a pattern file draws around the sew ``loops``, with each sew edge's
    allowance as the file has it (its middle's distance to the cut line)."""
    cut = shapely.geometry.polygon.orient(shapely.Polygon(outline), 1.0)
    mids = [0.5 * (lp + np.roll(lp, -1, axis=0)) for lp in loops]
    gaps = [shapely.distance(shapely.points(m), cut.exterior) for m in mids]
    return CutLine(loops[0], loops[1:], gaps[0], gaps[1:], cut)
