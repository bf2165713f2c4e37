"""A DXF-AAMA / ASTM D6673 pattern read as a cutting room reads it: pieces, sizes, quantities.

Layers (AAMA): 1 cut line (84 its ASTM duplicate), 2 turn points, 4 notches, 6 mirror line,
7 grain line, 8 internal lines, 13 drill holes, 14 sew line. TEXTs: ``Piece Name:``,
``Size:``, ``Quantity:`` (AAMA: ``2``, an even count cut as left/right pairs; ASTM D6673:
``1,1``, as drawn and mirrored); the modelspace says ``Units:`` and ``Sample Size:``.

A graded file repeats every piece once per size, but AccuMark writes the notches, turn
points and quantity on the sample size only: every size is its own outline, and what it
lacks is carried from the sample size along the outline (graded outlines share their vertex
structure, so a notch keeps its segment and fraction; otherwise its share of the length).
Every length here is in millimetres, whatever the file's units.
"""

from __future__ import annotations

import math
import re
import warnings
from collections import Counter, defaultdict
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import shapely

import untrusted
from solver.garment.dxf_file import chain_rings, read_blocks, reflect, texts, units_scale
from solver.geometry import polygon_area
from solver.seams.darts import open_darts

__all__ = ["DxfPattern", "DxfPiece", "read_dxf_pattern"]


