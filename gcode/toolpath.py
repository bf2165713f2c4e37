"""Toolpaths from a layout: kerf offset, notches, marks, contour and piece order, lead-ins, tabs.

Cut order inside a piece is marks, holes, notches, then the outline: once the outline is
cut the piece can shift, so everything inside it goes first. Start points and the order of
pieces are chosen to keep rapid travel short (nearest neighbour, then 2-opt).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely
from shapely.geometry import LinearRing, Point, Polygon

from gcode.arcs import FittedPath, fit_arcs
from gcode.layout import Layout, LayoutPiece
from gcode.machine import Machine

__all__ = ["Contour", "PieceToolpath", "build_toolpaths", "check_on_table", "fabric_box",
           "open_contour", "order_pieces", "two_opt"]


@dataclass
class Contour:
    """One feature to cut: kind is ``mark``, ``hole``, ``notch`` or ``outline``.

    ``strokes`` are the tool-down runs (one, unless tabs or knife corners split it); a stroke
    with no primitives is a plunge (a knife marking a point).
    """

    kind: str
    closed: bool
    strokes: list[FittedPath]
    points: np.ndarray  # (n,2) the cut polyline before fitting (closed: first point repeated)


@dataclass
class PieceToolpath:
    index: int  # index of the piece in the layout
    id: str
    name: str
    contours: list[Contour] = field(default_factory=list)
    polygon: Polygon | None = None  # the piece itself (not offset), for checks and reports
    warnings: list[str] = field(default_factory=list)

    @property
    def entry(self) -> np.ndarray:
        s = self.contours[0].strokes[0]
        return s.start

    @property
    def exit(self) -> np.ndarray:
        s = self.contours[-1].strokes[-1]
        return s.end[-1] if len(s) else s.start


# ---------------------------------------------------------------- ordering

def two_opt(order: np.ndarray, d: np.ndarray, d0: np.ndarray, max_rounds: int = 50) -> np.ndarray:
    """Improve an open path that starts at a fixed depot (distances ``d0``) by 2-opt moves.

    Each round evaluates every reversal [i..j] for one i at once (vectorised over j) and
    applies the best improving one.
    """
    order = np.asarray(order).copy()
    n = len(order)
    if n < 3:
        return order
    for _ in range(max_rounds * n):
        improved = False
        for i in range(n - 1):
            prev_cost = d0[order[i]] if i == 0 else d[order[i - 1], order[i]]
            a_prev = order[i - 1] if i > 0 else -1
            js = np.arange(i + 1, n)
            b = order[js]
            nxt = np.where(js + 1 < n, order[np.minimum(js + 1, n - 1)], -1)
            old = prev_cost + np.where(nxt >= 0, d[b, np.maximum(nxt, 0)], 0.0)
            new_first = d0[b] if a_prev < 0 else d[a_prev, b]
            new = new_first + np.where(nxt >= 0, d[order[i], np.maximum(nxt, 0)], 0.0)
            gain = old - new
            k = int(np.argmax(gain))
            if gain[k] > 1e-9:
                j = int(js[k])
                order[i:j + 1] = order[i:j + 1][::-1]
                improved = True
        if not improved:
            break
    return order


def order_pieces(samples: list[np.ndarray], start: np.ndarray) -> np.ndarray:
    """Order pieces to limit travel: nearest neighbour from ``start`` then 2-opt.

    ``samples[i]`` (k_i,2) are points on piece i's outline; the distance between two pieces
    is the smallest distance between their samples (a piece is entered where it is closest).
    """
    n = len(samples)
    if n == 0:
        return np.zeros(0, int)
    counts = np.array([len(s) for s in samples])
    allpts = np.vstack(samples)
    owner = np.repeat(np.arange(n), counts)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    d = np.empty((n, n))
    for i, s in enumerate(samples):  # one row of pieces at a time keeps memory at O(k * total)
        rows = np.hypot(s[:, None, 0] - allpts[None, :, 0], s[:, None, 1] - allpts[None, :, 1])
        d[i] = np.minimum.reduceat(rows.min(axis=0), starts)
    np.fill_diagonal(d, 0.0)
    d0 = np.full(n, np.inf)
    np.minimum.at(d0, owner, np.hypot(*(allpts - start).T))
    order = [int(np.argmin(d0))]
    left = np.ones(n, bool)
    left[order[0]] = False
    for _ in range(n - 1):
        row = np.where(left, d[order[-1]], np.inf)
        k = int(np.argmin(row))
        order.append(k)
        left[k] = False
    return two_opt(np.array(order), d, d0)


# ---------------------------------------------------------------- geometry helpers

def _ring_coords(ring: LinearRing) -> np.ndarray:
    c = np.asarray(ring.coords)[:, :2]
    return c[:-1] if np.allclose(c[0], c[-1]) else c


def _rotate_to(ring: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """The ring (n,2) starting at its vertex nearest ``pos``, closed (first point repeated)."""
    k = int(np.argmin(np.hypot(*(ring - pos).T)))
    r = np.roll(ring, -k, axis=0)
    return np.vstack([r, r[:1]])


def _waste_normal(closed: np.ndarray) -> np.ndarray:
    """Unit normal at the start of a closed polyline pointing to its right (the waste side
    for a CCW outline and for a CW hole)."""
    t = closed[1] - closed[-2]
    t = t / max(float(np.hypot(*t)), 1e-12)
    return np.array([t[1], -t[0]])


def _split_by_length(closed: np.ndarray, cuts: np.ndarray) -> list[np.ndarray]:
    """Pieces of a polyline between pairs of arc-length stations ``cuts`` (m,2) [from, to]."""
    seg = np.hypot(*np.diff(closed, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    out = []
    for a, b in cuts:
        if b - a <= 1e-9:
            continue
        inner = (s > a) & (s < b)
        pa = np.array([np.interp(a, s, closed[:, 0]), np.interp(a, s, closed[:, 1])])
        pb = np.array([np.interp(b, s, closed[:, 0]), np.interp(b, s, closed[:, 1])])
        out.append(np.vstack([pa, closed[inner], pb]))
    return out


def _tab_strokes(closed: np.ndarray, tabs: int, width: float) -> list[np.ndarray]:
    """Cut runs of a closed polyline that leave ``tabs`` uncut bridges of ``width`` mm."""
    total = float(np.hypot(*np.diff(closed, axis=0).T).sum())
    if tabs <= 0 or tabs * width >= total * 0.5:
        return [closed]
    centres = total * (np.arange(tabs) + 0.5) / tabs
    starts = np.concatenate([[0.0], centres + width / 2])
    ends = np.concatenate([centres - width / 2, [total]])
    return _split_by_length(closed, np.stack([starts, ends], axis=1))


def _corner_split(poly: np.ndarray, max_turn_deg: float) -> list[np.ndarray]:
    """Split a polyline at vertices where the direction turns more than ``max_turn_deg``."""
    if len(poly) < 3:
        return [poly]
    v = np.diff(poly, axis=0)
    a = np.arctan2(v[:, 1], v[:, 0])
    turn = np.abs((np.diff(a) + np.pi) % (2 * np.pi) - np.pi)
    idx = np.flatnonzero(turn > np.radians(max_turn_deg)) + 1
    parts = np.split(np.arange(len(poly)), idx)
    out = []
    for k, part in enumerate(parts):
        lo = part[0]
        hi = part[-1] + 1 if k + 1 < len(parts) else part[-1]
        out.append(poly[lo:hi + 1])
    return [p for p in out if len(p) >= 2]


def _fit(points: np.ndarray, machine: Machine) -> FittedPath:
    if machine.cut.arcs and len(points) >= 4:
        return fit_arcs(points, machine.cut.tolerance)
    return FittedPath.lines(points)


def _polygon(piece: LayoutPiece, source: str) -> Polygon:
    poly = Polygon(piece.outline, piece.holes)
    if not poly.is_valid:
        fixed = poly.buffer(0)
        lost = abs(fixed.area - abs(poly.area)) > 1e-3 * abs(poly.area)
        if not isinstance(fixed, Polygon) or lost:
            raise ValueError(f"{source}: piece {piece.id!r} outline is not a simple polygon "
                             f"({shapely.is_valid_reason(poly)})")
        poly = fixed
    if poly.area <= 0:
        raise ValueError(f"{source}: piece {piece.id!r} has zero area")
    return shapely.geometry.polygon.orient(poly, 1.0)


def _inward(poly: Polygon, at: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """The notch direction pointing into the piece (the layout may give either sense)."""
    d = direction
    if not np.any(d):
        ring = np.asarray(poly.exterior.coords)
        k = int(np.argmin(np.hypot(*(ring[:-1] - at).T)))
        t = ring[k + 1] - ring[k - 1 if k > 0 else -2]
        d = np.array([-t[1], t[0]]) / max(float(np.hypot(*t)), 1e-12)  # left of CCW = inside
    eps = 0.25
    inside_plus = poly.contains(Point(*(at + eps * d)))
    inside_minus = poly.contains(Point(*(at - eps * d)))
    return d if inside_plus or not inside_minus else -d


# ---------------------------------------------------------------- building

def _piece_features(piece: LayoutPiece, poly: Polygon, machine: Machine, gap: float,
                    source: str) -> tuple[list, list, list, np.ndarray, list[str]]:
    c = machine.cut
    warnings: list[str] = []
    half = c.kerf / 2
    cut = poly.buffer(half, join_style="mitre", mitre_limit=4.0) if half > 0 else poly
    if not isinstance(cut, Polygon):
        cut = max(cut.geoms, key=lambda g: g.area)
    cut = shapely.geometry.polygon.orient(cut, 1.0)
    outer = _ring_coords(cut.exterior)
    holes = [_ring_coords(r) for r in cut.interiors]
    if len(holes) < len(poly.interiors):
        warnings.append(f"piece {piece.id}: {len(poly.interiors) - len(holes)} hole(s) smaller "
                        "than the kerf were dropped")
    marks = [m for m in piece.marks]
    notches = []
    for n in piece.notches:
        inward = _inward(poly, n.at, n.direction)
        edge = n.at - inward * half
        # the layout's depth keeps the slit inside the seam allowance, clear of the sew line
        depth = c.notch_depth if n.depth is None else min(c.notch_depth, n.depth)
        if c.notch == "slit":
            notches.append(np.vstack([n.at + inward * depth, edge]))
        else:
            t = np.array([-inward[1], inward[0]]) * c.notch_width / 2
            notches.append(np.vstack([edge + t, n.at + inward * depth, edge - t]))
    del source, gap
    return marks, holes, notches, outer, warnings


def _order_open(items: list[np.ndarray], pos: np.ndarray, reversible: bool
                ) -> tuple[list[np.ndarray], np.ndarray]:
    """Nearest-neighbour order of open polylines, each entered at its nearer end."""
    left = list(items)
    out = []
    while left:
        d_first = np.array([np.hypot(*(p[0] - pos)) for p in left])
        d_last = (np.array([np.hypot(*(p[-1] - pos)) for p in left]) if reversible
                  else d_first + np.inf)
        k = int(np.argmin(np.minimum(d_first, d_last)))
        p = left.pop(k)
        if d_last[k] < d_first[k]:
            p = p[::-1]
        out.append(p)
        pos = p[-1]
    return out, pos


def _order_rings(rings: list[np.ndarray], pos: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """Nearest-neighbour order of closed rings, each started at its vertex nearest the head."""
    left = list(rings)
    out = []
    while left:
        d = np.array([np.hypot(*(r - pos).T).min() for r in left])
        r = _rotate_to(left.pop(int(np.argmin(d))), pos)
        out.append(r)
        pos = r[0]
    return out, pos


def _lead_in(closed: np.ndarray, length: float, waste: Polygon | None) -> np.ndarray:
    """Prepend a lead-in point on the waste side (shortened until it stays in the waste)."""
    if length <= 0:
        return closed
    nrm = _waste_normal(closed)
    for _ in range(6):
        p = closed[0] + nrm * length
        if waste is None or waste.contains(Point(*p)):
            return np.vstack([p, closed])
        length /= 2
    return closed


def check_on_table(layout: Layout, machine: Machine) -> None:
    """Refuse, naming the cause, a marker that runs past the table's end along the roll.

    A selvedge is an edge of the cloth, so a kerf beyond it is left out (`_on_fabric`);
    the table's end is not: the cloth runs on and the piece would be cut short. Without
    this check the program's own work-area check names a move and blames the kerf.
    """
    if not layout.pieces:
        return
    x0, x1 = machine.work_area[0], machine.work_area[2]
    xs = np.concatenate([p.outline[:, 0] for p in layout.pieces])
    lo, hi = float(xs.min()), float(xs.max())
    if lo < x0 - 1e-6 or hi > x1 + 1e-6:
        raise ValueError(
            f"{layout.source}: the marker runs from x={lo:.1f} to x={hi:.1f} mm, outside the "
            f"work area: the table ({machine.name}) cuts x={x0:g} to {x1:g} mm: nest it with "
            f"--length {x1 - layout.origin[0]:g} or less (station.toml [nest] length_mm)")


def fabric_box(layout: Layout) -> Polygon | None:
    """The cloth on the table (machine mm): its two selvedges and its start; the roll runs
    on past the marker's end (x = length), so that is no edge. None: no width given."""
    if layout.width <= 0:
        return None
    x0, y0 = layout.origin
    return shapely.box(x0, y0, x0 + 2 * max(layout.length, 0.0) + 1e6, y0 + layout.width)


