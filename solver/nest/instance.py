"""Nesting input: pieces, quantities, allowed orientations, mirrored pairs, the fabric.

A :class:`Piece` is given in its own *input* coordinates (DXF, ESICUP instance or
garment pattern). ``base`` maps those to the piece's *reference frame*: on plain
fabric the frame with the grain line along the roll (x); on printed fabric the
aligned position on the print (PLACEMENT.json), so that any move we then make must be
a symmetry of the print. Every copy to place is an :class:`Item`; its *candidates* are
the affine maps (2, 3) it may undergo in the reference frame before a translation
(rotations about the origin on plain fabric, the print's own operations on printed
fabric), and ``lattice`` (2, 2 columns) restricts that translation to whole lattice
vectors when a print is present.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import shapely

import untrusted
from solver.geometry import polygon_area
from solver.geometry import rotation_affine as rotation  # dxf_aama imports it from here
from solver.jsonfile import read_json
from solver.wallpaper import gauss_reduce

IDENTITY = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
MIRROR_X = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # reflection about the grain (x) axis
FREE_ANGLES = tuple(float(a) for a in range(0, 360, 45))  # sampled when rotation is free


def affine(m: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Apply a (2, 3) affine map to (n, 2) points."""
    p = np.asarray(p, float).reshape(-1, 2)
    return p @ m[:, :2].T + m[:, 2]


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The (2, 3) map ``a ∘ b`` (b first)."""
    return np.column_stack([a[:, :2] @ b[:, :2], a[:, :2] @ b[:, 2] + a[:, 2]])


def invert(m: np.ndarray) -> np.ndarray:
    inv = np.linalg.inv(m[:, :2])
    return np.column_stack([inv, -inv @ m[:, 2]])


def angle_of(m: np.ndarray, mirrored: bool) -> float:
    """Rotation angle (deg, in [0, 360)) of a linear part ``R(θ)`` or ``R(θ)·diag(1, -1)``."""
    return float(np.degrees(np.arctan2(m[1, 0], m[0, 0])) % 360.0)


def angle_allowed(angle: float, allowed: tuple[float, ...] | None, tol: float = 1e-4) -> bool:
    if allowed is None:
        return True
    d = (np.asarray(allowed, float) - angle + 180.0) % 360.0 - 180.0
    return bool(np.any(np.abs(d) <= tol))


def ccw_ring(points) -> np.ndarray:
    """(n, 2) closed ring, counter-clockwise, last point not repeated."""
    p = np.asarray(points, float).reshape(-1, 2)
    if len(p) > 1 and np.allclose(p[0], p[-1]):
        p = p[:-1]
    if len(p) < 3:
        raise ValueError(f"a piece outline needs at least 3 points, got {len(p)}")
    if polygon_area(p) < 0:
        p = p[::-1]
    return p


@dataclass
class Piece:
    """One pattern piece to cut ``quantity`` times (and mirrored too if ``mirrored_pair``)."""

    name: str
    outline: np.ndarray
    quantity: int = 1
    orientations: tuple[float, ...] | None = (0.0, 180.0)  # None: free rotation
    mirrored_pair: bool = False
    base: np.ndarray = field(default_factory=lambda: IDENTITY.copy())
    holes: list[np.ndarray] = field(default_factory=list)
    grainline: np.ndarray | None = None  # (2, 2) input coordinates
    # (at, direction, depth): depth None lets the cutter choose; given, it is the most the
    # seam allowance takes
    notches: list[tuple] = field(default_factory=list)
    marks: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    size: str | None = None
    garment: str | None = None  # the order's garment the piece belongs to (with ``size``)
    sew_line: np.ndarray | None = None  # (k, 2) the sew line inside the cut line ``outline``
    allowance: np.ndarray | None = None  # (k,) mm per sew-line edge sew_line[j] -> [j + 1]

    def __post_init__(self) -> None:
        try:
            self.outline = ccw_ring(self.outline)
        except ValueError as exc:
            raise ValueError(f"piece {self.name!r}: {exc}") from None
        if not shapely.Polygon(self.outline).is_valid:
            raise ValueError(f"piece {self.name!r}: the outline crosses itself")
        if int(self.quantity) < 1:
            raise ValueError(f"piece {self.name!r}: quantity must be at least 1")
        self.quantity = int(self.quantity)
        self.notches = [(np.asarray(n[0], float), np.asarray(n[1], float),
                         None if len(n) < 3 or n[2] is None else float(n[2]))
                        for n in self.notches]
        if self.sew_line is not None:
            self.sew_line = np.asarray(self.sew_line, float).reshape(-1, 2)
        if self.orientations is not None:
            self.orientations = tuple(float(a) % 360.0 for a in self.orientations) or (0.0,)
        self.base = np.asarray(self.base, float).reshape(2, 3)

    @property
    def area(self) -> float:
        return float(shapely.Polygon(self.outline).area)


@dataclass(frozen=True)
class PiecePair:
    """Pieces ``first`` and ``second`` (indices into ``NestProblem.pieces``) are a left/right
    pair kept ``mode`` ("mirror" or "same") by the alignment; ``mirror`` (2, 3) maps the
    first's input coordinates onto their mirror images on the second."""

    first: int
    second: int
    mode: str
    mirror: np.ndarray


