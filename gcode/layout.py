"""Reading LAYOUT.json (written by the nesting step) into plain arrays.

Outlines in LAYOUT.json are already in fabric millimetres (x along the roll, y across it);
``origin`` places the fabric on the table, so machine = fabric + origin.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import shapely

import untrusted

__all__ = ["Layout", "LayoutPiece", "Notch", "load_layout", "layout_from_dict", "on_table"]


@dataclass
class Notch:
    """A notch at ``at`` on the outline; ``direction`` points along the slit (either sense)."""

    at: np.ndarray  # (2,) float, machine mm
    direction: np.ndarray  # (2,) float, unit
    depth: float | None = None  # the most the piece allows (half its seam allowance), mm


@dataclass
class LayoutPiece:
    """One placed piece in machine millimetres."""

    id: str
    name: str
    outline: np.ndarray  # (n,2) float, closed ring, CCW, first point not repeated
    holes: list[np.ndarray] = field(default_factory=list)  # each (m,2) float
    notches: list[Notch] = field(default_factory=list)
    marks: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # (k,2) float
    grainline: np.ndarray | None = None  # (2,2) float or None
    transform: np.ndarray | None = None  # (2,3) float, pattern -> fabric, kept for reports


@dataclass
class Layout:
    """The pieces to cut, their fabric and where the fabric lies on the table."""

    pieces: list[LayoutPiece]
    width: float = 0.0
    length: float = 0.0
    gap: float = 0.0
    origin: tuple[float, float] = (0.0, 0.0)
    source: str = "<layout>"


def _points(value, source: str, where: str, *, min_len: int = 1) -> np.ndarray:
    return untrusted.points(value, source, where, min_len=min_len)


def _listed(piece: dict, key: str, source: str, where: str,
            max_len: int = untrusted.limits.MAX_PANEL_POINTS) -> list:
    """``piece[key]`` as a list (absent or null: empty); a number or text there is a fault."""
    value = piece.get(key)
    if value is None:
        return []
    return untrusted.sequence(value, source, f"{where}.{key}", max_len=max_len)


def _ring(value, source: str, where: str) -> np.ndarray:
    ring = _points(value, source, where, min_len=3)
    if np.allclose(ring[0], ring[-1]) and len(ring) > 3:
        ring = ring[:-1]  # tolerate a repeated closing point
    return ring


def _notch(value, source: str, where: str, off: np.ndarray) -> Notch:
    n = untrusted.mapping(value, source, where)
    at = untrusted.vector(n.get("at"), source, f"{where}.at") + off
    d = untrusted.vector(n.get("direction", [0.0, 0.0]), source, f"{where}.direction")
    depth = None if n.get("depth") is None else untrusted.number(
        n["depth"], source, f"{where}.depth", lo=0.0, hi=1000.0, lo_open=True)
    nd = float(np.hypot(*d))
    return Notch(at, d / nd if nd > 0 else d, depth)


EDGE_SLACK_MM = 1.0  # how far an outline may stray past the fabric's edge (rounding)


def _check_on_fabric(ring: np.ndarray, width: float, source: str, where: str) -> None:
    """Err if a piece (fabric mm) leaves the cloth: before the roll's start or beyond a
    selvedge. The toolpath trims cuts to the cloth, so such a piece would be cut short, or,
    lying wholly off it, not at all."""
    lo, hi = ring.min(axis=0), ring.max(axis=0)
    if lo[0] < -EDGE_SLACK_MM or lo[1] < -EDGE_SLACK_MM or hi[1] > width + EDGE_SLACK_MM:
        raise untrusted.InputError(
            source, f"{where} leaves the fabric: it spans x {lo[0]:g}..{hi[0]:g}, "
            f"y {lo[1]:g}..{hi[1]:g} mm; the cloth starts at x = 0 and spans y 0..{width:g} mm")


def _check_holes_inside(outline: np.ndarray, holes: list[np.ndarray], source: str,
                        where: str) -> None:
    """Err if a hole is not inside its piece: the toolpath cuts holes as the piece's inner
    rings, and one outside it was dropped without a word (or would cut the cloth around)."""
    piece = shapely.Polygon(outline).buffer(1e-6)
    for k, hole in enumerate(holes):
        if not piece.covers(shapely.Polygon(hole)):
            raise untrusted.InputError(source, f"{where}.holes[{k}] is not inside the "
                                       "piece's outline")


def layout_from_dict(data: dict, source: str = "<layout>") -> Layout:
    """Check a LAYOUT.json dict and return it in machine coordinates (fabric + origin)."""
    lim = untrusted.limits
    data = untrusted.mapping(data, source)
    if data.get("version", 1) != 1:
        raise untrusted.InputError(source, f"unsupported layout version {data.get('version')!r}")
    if data.get("units", "mm") != "mm":
        raise untrusted.InputError(source, f"units must be \"mm\", got {data.get('units')!r}")
    if not isinstance(data.get("pieces"), list):
        raise untrusted.InputError(source, "missing \"pieces\" list")
    pieces_in = untrusted.sequence(data["pieces"], source, "pieces", max_len=lim.MAX_PIECES)
    off = untrusted.vector(data.get("origin") or [0.0, 0.0], source, "origin")
    pieces: list[LayoutPiece] = []
    seen: set[str] = set()
    total = 0
    for i, p in enumerate(pieces_in):
        where = f"pieces[{i}]"
        if not isinstance(p, dict) or "outline" not in p:
            raise untrusted.InputError(source, f"{where}: expected an object with an "
                                       "\"outline\"")
        pid = str(p.get("id", f"piece{i}"))
        if pid in seen:
            raise untrusted.InputError(source, f"{where}: duplicate id {pid!r}")
        seen.add(pid)
        outline = _ring(p["outline"], source, f"{where}.outline") + off
        features = {key: _listed(p, key, source, where, lim.MAX_FEATURES_PER_PIECE)
                    for key in ("holes", "notches", "marks")}
        total += sum(map(len, features.values()))
        if total > lim.MAX_LAYOUT_FEATURES:
            raise untrusted.InputError(source, f"{where}: more than "
                                       f"{lim.MAX_LAYOUT_FEATURES:,} marks, notches and holes "
                                       "in the layout")
        holes = [_ring(h, source, f"{where}.holes[{k}]") + off
                 for k, h in enumerate(features["holes"])]
        _check_holes_inside(outline, holes, source, where)
        notches = [_notch(n, source, f"{where}.notches[{k}]", off)
                   for k, n in enumerate(features["notches"])]
        marks_in = features["marks"]
        marks = (_points(marks_in, source, f"{where}.marks") + off) if marks_in \
            else np.zeros((0, 2))
        grain = p.get("grainline")
        grain_arr = _points(grain, source, f"{where}.grainline", min_len=2) + off \
            if grain else None
        tr = p.get("transform")
        pieces.append(LayoutPiece(
            id=pid, name=str(p.get("name", pid)), outline=outline, holes=holes, notches=notches,
            marks=marks, grainline=grain_arr,
            transform=None if tr is None else untrusted.matrix(tr, source, f"{where}.transform",
                                                               (2, 3))))
    size = {k: untrusted.number(data.get(k, 0.0) or 0.0, source, k, lo=0.0,
                                hi=lim.MAX_COORD_MM) for k in ("width", "length", "gap")}
    if size["width"] > 0:
        for i, piece in enumerate(pieces):
            _check_on_fabric(piece.outline - off, size["width"], source, f"pieces[{i}].outline")
    return Layout(pieces=pieces, width=size["width"], length=size["length"], gap=size["gap"],
                  origin=(float(off[0]), float(off[1])), source=source)


def on_table(layout: Layout, origin: tuple[float, float]) -> Layout:
    """``layout`` with its fabric laid at ``origin`` on the table: every machine coordinate
    moves with the fabric (machine = fabric + origin); ``transform`` stays pattern ->
    fabric. The one way a marker is put where the station's fabric lies."""
    d = np.asarray(origin, float) - np.asarray(layout.origin, float)
    pieces = [replace(p, outline=p.outline + d, holes=[h + d for h in p.holes],
                      notches=[replace(n, at=n.at + d) for n in p.notches], marks=p.marks + d,
                      grainline=None if p.grainline is None else p.grainline + d)
              for p in layout.pieces]
    return replace(layout, pieces=pieces, origin=(float(origin[0]), float(origin[1])))


def load_layout(path: str | Path) -> Layout:
    """Read LAYOUT.json; every fault is a one-line ValueError naming the file."""
    return layout_from_dict(untrusted.read_json(path, what="layout"), str(path))