def _on_fabric(runs: list[np.ndarray], fabric: Polygon | None) -> list[np.ndarray]:
    """The parts of the cut runs that lie over the fabric.

    A piece may touch the fabric's edge (no gap): its kerf-offset outline then runs half a
    kerf beyond the edge, where there is no cloth to cut, and on a fabric laid at the
    table's corner, beyond the machine's travel. The nester cannot fix this (the kerf is
    the machine's, not the marker's), so the toolpath leaves those runs out: the fabric's
    own edge is the piece's edge there, within half a kerf of its cut line.
    """
    if fabric is None:
        return runs
    grown = fabric.buffer(1e-9, join_style="mitre")
    out = []
    for run in runs:
        line = shapely.LineString(run)
        if grown.covers(line):
            out.append(run)
            continue
        part = shapely.line_merge(shapely.intersection(line, fabric))
        out += [np.asarray(g.coords)[:, :2] for g in getattr(part, "geoms", [part])
                if g.geom_type == "LineString" and g.length > 1e-6]
    return out


def build_piece(piece: LayoutPiece, index: int, machine: Machine, pos: np.ndarray,
                gap: float = 0.0, source: str = "<layout>",
                fabric: Polygon | None = None) -> PieceToolpath:
    """The toolpath of one piece, entered from head position ``pos``.

    ``fabric`` (machine mm) trims the outline's cut to the cloth (see :func:`_on_fabric`),
    less the chordal tolerance an arc fit may stray by.
    """
    c = machine.cut
    poly = _polygon(piece, source)
    marks, holes, notches, outer, warnings = _piece_features(piece, poly, machine, gap, source)
    tp = PieceToolpath(index=index, id=piece.id, name=piece.name, polygon=poly, warnings=warnings)
    knife = machine.tool == "knife"

    if len(marks):
        pts = np.asarray(marks, float).reshape(-1, 2)
        order, _ = _order_open([p[None] for p in pts], pos, reversible=False)
        for p in order:
            p = p[0]
            if knife:
                tp.contours.append(Contour("mark", False, [FittedPath.lines(p[None])], p[None]))
            else:
                s = c.mark_size
                a = np.array([[p[0] - s, p[1]], [p[0] + s, p[1]]])
                b = np.array([[p[0], p[1] - s], [p[0], p[1] + s]])
                tp.contours.append(Contour("mark", False, [FittedPath.lines(a),
                                                           FittedPath.lines(b)], p[None]))
            pos = p
    ordered_holes, pos = _order_rings(holes, pos)
    for ring in ordered_holes:
        hole_poly = Polygon(ring)
        closed = _lead_in(ring, c.lead_in, hole_poly)
        tp.contours.append(_contour("hole", True, closed, machine))
    if fabric is not None:  # arcs may stray by the tolerance: keep that much inside
        fabric = fabric.buffer(-c.tolerance, join_style="mitre")
    notches = _on_fabric(notches, fabric)  # a notch's start half a kerf out, off the cloth
    ordered_notches, pos = _order_open(notches, pos, reversible=True)
    for p in ordered_notches:
        tp.contours.append(_contour("notch", False, p, machine))
    ring = _rotate_to(outer, pos)
    over_edge = fabric is not None and not fabric.buffer(1e-9, join_style="mitre").covers(
        shapely.LineString(ring))
    if over_edge:
        runs = _on_fabric(_tab_strokes(ring, c.tabs, c.tab_width) if knife else [ring], fabric)
        strokes = []
        for run in runs:
            strokes.extend(_fit(s, machine) for s in (
                _corner_split(run, machine.knife.corner_angle) if knife else [run]))
        tp.contours.append(Contour("outline", False, strokes, ring))
    elif knife and c.tabs > 0:
        runs = _tab_strokes(ring, c.tabs, c.tab_width)
        strokes = []
        for run in runs:
            strokes.extend(_fit(s, machine) for s in _corner_split(run, machine.knife.corner_angle))
        tp.contours.append(Contour("outline", True, strokes, ring))
    else:
        # the lead-in stays in this piece's half of the gap, clear of the neighbour's kerf
        lead_room = max(gap / 2 - c.kerf, 0.0)
        if c.lead_in > 0 and lead_room <= 0:
            tp.warnings.append(f"piece {piece.id}: no lead-in, the layout leaves no gap for it")
        waste = Polygon(ring).buffer(lead_room + 1e-6).difference(Polygon(ring))
        closed = _lead_in(ring, min(c.lead_in, lead_room), waste)
        tp.contours.append(_contour("outline", True, closed, machine))
    return tp


