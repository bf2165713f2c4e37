"""Reading LAYOUT.json (written by the nesting step) into plain arrays.

Outlines in LAYOUT.json are already in fabric millimetres (x along the roll, y across it);
``origin`` places the fabric on the table, so machine = fabric + origin.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["Layout", "LayoutPiece", "Notch", "load_layout", "layout_from_dict"]


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


def _points(value, where: str, *, min_len: int = 1) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: expected a list of [x, y] points") from None
    if arr.ndim != 2 or arr.shape[1] != 2 or len(arr) < min_len:
        raise ValueError(f"{where}: expected at least {min_len} [x, y] points, "
                         f"got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{where}: non-finite coordinate")
    return arr


def _ring(value, where: str) -> np.ndarray:
    ring = _points(value, where, min_len=3)
    if np.allclose(ring[0], ring[-1]) and len(ring) > 3:
        ring = ring[:-1]  # tolerate a repeated closing point
    return ring


def layout_from_dict(data: dict, source: str = "<layout>") -> Layout:
    """Check a LAYOUT.json dict and return it in machine coordinates (fabric + origin)."""
    if not isinstance(data, dict):
        raise ValueError(f"{source}: expected a JSON object")
    if data.get("version", 1) != 1:
        raise ValueError(f"{source}: unsupported layout version {data.get('version')!r}")
    if data.get("units", "mm") != "mm":
        raise ValueError(f"{source}: units must be \"mm\", got {data.get('units')!r}")
    pieces_in = data.get("pieces")
    if not isinstance(pieces_in, list):
        raise ValueError(f"{source}: missing \"pieces\" list")
    origin = data.get("origin") or [0.0, 0.0]
    off = _points([origin], f"{source}: origin")[0]
    pieces: list[LayoutPiece] = []
    seen: set[str] = set()
    for i, p in enumerate(pieces_in):
        where = f"{source}: pieces[{i}]"
        if not isinstance(p, dict) or "outline" not in p:
            raise ValueError(f"{where}: expected an object with an \"outline\"")
        pid = str(p.get("id", f"piece{i}"))
        if pid in seen:
            raise ValueError(f"{where}: duplicate id {pid!r}")
        seen.add(pid)
        outline = _ring(p["outline"], f"{where}.outline") + off
        holes = [_ring(h, f"{where}.holes[{k}]") + off for k, h in enumerate(p.get("holes") or [])]
        notches = []
        for k, n in enumerate(p.get("notches") or []):
            try:
                at = np.asarray(n["at"], float).reshape(2) + off
                d = np.asarray(n.get("direction", [0.0, 0.0]), float).reshape(2)
                depth = None if n.get("depth") is None else float(n["depth"])
            except (KeyError, TypeError, ValueError):
                raise ValueError(f"{where}.notches[{k}]: expected {{\"at\": [x, y], "
                                 "\"direction\": [dx, dy]}") from None
            if depth is not None and not (np.isfinite(depth) and depth > 0):
                raise ValueError(f"{where}.notches[{k}]: depth must be a positive number")
            nd = float(np.hypot(*d))
            notches.append(Notch(at, d / nd if nd > 0 else d, depth))
        marks_in = p.get("marks") or []
        marks = (_points(marks_in, f"{where}.marks") + off) if len(marks_in) else np.zeros((0, 2))
        grain = p.get("grainline")
        grain_arr = _points(grain, f"{where}.grainline", min_len=2) + off if grain else None
        tr = p.get("transform")
        pieces.append(LayoutPiece(
            id=pid, name=str(p.get("name", pid)), outline=outline, holes=holes, notches=notches,
            marks=marks, grainline=grain_arr,
            transform=np.asarray(tr, float) if tr is not None else None))
    return Layout(pieces=pieces, width=float(data.get("width", 0.0) or 0.0),
                  length=float(data.get("length", 0.0) or 0.0),
                  gap=float(data.get("gap", 0.0) or 0.0),
                  origin=(float(off[0]), float(off[1])), source=source)


def load_layout(path: str | Path) -> Layout:
    """Read LAYOUT.json; every fault is a one-line ValueError naming the file."""
    p = Path(path)
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FileNotFoundError(f"{p}: layout not found") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{p}: not valid JSON: {exc}") from None
    return layout_from_dict(data, str(p))
