"""LAYOUT.json: the nested marker, and an independent checker of it.

A layout lists per placed copy the rigid transform from the piece's input coordinates
to fabric coordinates (mm; x along the roll, y across the width) and the transformed
outline, notches, marks and grain line, so the G-code side and the tests need nothing
else. :func:`verify_layout` recomputes everything from the outlines with shapely and
never trusts the nester.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import shapely

from solver.jsonfile import read_json
from solver.nest.instance import (
    Item,
    NestProblem,
    affine,
    angle_allowed,
    angle_of,
    compose,
    invert,
)

OVERLAP_TOL = 1e-6  # allowed overlap as a fraction of the smaller piece's area
EDGE_TOL = 1e-6  # mm of rounding slack at the fabric edge


def _label(value) -> str | None:
    """A garment or size label of a LAYOUT piece: a short string, or absent."""
    if value is None:
        return None
    if not isinstance(value, str) or len(value) > 200:
        raise ValueError("a piece's garment and size are strings of at most 200 characters")
    return value


@dataclass
class Placed:
    id: str
    name: str
    transform: np.ndarray  # (2, 3) input -> fabric
    mirrored: bool
    outline: np.ndarray
    holes: list[np.ndarray] = field(default_factory=list)
    notches: list[tuple] = field(default_factory=list)  # (at, direction, depth or None)
    marks: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    grainline: np.ndarray | None = None
    sew_line: np.ndarray | None = None  # (k, 2) inside the cut line ``outline``
    allowance: np.ndarray | None = None  # (k,) mm per sew-line edge
    garment: str | None = None  # which garment of an order, and its size
    size: str | None = None

    @property
    def angle_deg(self) -> float:
        return angle_of(self.transform, self.mirrored)

    def polygon(self) -> shapely.Polygon:
        return shapely.Polygon(self.outline, self.holes)

    def to_dict(self) -> dict:
        r = lambda a: np.round(np.asarray(a, float), 9).tolist()  # noqa: E731
        return {"id": self.id, "name": self.name, "transform": r(self.transform),
                "angle_deg": round(self.angle_deg, 9), "mirrored": self.mirrored,
                "outline": r(self.outline), "holes": [r(h) for h in self.holes],
                "notches": [{"at": r(a), "direction": r(d)} | ({} if h is None else
                                                              {"depth": round(h, 9)})
                            for a, d, h in self.notches],
                "marks": r(self.marks),
                "grainline": None if self.grainline is None else r(self.grainline),
                **({} if self.sew_line is None else {"sew_line": r(self.sew_line)}),
                **({} if self.allowance is None else {"allowance": r(self.allowance)}),
                **{k: v for k, v in (("garment", self.garment), ("size", self.size)) if v}}

    @classmethod
    def from_dict(cls, d: dict) -> Placed:
        return cls(d["id"], d.get("name", d["id"]), np.asarray(d["transform"], float),
                   bool(d.get("mirrored", False)), np.asarray(d["outline"], float),
                   [np.asarray(h, float) for h in d.get("holes", [])],
                   [(np.asarray(n["at"], float), np.asarray(n["direction"], float),
                     None if n.get("depth") is None else float(n["depth"]))
                    for n in d.get("notches", [])],
                   np.asarray(d.get("marks", []), float).reshape(-1, 2),
                   None if d.get("grainline") is None else np.asarray(d["grainline"], float),
                   None if d.get("sew_line") is None else np.asarray(d["sew_line"], float),
                   None if d.get("allowance") is None else np.asarray(d["allowance"], float),
                   _label(d.get("garment")), _label(d.get("size")))


@dataclass
class Layout:
    width: float
    length: float
    gap: float
    pieces: list[Placed]
    fabric: dict | None = None
    keepouts: list[np.ndarray] = field(default_factory=list)
    allowance: dict | None = None  # the allowance rules the cut lines were made with
    # left/right pairs as PLACEMENT.json has them, [i, j, "mirror" | "same"], i and j
    # indices into ``pieces`` (copy k of a pair's first piece with copy k of its second)
    pairs: list[list] = field(default_factory=list)
    # where the marker starts along the roll (mm), on the print as found: a marker free
    # to start at any phase of the print begins where its first piece does, and the
    # cloth before it (less than a repeat) is not the marker's. The pieces lie where
    # they are cut, each on its aligned print position; 0: the marker starts at x = 0.
    phase_mm: float = 0.0

    @property
    def marker_length(self) -> float:
        """The marker's own length: from its start (``phase_mm``) to its end."""
        return self.length - self.phase_mm

    @property
    def density(self) -> float:
        """The pieces' share of the marker's area (the cloth before its start not counted)."""
        area = sum(p.polygon().area for p in self.pieces)
        span = self.marker_length
        return float(area / (self.width * span)) if span > 0 else 0.0

    def to_dict(self) -> dict:
        d = {"version": 1, "units": "mm", "width": self.width, "length": self.length,
             "gap": self.gap, "origin": [0, 0], "density": round(self.density, 6),
             "fabric": self.fabric, "pieces": [p.to_dict() for p in self.pieces]}
        if self.allowance is not None:
            d["allowance"] = self.allowance
        if self.pairs:
            d["pairs"] = [[int(i), int(j), str(m)] for i, j, m in self.pairs]
        if self.keepouts:
            d["keepouts"] = [np.asarray(k, float).tolist() for k in self.keepouts]
        if self.phase_mm:
            d["phase_mm"] = round(float(self.phase_mm), 9)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> Layout:
        if d.get("version") != 1 or d.get("units") != "mm":
            raise ValueError("not a version-1 LAYOUT in mm")
        pieces = [Placed.from_dict(p) for p in d["pieces"]]
        pairs = [[int(i), int(j), str(m)] for i, j, m in d.get("pairs", [])]
        if any(not (0 <= i < len(pieces) and 0 <= j < len(pieces)) or i == j
               for i, j, _ in pairs):
            raise ValueError('"pairs" name pieces the layout does not have')
        return cls(float(d["width"]), float(d["length"]), float(d.get("gap", 0.0)), pieces,
                   d.get("fabric"), [np.asarray(k, float) for k in d.get("keepouts", [])],
                   d.get("allowance"), pairs, float(d.get("phase_mm", 0.0)))

    def save(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps(self.to_dict(), indent=1) + "\n")

    @classmethod
    def load(cls, path: str | Path) -> Layout:
        data = read_json(path)
        try:
            return cls.from_dict(data)
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{path}: bad LAYOUT ({exc})") from None