def open_contour(kind: str, points: np.ndarray, machine: Machine) -> Contour:
    """One run of ``kind`` along ``points`` as a single stroke (a resumed remainder)."""
    return Contour(kind, False, [_fit(points, machine)], points)


def _contour(kind: str, closed: bool, points: np.ndarray, machine: Machine) -> Contour:
    runs = [points]
    if machine.tool == "knife":
        runs = _corner_split(points, machine.knife.corner_angle)
    return Contour(kind, closed, [_fit(r, machine) for r in runs], points)


def build_toolpaths(layout: Layout, machine: Machine, *, only: set[str] | None = None
                    ) -> list[PieceToolpath]:
    """Toolpaths of the layout's pieces (all, or those whose id is in ``only``) in cut order."""
    pieces = [(i, p) for i, p in enumerate(layout.pieces) if only is None or p.id in only]
    check_on_table(layout, machine)
    if only is not None:
        missing = only - {p.id for _, p in pieces}
        if missing:
            raise ValueError(f"{layout.source}: no piece with id {sorted(missing)}")
    samples = []
    for _, p in pieces:
        ring = p.outline
        step = max(1, len(ring) // 48)
        samples.append(ring[::step])
    park = np.asarray(machine.park, float)
    order = order_pieces(samples, park)
    pos = park
    out = []
    for k in order:
        i, p = pieces[int(k)]
        tp = build_piece(p, i, machine, pos, gap=layout.gap, source=layout.source,
                         fabric=fabric_box(layout))
        out.append(tp)
        pos = tp.exit
    return out