@dataclass
class NestProblem:
    """Pieces on a roll of ``width`` (y), optionally limited in ``length`` (x, the table)."""

    pieces: list[Piece]
    width: float
    length: float | None = None
    gap: float = 0.0
    fabric: object | None = None  # solver.wallpaper.Wallpaper
    keepouts: list[np.ndarray] = field(default_factory=list)
    name: str = ""
    allowance: dict | None = None  # the rules garments' cut lines were made with (reported)
    pairs: list[PiecePair] = field(default_factory=list)  # left/right pairs of garments

    def __post_init__(self) -> None:
        if not self.pieces:
            raise ValueError("nothing to nest: no pieces")
        if not (self.width > 2 * self.gap >= 0):
            raise ValueError(f"fabric width {self.width} must exceed twice the gap {self.gap}")
        if self.length is not None and not self.length > 2 * self.gap:
            raise ValueError(f"fabric length {self.length} must exceed twice the gap")
        self.keepouts = [ccw_ring(k) for k in self.keepouts]

    def items(self) -> list[Item]:
        """Every copy to place, with its candidate maps (see the module docstring)."""
        out: list[Item] = []
        for index, piece in enumerate(self.pieces):
            for mirrored in (False, True) if piece.mirrored_pair else (False,):
                cands = candidate_maps(piece, mirrored, self.fabric)
                ref = affine(piece.base, piece.outline)
                for k in range(piece.quantity):
                    out.append(Item(f"{piece.name}#{k + 1}{'m' if mirrored else ''}", piece.name,
                                    index, mirrored, ref, cands, self.lattice))
        return out

    @property
    def lattice(self) -> np.ndarray | None:
        """(2, 2) reduced lattice basis (columns) of the print, or None on plain fabric."""
        if self.fabric is None:
            return None
        u1, u2, _ = gauss_reduce(self.fabric.w1, self.fabric.w2)  # same lattice, short basis
        return np.column_stack([u1, u2])

    @property
    def piece_area(self) -> float:
        return sum(p.area * p.quantity * (2 if p.mirrored_pair else 1) for p in self.pieces)


def marker_span(items: list[Item], moves: list[np.ndarray], gap: float) -> float:
    """A marker free of phase: its length from its leftmost piece to its rightmost, plus
    the gap at both ends."""
    xs = [affine(m, it.ref)[:, 0] for it, m in zip(items, moves)]
    return max(float(x.max()) for x in xs) - min(float(x.min()) for x in xs) + 2 * gap