def build_layout(problem: NestProblem, items: list[Item], moves: list[np.ndarray],
                 length: float | None = None) -> Layout:
    """Layout from, per item, its final map ``G`` (2, 3) in the reference frame."""
    placed = []
    for item, g in zip(items, moves):
        piece = problem.pieces[item.piece]
        t = compose(g, piece.base)
        placed.append(Placed(
            item.id, item.name, t, item.mirrored, affine(t, piece.outline),
            [affine(t, h) for h in piece.holes],
            [(affine(t, a)[0], t[:, :2] @ np.asarray(d, float), h) for a, d, h in piece.notches],
            affine(t, piece.marks),
            None if piece.grainline is None else affine(t, piece.grainline),
            None if piece.sew_line is None else affine(t, piece.sew_line),
            piece.allowance, piece.garment, piece.size))
    if length is None:
        xmax = max(float(p.outline[:, 0].max()) for p in placed)
        length = xmax + problem.gap
    fabric = None if problem.fabric is None else problem.fabric.to_dict()
    return Layout(float(problem.width), float(length), float(problem.gap), placed, fabric,
                  list(problem.keepouts), problem.allowance, layout_pairs(problem, items))


def layout_pairs(problem: NestProblem, items: list[Item]) -> list[list]:
    """The problem's pairs as indices into the placed copies: the k-th copy of a pair's
    first piece goes with the k-th copy (same side up) of its second."""
    copies: dict[tuple[int, bool], list[int]] = {}
    for k, item in enumerate(items):
        copies.setdefault(item.key, []).append(k)
    return [[a, b, pair.mode] for pair in problem.pairs for side in (False, True)
            for a, b in zip(copies.get((pair.first, side), []),
                            copies.get((pair.second, side), []))]


