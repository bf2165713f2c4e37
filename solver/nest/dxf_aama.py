"""DXF-AAMA / ASTM D6673 pattern files: read pieces for nesting, and write them back.

A cutting room receives its pieces from pattern CAD (Gerber AccuMark, Lectra, CLO) as
AutoCAD R12 DXF where every piece is a BLOCK (placed by one INSERT) and the meaning of an
entity is its layer number (AAMA/ASTM D6673):

    1 boundary (cut line; often split in several open POLYLINEs), 4 notches,
    6 mirror line (the block holds half the piece), 7 grain line, 8 internal lines,
    11 internal cut-outs, 13 drill holes, 14 sew line (stitch line),
    84 ASTM boundary curve (duplicate of 1)

and TEXT entities in the block say ``Piece Name:``, ``Size:``, ``Quantity:``; the
modelspace says ``Units: ENGLISH`` (inches) or ``METRIC`` (mm). ezdxf does the file
format; this module only interprets the layers.
"""

from __future__ import annotations

import math
import re
import warnings
from collections import defaultdict
from pathlib import Path

import ezdxf
import numpy as np
import shapely

import untrusted
from solver.nest.instance import Piece, affine, rotation

__all__ = ["dxf_sizes", "read_dxf_aama", "write_dxf_aama"]

_INSUNITS_MM = {1: 25.4, 2: 304.8, 4: 1.0, 5: 10.0, 6: 1000.0}
_TEXT = re.compile(r"^\s*([A-Za-z ]+?)\s*:\s*(.*?)\s*$")


def _texts(entities) -> dict[str, str]:
    out = {}
    for e in entities:
        if e.dxftype() == "TEXT":
            m = _TEXT.match(e.dxf.text)
            if m:
                out.setdefault(m.group(1).lower(), m.group(2))
    return out


def _scale(doc, path: Path, units: str | None) -> float:
    if units is not None:
        table = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4, "inch": 25.4}
        if units not in table:
            raise ValueError(f"unknown units {units!r}; expected mm, cm, m or in")
        return table[units]
    declared = _texts(doc.modelspace()).get("units", "").upper()
    if declared.startswith("ENGLISH") or declared.startswith("INCH"):
        return 25.4
    if declared.startswith("METRIC"):
        return 1.0
    code = doc.header.get("$INSUNITS", 0)
    if code in _INSUNITS_MM:
        return _INSUNITS_MM[code]
    raise ValueError(f"{path}: the file does not say its units (no 'Units:' text, no $INSUNITS);"
                     " give them with units='mm' or 'in'")


def _chain(parts: list[np.ndarray], tol: float) -> list[np.ndarray]:
    """Join open polylines end to end into closed rings (AccuMark splits the boundary)."""
    parts = [p for p in parts if len(p) >= 2]
    rings = []
    while parts:
        cur = parts.pop(0)
        grown = True
        while grown and np.linalg.norm(cur[0] - cur[-1]) > tol:
            grown = False
            for k, p in enumerate(parts):
                if np.linalg.norm(p[0] - cur[-1]) <= tol:
                    cur = np.vstack([cur, p[1:]])
                elif np.linalg.norm(p[-1] - cur[-1]) <= tol:
                    cur = np.vstack([cur, p[::-1][1:]])
                elif np.linalg.norm(p[-1] - cur[0]) <= tol:
                    cur = np.vstack([p, cur[1:]])
                elif np.linalg.norm(p[0] - cur[0]) <= tol:
                    cur = np.vstack([p[::-1], cur[1:]])
                else:
                    continue
                parts.pop(k)
                grown = True
                break
        if len(cur) >= 4 and np.linalg.norm(cur[0] - cur[-1]) <= tol:
            rings.append(cur[:-1])
        elif len(cur) >= 3:
            rings.append(cur)  # an open boundary: closed by its last segment
    return rings