@dataclass
class Item:
    id: str
    name: str
    piece: int
    mirrored: bool
    ref: np.ndarray  # (n, 2) outline in the reference frame
    candidates: list[np.ndarray]  # (2, 3) maps in the reference frame
    lattice: np.ndarray | None  # (2, 2) columns or None (free translation)

    @property
    def key(self) -> tuple[int, bool]:
        """Copies with equal keys are interchangeable (same shape, same candidates)."""
        return (self.piece, self.mirrored)


def candidate_maps(piece: Piece, mirrored: bool, fabric) -> list[np.ndarray]:
    """The maps an item may undergo in its reference frame before translation.

    Plain fabric: rotations by the allowed orientations (after a reflection about x
    for the mirrored copy). Printed fabric: the print's operations whose linear part is
    such a rotation (det -1 for the mirrored copy), so the print under the piece is
    unchanged; a mirrored copy needs a print with mirror or glide lines.
    """
    angles = piece.orientations if piece.orientations is not None else FREE_ANGLES
    if fabric is None:
        return [compose(rotation(a), MIRROR_X) if mirrored else rotation(a) for a in angles]
    out = []
    for op in fabric.cartesian_ops():
        m = op[:2, :3]
        det = np.linalg.det(m[:, :2])
        if (det < 0) != mirrored:
            continue
        if angle_allowed(angle_of(m, mirrored), piece.orientations, tol=1e-3):
            out.append(m.copy())
    if not out:
        kind = "mirrored copy" if mirrored else "piece"
        raise ValueError(f"{kind} {piece.name!r}: no operation of print {fabric.group} keeps its "
                         f"grain within orientations {piece.orientations}")
    return out


def load_esicup(path: str | Path) -> NestProblem:
    """An ESICUP/jagua-rs strip-packing instance (``strip_height`` is the fabric width)."""
    path = Path(path)
    src = str(path)
    lim = untrusted.limits
    d = untrusted.mapping(read_json(path), src)
    if "strip_height" not in d or "items" not in d:
        raise untrusted.InputError(src, "not a strip-packing instance (needs strip_height and "
                                   "items)")
    width = untrusted.number(d["strip_height"], src, "strip_height", lo=0.0,
                             hi=lim.MAX_COORD_MM, lo_open=True)
    items = untrusted.sequence(d["items"], src, "items", min_len=1, max_len=lim.MAX_PIECES)
    pieces, total = [], 0
    for i, it in enumerate(items):
        where = f"items[{i}]"
        it = untrusted.mapping(it, src, where)
        shape = untrusted.mapping(it.get("shape", {}), src, f"{where}.shape")
        if "data" not in shape or "id" not in it:
            raise untrusted.InputError(src, f"item {it.get('id', i)} lacks an id or shape data")
        if shape.get("type", "simple_polygon") != "simple_polygon":
            raise untrusted.InputError(src, f"{where}: only simple_polygon shapes are read")
        outline = untrusted.points(shape["data"], src, f"{where}.shape.data", min_len=3)
        demand = untrusted.integer(it.get("demand", 1), src, f"{where}.demand", lo=1,
                                   hi=lim.MAX_DEMAND)
        total += demand
        orient = it.get("allowed_orientations")
        if orient is not None:
            untrusted.sequence(orient, src, f"{where}.allowed_orientations", min_len=1,
                               max_len=360)
            orient = tuple(untrusted.number(a, src, f"{where}.allowed_orientations", lo=-360,
                                            hi=360) for a in orient)
        try:
            pieces.append(Piece(str(it["id"])[:200], outline, quantity=demand,
                                orientations=orient))
        except ValueError as exc:
            raise untrusted.InputError(src, str(exc)) from None
    if total > lim.MAX_DEMAND:
        raise untrusted.InputError(src, f"the items' demands add up to {total:,}; at most "
                                   f"{lim.MAX_DEMAND:,} copies are nested at once")
    name = d.get("name", path.stem)
    return NestProblem(pieces, width, name=name if isinstance(name, str) else path.stem)
