"""The dotted board's allowed positions and their clashes (:mod:`solver.nest.dotted`).

Every allowed position of a piece is a candidate map (a grain-keeping operation of the
print) and a whole lattice translation that keeps it on the roll. Whether two pieces
under two maps collide depends only on their relative lattice offset, so the colliding
offsets are tabulated once per pair of (piece, map) with shapely (the gap semantics of
``verify_layout``) and expanded to pairs of positions by index arithmetic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely

from solver.nest.instance import Item, NestProblem, affine
from solver.nest.snapjoint import collide

EDGE_EPS = 1e-9  # mm of slack at the fabric's edges (verify_layout allows 1e-6)


@dataclass
class Options:
    """One item's allowed positions: candidate map index and lattice coordinates each."""

    cand: np.ndarray  # (m,) int
    k: np.ndarray  # (m, 2) int
    left: np.ndarray  # (m,) left edge, mm
    right: np.ndarray  # (m,) right edge, mm
    bottom: np.ndarray  # (m,) lower edge, mm




def lattice_points(basis: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(m, 2) int coordinates ``k`` with ``basis @ k`` inside the box [lo, hi] (mm)."""
    corners = np.array([[lo[0], lo[1]], [lo[0], hi[1]], [hi[0], lo[1]], [hi[0], hi[1]]])
    f = np.linalg.solve(basis, corners.T).T
    a = np.arange(math.floor(f[:, 0].min()), math.ceil(f[:, 0].max()) + 1)
    b = np.arange(math.floor(f[:, 1].min()), math.ceil(f[:, 1].max()) + 1)
    k = np.stack(np.meshgrid(a, b, indexing="ij"), -1).reshape(-1, 2)
    t = k @ basis.T
    return k[np.all((t >= lo - EDGE_EPS) & (t <= hi + EDGE_EPS), axis=1)]


def shape_at_zero(item: Item, c: int) -> np.ndarray:
    """(n, 2) the item's outline under candidate map ``c``, lattice translation zero."""
    return affine(item.candidates[c], item.ref)


def item_options(problem: NestProblem, item: Item, limit: float) -> Options:
    """Every allowed position of ``item`` on the roll, ending before ``limit`` (mm).

    Per candidate map the box of lattice translations that keep the outline between the
    gap and the roll's edges, then (vectorised) those clear of the keep-outs.
    """
    g, basis = problem.gap, item.lattice
    end = limit if problem.length is None else min(limit, problem.length)
    cands, ks, lefts, rights, bottoms = [], [], [], [], []
    for c in range(len(item.candidates)):
        ring = shape_at_zero(item, c)
        lo, hi = ring.min(0), ring.max(0)
        k = lattice_points(basis, np.array([g, g]) - lo,
                           np.array([end - g, problem.width - g]) - hi)
        t = k @ basis.T
        if problem.keepouts and len(k):
            polys = shapely.polygons(ring[None] + t[:, None])
            ok = np.ones(len(k), bool)
            for ring_k in problem.keepouts:
                ok &= ~collide(polys, shapely.Polygon(ring_k), g)
            k, t = k[ok], t[ok]
        cands.append(np.full(len(k), c))
        ks.append(k)
        lefts.append(lo[0] + t[:, 0])
        rights.append(hi[0] + t[:, 0])
        bottoms.append(lo[1] + t[:, 1])
    return Options(np.concatenate(cands), np.concatenate(ks).reshape(-1, 2).astype(np.int64),
                   np.concatenate(lefts), np.concatenate(rights), np.concatenate(bottoms))


def positions(problem: NestProblem, items: list[Item], length: float) -> float:
    """About how many allowed positions the items have on a marker ``length`` long (the
    size of the dotted-board model), from the area of each map's box of translations over
    the lattice cell's, without listing them (a 1 mm stripe step has millions)."""
    g, total = problem.gap, 0.0
    end = length if problem.length is None else min(length, problem.length)
    for it in items:
        cell = abs(np.linalg.det(it.lattice))
        for c in range(len(it.candidates)):
            size = np.ptp(shape_at_zero(it, c), axis=0)
            room = np.array([end, problem.width]) - 2 * g - size
            total += float(np.prod(np.maximum(room, 0.0))) / cell
    return total


def clash_offsets(ring_a: np.ndarray, ring_b: np.ndarray, basis: np.ndarray,
                  gap: float) -> np.ndarray:
    """(d, 2) int lattice offsets ``k_b - k_a`` at which outline B collides with outline A.

    Only offsets whose boxes come within the gap can collide; those are checked exactly
    (``collide``: closer than the gap, or overlapping at gap 0), all at once.
    """
    lo_a, hi_a = ring_a.min(0), ring_a.max(0)
    lo_b, hi_b = ring_b.min(0), ring_b.max(0)
    d = lattice_points(basis, lo_a - hi_b - gap, hi_a - lo_b + gap)
    if len(d) == 0:
        return d.reshape(0, 2)
    polys = shapely.polygons(ring_b[None] + (d @ basis.T)[:, None])
    return d[collide(shapely.Polygon(ring_a), polys, gap)]


def index_grid(k: np.ndarray, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A dense table lattice coordinates -> option id (-1: none) and its origin."""
    origin = k.min(0)
    grid = np.full(tuple(np.ptp(k, axis=0) + 1), -1, np.int64)
    grid[tuple((k - origin).T)] = ids
    return grid, origin


def clash_lists(opts_a: Options, opts_b: Options, offsets: dict, ids_b: np.ndarray,
                ) -> list[np.ndarray]:
    """Per option of A, the ids of B's options that collide with it.

    ``offsets[ca, cb]`` are the colliding offsets of the two maps (:func:`clash_offsets`);
    B's options are looked up in a dense grid per map, by index arithmetic.
    """
    parts = []  # (m_a, d) arrays of B ids, -1 where none
    for cb in np.unique(opts_b.cand):
        sel = opts_b.cand == cb
        grid, origin = index_grid(opts_b.k[sel], ids_b[sel])
        block = np.full((len(opts_a.cand), 0), -1, np.int64)
        for ca in np.unique(opts_a.cand):
            d = offsets[int(ca), int(cb)]
            rows = np.flatnonzero(opts_a.cand == ca)
            if len(d) == 0 or len(rows) == 0:
                continue
            kb = opts_a.k[rows, None, :] + d[None] - origin  # (r, d, 2)
            inside = np.all((kb >= 0) & (kb < grid.shape), axis=2)
            got = np.full(kb.shape[:2], -1, np.int64)
            got[inside] = grid[kb[inside][:, 0], kb[inside][:, 1]]
            if block.shape[1] < got.shape[1]:
                block = np.pad(block, ((0, 0), (0, got.shape[1] - block.shape[1])),
                               constant_values=-1)
            block[rows, :got.shape[1]] = got
        parts.append(block)
    rows = np.concatenate(parts, axis=1) if parts else np.full((len(opts_a.cand), 0), -1)
    return [r[r >= 0] for r in rows]