@dataclass
class DxfPiece:
    """One piece of one size, in mm, as the file draws it (a fold already unfolded)."""

    name: str
    size: str | None
    quantity: int
    cut: np.ndarray  # (n,2) cut line, counter-clockwise
    sew: np.ndarray | None = None  # (m,2) sew line, counter-clockwise
    sew_source: str = ""
    sew_guessed_mm: float = 0.0  # the sew line is the cut line inset by a guessed allowance
    grain: np.ndarray | None = None  # (2,2)
    fold: np.ndarray | None = None  # (2,2) the mirror line the piece was unfolded about
    notches: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    turns: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    drills: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    internal: list[np.ndarray] = field(default_factory=list)
    holes: list[np.ndarray] = field(default_factory=list)  # cut-outs (layer 11)
    carried: tuple[str, ...] = ()  # what came from the sample size
    mirrored: bool = False  # the right-hand copy of a piece cut as a left/right pair
    family: str = ""  # the pattern piece (name and size) a copy in the cut list was made of
    flipped: int | None = None  # of ``quantity``, how many mirrored (ASTM "a,b"; None: AAMA)

    @property
    def in_pairs(self) -> bool:
        """Whether its copies are cut as left/right pairs: an even AAMA count, or ASTM's
        as many mirrored as drawn."""
        return self.quantity % 2 == 0 and self.flipped in (None, self.quantity // 2)

    def mirror_copy(self) -> DxfPiece:
        """The other half of a left/right pair: every part mirrored left to right."""
        x0 = float(self.cut[:, 0].min() + self.cut[:, 0].max()) / 2

        def flip(p: np.ndarray) -> np.ndarray:
            p = np.asarray(p, float).reshape(-1, 2).copy()
            p[:, 0] = 2 * x0 - p[:, 0]
            return p

        return replace(self, cut=flip(self.cut)[::-1],
                       sew=None if self.sew is None else flip(self.sew)[::-1],
                       grain=None if self.grain is None else flip(self.grain),
                       fold=None if self.fold is None else flip(self.fold),
                       notches=[(flip(a)[0], d * np.array([-1.0, 1.0])) for a, d in self.notches],
                       turns=flip(self.turns), drills=flip(self.drills),
                       internal=[flip(q) for q in self.internal],
                       holes=[flip(q)[::-1] for q in self.holes], mirrored=not self.mirrored)


@dataclass
class DxfPattern:
    """The pieces of the chosen size(s) and what the reader had to decide, for the report."""

    pieces: list[DxfPiece]
    sizes: list[str]
    sample_size: str | None
    units: str
    source: str
    notes: list[str] = field(default_factory=list)

    def cut_list(self) -> list[DxfPiece]:
        """Every piece to cut: ``Quantity: 0`` left out, an even quantity cut as left/right
        pairs (the second of each pair mirrored), an odd one as that many copies; an ASTM
        ``a,b`` other than as many mirrored as drawn: ``a`` copies, then ``b`` mirrored."""
        out = []
        many = len({p.size for p in self.pieces}) > 1
        for p in self.pieces:
            base = f"{p.name} {p.size}" if many and p.size else p.name
            for k in range(p.quantity):
                if not p.in_pairs:  # copies, the last ``flipped`` of them mirrored
                    q = p.mirror_copy() if k >= p.quantity - (p.flipped or 0) else p
                    out.append(replace(q, name=f"{base} #{k + 1}" if p.quantity > 1 else base,
                                       family=base))
                else:  # left and right halves of pairs
                    tag = ("L", "R")[k % 2] + (f"{k // 2 + 1}" if p.quantity > 2 else "")
                    q = p.mirror_copy() if k % 2 else p
                    out.append(replace(q, name=f"{base} {tag}", family=base))
        return out


def _polylines(entities, layer: str, scale: float) -> list[np.ndarray]:
    out = []
    for e in entities:
        if str(e.dxf.layer) != layer:
            continue
        if e.dxftype() == "POLYLINE":
            pts = np.array([tuple(p)[:2] for p in e.points()], float).reshape(-1, 2)
            out.append(np.vstack([pts, pts[:1]]) if e.is_closed else pts)
        elif e.dxftype() == "LWPOLYLINE":
            pts = np.array([tuple(p)[:2] for p in e.get_points("xy")], float).reshape(-1, 2)
            out.append(np.vstack([pts, pts[:1]]) if e.closed else pts)
        elif e.dxftype() == "LINE":
            out.append(np.array([tuple(e.dxf.start)[:2], tuple(e.dxf.end)[:2]], float))
    return [p * scale for p in out]


def _points(entities, layer: str, scale: float) -> np.ndarray:
    pts = [tuple(e.dxf.location)[:2] for e in entities
           if str(e.dxf.layer) == layer and e.dxftype() == "POINT"]
    return np.array(pts, float).reshape(-1, 2) * scale


def _notches(entities, scale: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """(point on the outline, unit direction into the piece) of each notch on layer 4, as
    CADs draw them: a POINT with an angle, a slit (a LINE from the outline inwards), or a
    V (an open polyline, or two LINEs meeting at the tip) whose mouth is on the outline."""
    out, slits = [], []
    for e in entities:
        if str(e.dxf.layer) != "4":
            continue
        if e.dxftype() == "POINT":
            ang = math.radians(e.dxf.get("angle", 0.0) or 0.0)
            out.append((np.array(tuple(e.dxf.location)[:2]) * scale,
                        np.array([math.cos(ang), math.sin(ang)])))
        elif e.dxftype() == "LINE":
            slits.append(np.array([tuple(e.dxf.start)[:2], tuple(e.dxf.end)[:2]]) * scale)
        elif e.dxftype() in ("LWPOLYLINE", "POLYLINE") and not _closed_entity(e):
            pts = _polylines([e], "4", scale)[0]
            out.append(_slit(pts) if len(pts) == 2 else _v_notch(pts[0], pts[-1], pts[1:-1]))
    return out + _slit_notches(slits)


def _closed_entity(e) -> bool:
    return bool(e.closed if e.dxftype() == "LWPOLYLINE" else e.is_closed)


def _slit(ab: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = float(np.linalg.norm(ab[1] - ab[0]))
    return ab[0], (ab[1] - ab[0]) / n if n > 0 else np.array([1.0, 0.0])


def _v_notch(end_a: np.ndarray, end_b: np.ndarray, inner: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """A V's mouth (midway between its two ends, on the outline) and its way to the tip
    (of its ``inner`` vertices, the farthest from the mouth)."""
    mouth = 0.5 * (end_a + end_b)
    tip = inner[np.argmax(np.linalg.norm(inner - mouth, axis=1))]
    return _slit(np.array([mouth, tip]))


def _slit_notches(lines: list[np.ndarray], tol: float = 0.01) -> list[tuple[np.ndarray,
                                                                            np.ndarray]]:
    """Slits, and V notches drawn as two LINEs sharing their tip (one notch, not two)."""
    out, used = [], set()
    for i, a in enumerate(lines):
        if i in used:
            continue
        for j in range(i + 1, len(lines)):
            b = lines[j]
            shared = [(p, q) for p in (0, 1) for q in (0, 1)
                      if j not in used and np.linalg.norm(a[p] - b[q]) < tol]
            if shared:
                p, q = shared[0]
                out.append(_v_notch(a[1 - p], b[1 - q], np.array([a[p]])))
                used |= {i, j}
                break
        else:
            out.append(_slit(a))
    return out


def _ccw(ring: np.ndarray) -> np.ndarray:
    """The ring counter-clockwise (a CAD draws pieces either way; shapely's area is
    unsigned, so the shoelace sign decides)."""
    return ring[::-1].copy() if polygon_area(ring) < 0 else ring


def _largest_ring(parts: list[np.ndarray], tol: float) -> np.ndarray | None:
    rings = chain_rings(parts, tol)
    return max(rings, key=lambda r: abs(shapely.Polygon(r).area)) if rings else None


def _quantity(text: str | None, where: str) -> tuple[int, int | None] | None:
    """(copies, of them mirrored or None) of a ``Quantity:`` text: AAMA's ``N`` (None:
    pairs by the count), ASTM D6673's ``a,b`` (``a`` as drawn, ``b`` mirrored)."""
    if text is None or not text.strip():
        return None
    counts = [_count(part, text, where) for part in text.split(",", 1)]
    total = sum(counts)
    if total > untrusted.limits.MAX_DEMAND:
        raise ValueError(f"{where}: quantity is over {untrusted.limits.MAX_DEMAND} copies")
    return total, counts[1] if len(counts) == 2 else None


def _count(part: str, text: str, where: str) -> int:
    try:
        q = float(part)
    except ValueError:
        raise ValueError(f"{where}: Quantity {text[:40]!r} is not a number") from None
    if q > untrusted.limits.MAX_DEMAND:  # inf too
        raise ValueError(f"{where}: quantity is over {untrusted.limits.MAX_DEMAND} copies")
    if not q >= 0 or q != int(q):  # NaN too
        raise ValueError(f"{where}: Quantity {text[:40]!r} is not a whole number of copies")
    return int(q)


def _raw_piece(block: str, entities, scale: float, where: str) -> DxfPiece:
    """One block as drawn (half a piece if it has a mirror line), in mm."""
    text = texts(entities)
    name = text.get("piece name") or block
    at = f"{where}: piece {name[:80]!r}"
    boundary = _polylines(entities, "1", scale) or _polylines(entities, "84", scale)
    if not boundary:
        raise ValueError(f"{at} has no boundary on layer 1")
    flat = np.vstack(boundary)
    if not np.isfinite(flat).all():
        raise ValueError(f"{at}: a boundary point is not a finite number")
    tol = 1e-6 * max(float(np.ptp(flat, axis=0).max()), 1e-9) + 1e-6
    cut = _largest_ring(boundary, tol)
    if cut is None:
        raise ValueError(f"{at}: the boundary on layer 1 is not a closed line")
    sew = _largest_ring(_polylines(entities, "14", scale), tol)
    grain = _polylines(entities, "7", scale)
    mirror = _polylines(entities, "6", scale)
    qty = _quantity(text.get("quantity"), at)
    return DxfPiece(name=name, size=text.get("size") or None,
                    quantity=-1 if qty is None else qty[0], flipped=None if qty is None else qty[1],
                    cut=_ccw(cut), sew=None if sew is None else _ccw(sew),
                    sew_source="the file's sew line (layer 14)" if sew is not None else "",
                    grain=grain[0][[0, -1]] if grain else None,
                    fold=mirror[0][[0, -1]] if mirror else None,
                    notches=_notches(entities, scale), turns=_points(entities, "2", scale),
                    drills=_points(entities, "13", scale),
                    internal=_polylines(entities, "8", scale),
                    holes=chain_rings(_polylines(entities, "11", scale), tol))


def _unfold_ring(ring: np.ndarray, line: np.ndarray, tol: float) -> np.ndarray:
    whole = shapely.union(shapely.Polygon(ring).buffer(0),
                          shapely.Polygon(reflect(ring, line)).buffer(0))
    whole = whole.buffer(tol, join_style="mitre").buffer(-tol, join_style="mitre")
    if whole.geom_type == "MultiPolygon":
        whole = max(whole.geoms, key=lambda g: g.area)
    whole = shapely.geometry.polygon.orient(shapely.simplify(whole, tol), 1.0)
    return np.asarray(whole.exterior.coords)[:-1]


def unfold(p: DxfPiece) -> DxfPiece:
    """A half piece cut on the fold (mirror line, layer 6) made whole: outline and sew line
    united with their mirror images, every mark mirrored too; ``fold`` keeps the centre."""
    if p.fold is None or np.linalg.norm(p.fold[1] - p.fold[0]) == 0:
        return p
    line = p.fold
    tol = 1e-4 * float(np.ptp(p.cut, axis=0).max())

    def both(q: np.ndarray) -> np.ndarray:
        q = np.asarray(q, float).reshape(-1, 2)
        return np.vstack([q, reflect(q, line)]) if len(q) else q

    def lin(d: np.ndarray) -> np.ndarray:
        return reflect(d[None], line - line[0])[0]  # a direction, mirrored about the origin

    return replace(p, cut=_unfold_ring(p.cut, line, tol),
                   sew=None if p.sew is None else _unfold_ring(p.sew, line, tol),
                   notches=p.notches + [(reflect(a[None], line)[0], lin(d)) for a, d in p.notches],
                   turns=both(p.turns), drills=both(p.drills),
                   internal=p.internal + [reflect(q, line) for q in p.internal],
                   holes=p.holes + [reflect(q, line) for q in p.holes])


def _along(points: np.ndarray, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Points on (or near) the closed outline ``src`` carried to the graded outline ``dst``:
    the same segment and fraction when the two share their vertex structure (a graded size),
    else the same share of the outline's length from the same start."""
    points = np.asarray(points, float).reshape(-1, 2)
    if not len(points):
        return points
    a, b = src, np.roll(src, -1, axis=0)
    ab = b - a
    t = np.clip(np.einsum("pkj,kj->pk", points[:, None] - a[None], ab)
                / np.maximum((ab * ab).sum(1), 1e-300), 0, 1)
    foot = a[None] + t[..., None] * ab[None]
    seg = np.argmin(((foot - points[:, None]) ** 2).sum(-1), axis=1)
    frac = t[np.arange(len(points)), seg]
    if len(src) == len(dst):
        da, db = dst[seg], np.roll(dst, -1, axis=0)[seg]
        return da + frac[:, None] * (db - da)
    s_len = np.concatenate([[0], np.cumsum(np.linalg.norm(ab, axis=1))])
    share = (s_len[seg] + frac * np.linalg.norm(ab[seg], axis=1)) / s_len[-1]
    d_seg = np.linalg.norm(np.roll(dst, -1, axis=0) - dst, axis=1)
    d_len = np.concatenate([[0], np.cumsum(d_seg)])
    at = share * d_len[-1]
    k = np.clip(np.searchsorted(d_len, at, side="right") - 1, 0, len(dst) - 1)
    f = (at - d_len[k]) / np.maximum(d_seg[k], 1e-300)
    return dst[k] + f[:, None] * (np.roll(dst, -1, axis=0)[k] - dst[k])


def _graded(p: DxfPiece, sample: DxfPiece) -> DxfPiece:
    """``p`` with what its size lacks carried from the sample size's piece ``sample``."""
    carried = []
    out = p
    if p.quantity < 0:
        out, carried = replace(out, quantity=sample.quantity, flipped=sample.flipped), \
            carried + ["quantity"]
    if not p.notches and sample.notches:
        moved = _along(np.array([a for a, _ in sample.notches]), sample.cut, p.cut)
        tips = _along(np.array([a + d for a, d in sample.notches]), sample.cut, p.cut)
        out = replace(out, notches=[(a, (t - a) / max(np.linalg.norm(t - a), 1e-12))
                                    for a, t in zip(moved, tips, strict=True)])
        carried.append("notches")
    if not len(p.turns) and len(sample.turns):
        out, carried = replace(out, turns=_along(sample.turns, sample.cut, p.cut)), \
            carried + ["turn points"]
    if p.grain is None and sample.grain is not None:
        shift = p.cut.mean(0) - sample.cut.mean(0)
        out, carried = replace(out, grain=sample.grain + shift), carried + ["grain line"]
    return replace(out, carried=tuple(carried))


def _with_sew(p: DxfPiece, allowance_mm: float | None, allowance_from: str,
              where: str, guessed: bool = True) -> DxfPiece:
    """The sew line a piece without layer 14 implies: its cut line inset by the allowance
    (``guessed``: not the file's own). A piece narrower than twice the allowance (a binding
    strip) has none, and that is said."""
    if p.sew is not None or not allowance_mm:
        return p
    inner = shapely.Polygon(p.cut).buffer(-allowance_mm, join_style="mitre", mitre_limit=2.0)
    if inner.is_empty:
        warnings.warn(f"{where}: piece {p.name!r} is too narrow for a {allowance_mm:g} mm "
                      "seam allowance on every side: it gets no sew line (give its sew line "
                      "on layer 14, or a smaller --seam-allowance)", stacklevel=3)
        return p
    if inner.geom_type != "Polygon":
        inner = max(inner.geoms, key=lambda q: q.area)
    ring = np.asarray(shapely.geometry.polygon.orient(inner, 1.0).exterior.coords)[:-1]
    # a CAD's cut line runs across a dart's mouth: the notches and drill hole open it again
    ring, darts = open_darts(ring, np.array([a for a, _ in p.notches]), p.drills)
    return replace(p, sew=ring, sew_source=f"the cut line inset by {allowance_mm:g} mm "
                   f"({allowance_from})" + (f", {darts} dart(s) opened" if darts else ""),
                   sew_guessed_mm=allowance_mm if guessed else 0.0)


def _file_allowance(doc, scale: float) -> float | None:
    raw = texts(doc.modelspace()).get("seam allowance")
    m = re.match(r"\s*([0-9.]+)", raw or "")
    return float(m.group(1)) * scale if m else None


def _wanted_sizes(path: Path, sizes: list[str], sample: str | None,
                  size: str | list[str] | None) -> list[str] | None:
    """The sizes to read (None: every piece): a graded file gives its sample size by
    default, an ungraded one everything; a size the file lacks is refused by name."""
    if size is None:
        return [sample] if len(sizes) > 1 else None
    wanted = [size] if isinstance(size, str) else list(size)
    if not sizes:
        raise ValueError(f"{path}: no size {', '.join(wanted)}: the file has no sizes "
                         "(no Size: texts)")
    missing = [s for s in wanted if s not in sizes]
    if missing:
        raise ValueError(f"{path}: no size {', '.join(missing)}; sizes are {', '.join(sizes)}")
    return wanted


def _decisions(pieces: list[DxfPiece], sample: str | None) -> list[str]:
    """What the reader decided, one line each: pieces not cut, what was carried where."""
    notes = [f"piece {p.name!r} size {p.size}: Quantity 0, not cut"
             for p in pieces if p.quantity == 0]
    groups: dict[str, list[str]] = defaultdict(list)
    for p in pieces:
        for what in p.carried:
            groups[what].append(p.size or "")
    return notes + [f"{what} carried from sample size {sample} to size(s) "
                    f"{', '.join(sorted(set(got)))}" for what, got in groups.items()]


def _line_notes(pieces: list[DxfPiece]) -> list[str]:
    """Where the lines the station cuts and sews on come from, one line per source."""
    sources = Counter(p.sew_source or "none: the piece is sewn on its cut line"
                      for p in pieces)
    return ["cut line: the file's layer 1, as the pattern maker drew it (the allowance "
            "it carries is the file's)",
            *(f"sew line of {n} piece(s): {src}" for src, n in sources.items())]


def read_dxf_pattern(path: str | Path, *, size: str | list[str] | None = None,
                     units: str | None = None, allowance_mm: float | None = None,
                     allowance_from: str = "--seam-allowance",
                     unfold_folds: bool = True) -> DxfPattern:
    """The pieces of ``size`` (default: the sample size) of a DXF-AAMA/ASTM file, in mm.

    Folds are unfolded, what a graded size lacks is carried from the sample size, and the
    sew line is the file's (layer 14), else the cut line inset by the file's ``Seam
    Allowance:``, else by ``allowance_mm`` (whose origin ``allowance_from`` names).
    """
    doc, path, blocks = read_blocks(path)
    if not blocks:
        raise ValueError(f"{path}: no pattern pieces (no INSERTed block with a layer-1 boundary)")
    scale, unit_note = units_scale(doc, path, units)
    raw = [_raw_piece(name, ents, scale, str(path)) for name, ents in blocks]
    sizes = [s for s in dict.fromkeys(p.size for p in raw) if s]
    sample = texts(doc.modelspace()).get("sample size")
    sample = sample if sample in sizes else (sizes[0] if sizes else None)
    wanted = _wanted_sizes(path, sizes, sample, size)
    by_name: dict[str, DxfPiece] = {}
    for p in raw:
        if p.size == sample or p.name not in by_name:
            by_name[p.name] = p
    file_allowance = _file_allowance(doc, scale)
    if file_allowance is not None:
        allowance_mm, allowance_from = file_allowance, "the file's Seam Allowance"
    guessed = file_allowance is None
    pieces = []
    for p in raw:
        if wanted is not None and p.size not in wanted:
            continue
        p = _graded(p, by_name[p.name])  # before unfolding: graded sizes share vertices
        p = unfold(p) if unfold_folds else p
        p = replace(p, quantity=1) if p.quantity < 0 else p
        pieces.append(_with_sew(p, allowance_mm, allowance_from, str(path), guessed))
    notes = [f"units: {unit_note}", *_decisions(pieces, sample), *_line_notes(pieces)]
    return DxfPattern(pieces, sizes, sample, unit_note.split()[0], str(path), notes)