def _reflect(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    a, b = line
    d = (b - a) / np.linalg.norm(b - a)
    v = points - a
    return a + 2 * np.outer(v @ d, d) - v


def _sew_inward(outline: np.ndarray, allowance_mm: float | None, what: str
                ) -> np.ndarray | None:
    """The sew line a file without layer 14 implies: the cut line moved in by the allowance.

    A piece narrower than twice the allowance (a loop, a binding strip) has none; that is
    said (a warning naming ``what``), since the file's pieces are otherwise taken as cut."""
    if not allowance_mm:
        return None
    inner = shapely.Polygon(outline).buffer(-allowance_mm, join_style="mitre", mitre_limit=2.0)
    if inner.is_empty:
        warnings.warn(f"{what} is too narrow for a {allowance_mm:g} mm seam allowance on "
                      "every side: it gets no sew line (give its sew line on layer 14, or "
                      "a smaller --seam-allowance)", stacklevel=2)
        return None
    if inner.geom_type != "Polygon":
        inner = max(inner.geoms, key=lambda q: q.area)
    return np.asarray(shapely.geometry.polygon.orient(inner, 1.0).exterior.coords)[:-1]


def _piece_from_block(entities: list, name_default: str, scale: float, unfold: bool,
                      where: str, allowance_mm: float | None = None) -> Piece:
    by_layer = defaultdict(list)
    for e in entities:
        by_layer[str(e.dxf.layer)].append(e)
    text = _texts(entities)
    name = text.get("piece name", name_default) or name_default

    def polylines(layer: str) -> list[np.ndarray]:
        out = []
        for e in by_layer.get(layer, []):
            if e.dxftype() == "POLYLINE":
                pts = np.array([tuple(p)[:2] for p in e.points()], float)
                out.append(np.vstack([pts, pts[:1]]) if e.is_closed else pts)
            elif e.dxftype() == "LWPOLYLINE":
                pts = np.array([tuple(p)[:2] for p in e.get_points("xy")], float)
                out.append(np.vstack([pts, pts[:1]]) if e.closed else pts)
            elif e.dxftype() == "LINE":
                out.append(np.array([tuple(e.dxf.start)[:2], tuple(e.dxf.end)[:2]], float))
        return [p * scale for p in out]

    boundary = polylines("1") or polylines("84")
    if not boundary:
        raise ValueError(f"{where}: piece {name!r} has no boundary on layer 1")
    if not np.isfinite(np.vstack(boundary)).all():
        raise ValueError(f"{where}: piece {name!r}: a boundary point is not a finite number")
    span = max(float(np.ptp(np.vstack(boundary), axis=0).max()), 1e-9)
    rings = _chain(boundary, 1e-6 * span + 1e-6)
    if not rings:
        raise ValueError(f"{where}: piece {name!r}: the boundary on layer 1 is not a closed line")
    outline = max(rings, key=lambda r: abs(shapely.Polygon(r).area))
    sew_rings = _chain(polylines("14"), 1e-6 * span + 1e-6)
    sew_line = max(sew_rings, key=lambda r: abs(shapely.Polygon(r).area)) if sew_rings else None
    holes = [r for r in _chain(polylines("11"), 1e-6 * span + 1e-6)]
    grain = polylines("7")
    grainline = grain[0][[0, -1]] if grain else None
    notches = []
    for e in by_layer.get("4", []):
        if e.dxftype() == "POINT":
            at = np.array(tuple(e.dxf.location)[:2]) * scale
            ang = math.radians(e.dxf.get("angle", 0.0) or 0.0)
            notches.append((at, np.array([math.cos(ang), math.sin(ang)])))
        elif e.dxftype() == "LINE":
            a = np.array(tuple(e.dxf.start)[:2]) * scale
            b = np.array(tuple(e.dxf.end)[:2]) * scale
            n = np.linalg.norm(b - a)
            notches.append((a, (b - a) / n if n > 0 else np.array([1.0, 0.0])))
    marks = np.array([tuple(e.dxf.location)[:2] for e in by_layer.get("13", [])
                      if e.dxftype() == "POINT"], float).reshape(-1, 2) * scale
    mirror = polylines("6")
    if unfold and mirror:
        line = mirror[0][[0, -1]]
        tol = 1e-4 * span
        whole = shapely.union(shapely.Polygon(outline),
                              shapely.Polygon(_reflect(outline, line)).buffer(0))
        whole = whole.buffer(tol, join_style="mitre").buffer(-tol, join_style="mitre")
        if whole.geom_type == "MultiPolygon":
            whole = max(whole.geoms, key=lambda g: g.area)
        outline = shapely.simplify(whole, tol).exterior.coords[:-1]
        if sew_line is not None:
            sew = shapely.union(shapely.Polygon(sew_line),
                                shapely.Polygon(_reflect(sew_line, line)).buffer(0))
            sew = sew.buffer(tol, join_style="mitre").buffer(-tol, join_style="mitre")
            if sew.geom_type == "MultiPolygon":
                sew = max(sew.geoms, key=lambda g: g.area)
            sew_line = np.asarray(shapely.simplify(sew, tol).exterior.coords[:-1])
        notches += [(_reflect(a[None], line)[0], _reflect(a[None] + d[None], line)[0]
                     - _reflect(a[None], line)[0]) for a, d in notches]
        if len(marks):
            marks = np.vstack([marks, _reflect(marks, line)])
    try:
        quantity = int(float(text.get("quantity", "1") or 1))
    except ValueError:
        quantity = 1
    except OverflowError:  # "inf"
        quantity = untrusted.limits.MAX_DEMAND + 1
    if quantity > untrusted.limits.MAX_DEMAND:
        raise ValueError(f"{where}: piece {name!r}: quantity is over "
                         f"{untrusted.limits.MAX_DEMAND} copies")
    outline = np.asarray(outline, float)
    if sew_line is None:
        sew_line = _sew_inward(outline, allowance_mm, f"{where}: piece {name!r}")
    elif shapely.Polygon(sew_line).area < 0:
        sew_line = sew_line[::-1]
    if sew_line is not None:
        sew_line = np.asarray(shapely.geometry.polygon.orient(
            shapely.Polygon(sew_line), 1.0).exterior.coords)[:-1]
    piece = Piece(name, outline, quantity=max(quantity, 1), holes=holes,
                  grainline=grainline, notches=notches, marks=marks,
                  size=text.get("size") or None, sew_line=sew_line)
    if grainline is not None:  # reference frame: the grain along the roll (+x)
        d = grainline[1] - grainline[0]
        if np.linalg.norm(d) > 0:
            piece.base = rotation(-math.degrees(math.atan2(d[1], d[0])))
    return piece


class _BadPlacement(ValueError):
    """An INSERT whose placement no pattern CAD writes (kept apart from ezdxf's own errors)."""


# A piece is placed at scale 1 (rarely a grading or unit factor) and turned within a turn;
# beyond these bounds the transform is degenerate or its float rounding meaningless.
_SCALE_RANGE = (1e-6, 1e6)
_MAX_ROTATION_DEG = 3600.0


def _check_placement(ins, path: Path) -> None:
    """Refuse an INSERT of scale 0, NaN or huge, or of a NaN or huge rotation, by name."""
    where = f"{path}: INSERT of block {str(ins.dxf.name)[:80]!r}"
    for axis in ("xscale", "yscale", "zscale"):
        s = float(ins.dxf.get(axis, 1.0))
        if not _SCALE_RANGE[0] <= abs(s) <= _SCALE_RANGE[1]:  # False for NaN
            raise _BadPlacement(f"{where}: {axis} {s:g} is not usable (its size must be "
                                f"{_SCALE_RANGE[0]:g} to {_SCALE_RANGE[1]:g})")
    turn = float(ins.dxf.get("rotation", 0.0))
    if not abs(turn) <= _MAX_ROTATION_DEG:
        raise _BadPlacement(f"{where}: rotation {turn:g} degrees is not usable (at most "
                            f"{_MAX_ROTATION_DEG:g} either way)")


def _blocks(path: str | Path):
    path = untrusted.check_file(path, what="DXF file", max_bytes=untrusted.limits.MAX_DXF_BYTES)
    out = []
    try:
        doc = ezdxf.readfile(path)
        for ins in doc.modelspace().query("INSERT"):
            _check_placement(ins, path)
            ents = list(ins.virtual_entities())  # applies the INSERT's placement
            if any(str(e.dxf.layer) in ("1", "84") for e in ents):
                out.append((ins.dxf.name, ents))
    except _BadPlacement:
        raise
    except OSError as exc:
        raise ValueError(f"{path}: not a readable DXF file ({exc})") from None
    except (ezdxf.DXFError, ValueError, TypeError, IndexError, KeyError, AttributeError,
            OverflowError) as exc:
        # ezdxf meets malformed bytes with assorted errors: all mean "not a valid DXF"
        raise ValueError(f"{path}: not a valid DXF file ({type(exc).__name__}: "
                         f"{' '.join(str(exc).split())[:200]})") from None
    return doc, path, out


def dxf_sizes(path: str | Path) -> list[str]:
    """The sizes present in a graded file, in file order."""
    _, _, blocks = _blocks(path)
    sizes = []
    for _, ents in blocks:
        s = _texts(ents).get("size")
        if s and s not in sizes:
            sizes.append(s)
    return sizes


def read_dxf_aama(path: str | Path, *, size: str | list[str] | None = None,
                  units: str | None = None, unfold: bool = True,
                  allowance_mm: float | None = None) -> list[Piece]:
    """Pieces (mm) of a DXF-AAMA/ASTM file: outline = the cut line (layer 1).

    The sew line is layer 14 where the piece has one, else the cut line moved inward by
    ``allowance_mm`` (None or 0: the piece has no sew line).

    ``size`` picks the size(s) to cut when the file is graded (several sizes); by default
    a graded file gives its sample size (``Sample Size:``) or else its first size.
    ``unfold`` makes whole pieces of half pieces that carry a mirror line (layer 6).
    Each piece's ``base`` turns its grain line along +x.
    """
    doc, path, blocks = _blocks(path)
    if not blocks:
        raise ValueError(f"{path}: no pattern pieces (no INSERTed block with a layer-1 boundary)")
    scale = _scale(doc, path, units)
    sizes = [s for s in dict.fromkeys(_texts(e).get("size") for _, e in blocks) if s]
    if size is None and len(sizes) > 1:
        sample = _texts(doc.modelspace()).get("sample size")
        size = sample if sample in sizes else sizes[0]
    wanted = None if size is None else ([size] if isinstance(size, str) else list(size))
    if wanted is not None and sizes:
        unknown = [s for s in wanted if s not in sizes]
        if unknown:
            raise ValueError(f"{path}: no size {', '.join(unknown)}; sizes are "
                             f"{', '.join(sizes)}")
    pieces = []
    for name, ents in blocks:
        s = _texts(ents).get("size")
        if wanted is not None and sizes and s not in wanted:
            continue
        p = _piece_from_block(ents, name, scale, unfold, str(path), allowance_mm)
        if wanted is not None and len(wanted) > 1 and s:
            p.name = f"{p.name} {s}"
        pieces.append(p)
    return pieces


def write_dxf_aama(pieces: list[Piece], path: str | Path, *, style: str = "station") -> None:
    """Write pieces (mm, input coordinates) as DXF-AAMA R12: one BLOCK + INSERT per piece.

    Each block holds the outline = cut line (layer 1, closed), the sew line (14, closed,
    where the piece has one), cut-outs (11), the grain line (7),
    notches as POINTs with their direction angle (4), drill holes (13) and the TEXTs
    ``Piece Name``, ``Size``, ``Quantity``; it round-trips through :func:`read_dxf_aama`.
    """
    doc = ezdxf.new("R12")
    msp = doc.modelspace()
    for k, line in enumerate([f"Style Name: {style}", "Units: METRIC"]):
        msp.add_text(line, dxfattribs={"layer": "1", "height": 5.0, "insert": (0, -10 * k)})
    used = set()
    for p in pieces:
        bname = re.sub(r"[^A-Za-z0-9_ -]", "_", f"{p.name}_{p.size}" if p.size else p.name)
        while bname in used:
            bname += "_"
        used.add(bname)
        blk = doc.blocks.new(name=bname)
        blk.add_polyline2d([tuple(map(float, q)) for q in p.outline], close=True,
                           dxfattribs={"layer": "1"})
        if p.sew_line is not None:
            blk.add_polyline2d([tuple(map(float, q)) for q in p.sew_line], close=True,
                               dxfattribs={"layer": "14"})
        for h in p.holes:
            blk.add_polyline2d([tuple(map(float, q)) for q in h], close=True,
                               dxfattribs={"layer": "11"})
        if p.grainline is not None:
            blk.add_line(tuple(map(float, p.grainline[0])), tuple(map(float, p.grainline[1])),
                         dxfattribs={"layer": "7"})
        for at, d, _ in p.notches:
            blk.add_point(tuple(map(float, at)), dxfattribs={
                "layer": "4", "angle": math.degrees(math.atan2(d[1], d[0])) % 360.0})
        for m in np.asarray(p.marks, float).reshape(-1, 2):
            blk.add_point(tuple(map(float, m)), dxfattribs={"layer": "13"})
        texts = [f"Piece Name: {p.name}", f"Quantity: {p.quantity}"]
        if p.size:
            texts.insert(1, f"Size: {p.size}")
        x0, y0 = p.outline.min(0)
        for k, line in enumerate(texts):
            blk.add_text(line, dxfattribs={"layer": "1", "height": 3.0,
                                           "insert": (float(x0), float(y0) - 5.0 * (k + 1))})
        msp.add_blockref(bname, (0, 0), dxfattribs={"layer": "1"})
    doc.saveas(Path(path))


def transformed(piece: Piece, m: np.ndarray) -> Piece:
    """A copy of ``piece`` with every geometric part mapped by the (2, 3) affine ``m``."""
    lin = m[:, :2]
    return Piece(piece.name, affine(m, piece.outline), piece.quantity, piece.orientations,
                 piece.mirrored_pair, holes=[affine(m, h) for h in piece.holes],
                 grainline=None if piece.grainline is None else affine(m, piece.grainline),
                 notches=[(affine(m, a)[0], lin @ d, h) for a, d, h in piece.notches],
                 marks=affine(m, piece.marks), size=piece.size,
                 sew_line=None if piece.sew_line is None else affine(m, piece.sew_line),
                 allowance=piece.allowance)