def verify_layout(layout: Layout, problem: NestProblem | None = None, *,
                  symmetry_samples: int = 16) -> list[str]:
    """Every fault of a layout as a one-line message (empty list: safe to cut).

    Outlines are cut lines (allowances included). Checks: each sew line lies inside its
    cut line; outlines pairwise overlap by at most 1e-6 of the smaller area and keep at
    least the gap apart; each outline lies in the fabric shrunk by the gap and away from
    the keep-outs; with ``problem``: the right copies are all there, each transform
    carries the piece's input outline onto the placed outline, its rotation relative to
    the piece's reference frame is allowed, and on a print it is a symmetry of the print
    (checked on sample points with ``Wallpaper.mismatch_distance``), and the layout's
    pairs are the problem's, each "mirror" pair's print still mirrored (`_check_pairs`).
    """
    faults: list[str] = []
    g = layout.gap
    polys = np.array([p.polygon() for p in layout.pieces], dtype=object)
    if not 0.0 <= layout.phase_mm < layout.length:
        faults.append(f"the marker's start phase_mm {layout.phase_mm:g} is not within its "
                      f"length {layout.length:g}")
    for p, poly in zip(layout.pieces, polys):
        if not poly.is_valid:
            faults.append(f"{p.id}: outline is not a valid polygon")
        elif p.sew_line is not None and not shapely.Polygon(p.outline).buffer(1e-6).contains(
                shapely.Polygon(p.sew_line)):
            faults.append(f"{p.id}: the sew line leaves the cut line")
    inner = shapely.box(layout.phase_mm + g - EDGE_TOL, g - EDGE_TOL,
                        layout.length - g + EDGE_TOL, layout.width - g + EDGE_TOL)
    for p, poly in zip(layout.pieces, polys):
        if not inner.contains(poly):
            start = f" from {layout.phase_mm:g}" if layout.phase_mm else ""
            faults.append(f"{p.id}: leaves the fabric ({layout.length:g} x {layout.width:g} mm"
                          f"{start}) minus the gap {g:g}")
    tree = shapely.STRtree(polys)
    areas = shapely.area(polys)
    for k, poly in enumerate(polys):
        near = tree.query(poly, predicate="dwithin", distance=max(g - 1e-6, 0.0))
        for j in near[near > k]:
            inter = poly.intersection(polys[j]).area
            if inter > OVERLAP_TOL * min(areas[k], areas[j]):
                faults.append(f"{layout.pieces[k].id} overlaps {layout.pieces[j].id} "
                              f"by {inter:.3g} mm²")
            elif g > 0 and poly.distance(polys[j]) < g * (1 - 1e-6) - 1e-6:
                faults.append(f"{layout.pieces[k].id} is closer than the gap {g:g} to "
                              f"{layout.pieces[j].id}")
    for i, ring in enumerate(layout.keepouts):
        bad = shapely.Polygon(ring)
        for p, poly in zip(layout.pieces, polys):
            if poly.intersection(bad).area > OVERLAP_TOL * poly.area or (
                    g > 0 and poly.distance(bad) < g * (1 - 1e-6) - 1e-6):
                faults.append(f"{p.id}: touches keep-out region {i}")
    if problem is not None:
        faults += _check_against_problem(layout, problem, symmetry_samples)
        faults += _check_pairs(layout, problem, symmetry_samples)
    return faults


PAIR_TOL_MM = 0.1  # mirrored print: largest mismatch at mirror-image points (issue 14)


def _check_pairs(layout: Layout, problem: NestProblem, samples: int) -> list[str]:
    """The layout records the problem's pairs, and on a print every "mirror" pair is still
    mirrored: the map from one copy's fabric point through the pattern's mirror onto the
    other copy, ``T_b M T_a^-1``, is an operation of the print (checked at points of the
    first copy's outline and halfway to its centre, by ``Wallpaper.mismatch_distance``)."""
    faults = []
    by_id = {it.id: it for it in problem.items()}
    items = [by_id.get(p.id) for p in layout.pieces]
    if any(it is None for it in items):
        return faults  # reported as unknown pieces
    expected = layout_pairs(problem, items)
    if sorted(map(tuple, layout.pairs)) != sorted(map(tuple, expected)):
        faults.append(f"pairs {layout.pairs} are not the pieces' pairs {expected}")
        return faults
    maps = {(p.first, p.second): p.mirror for p in problem.pairs}
    for a, b, mode in layout.pairs:
        if mode != "mirror" or problem.fabric is None:
            continue
        pa, pb = layout.pieces[a], layout.pieces[b]
        ring = pa.outline[np.linspace(0, len(pa.outline) - 1, samples).astype(int)]
        pts = np.vstack([ring, 0.5 * (ring + pa.outline.mean(axis=0))])
        mirror = maps[(items[a].piece, items[b].piece)]
        there = affine(compose(pb.transform, compose(mirror, invert(pa.transform))), pts)
        err = float(problem.fabric.mismatch_distance(there, pts).max())
        if err > PAIR_TOL_MM:
            faults.append(f"{pa.id} and {pb.id}: the pair's print is no longer mirrored "
                          f"(mismatch {err:.3g} mm)")
    return faults


def _check_against_problem(layout: Layout, problem: NestProblem, samples: int) -> list[str]:
    faults = []
    expected = {it.id: it for it in problem.items()}
    got = {p.id for p in layout.pieces}
    if missing := sorted(set(expected) - got):
        faults.append(f"missing pieces: {', '.join(missing[:8])}")
    if extra := sorted(got - set(expected)):
        faults.append(f"unknown pieces: {', '.join(extra[:8])}")
    rng = np.random.default_rng(0)
    for p in layout.pieces:
        item = expected.get(p.id)
        if item is None:
            continue
        piece = problem.pieces[item.piece]
        if not np.allclose(affine(p.transform, piece.outline), p.outline, atol=1e-6, rtol=0):
            faults.append(f"{p.id}: transform does not map the piece onto its outline")
        t = p.transform[:, :2]
        if not np.allclose(t.T @ t, np.eye(2), atol=1e-9):
            faults.append(f"{p.id}: transform is not rigid")
            continue
        if (np.linalg.det(t) < 0) != item.mirrored:
            faults.append(f"{p.id}: mirrored={item.mirrored} but transform has det "
                          f"{np.linalg.det(t):+.0f}")
        g = compose(p.transform, invert(piece.base))  # the move in the reference frame
        lin = g[:, :2] @ np.diag([1.0, -1.0]) if item.mirrored else g[:, :2]
        ang = angle_of(lin, False)
        if not angle_allowed(ang, piece.orientations, tol=1e-3):
            faults.append(f"{p.id}: rotation {ang:.3f} deg not in {piece.orientations}")
        if problem.fabric is not None:
            lo, hi = p.outline.min(0), p.outline.max(0)
            pts = lo + rng.random((samples, 2)) * (hi - lo)
            err = problem.fabric.mismatch_distance(affine(g, pts), pts)
            if err.max() > 1e-6 * max(1.0, float(np.abs(hi).max())):
                faults.append(f"{p.id}: move is not a symmetry of the print "
                              f"(mismatch {err.max():.3g} mm)")
    return faults
