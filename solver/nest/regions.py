"""Fabric regions: the table window, keep-out flaws, and repairing a layout to respect them.

A free sparrow nest knows nothing of flaws marked by the operator nor of a print's
lattice. Both are handled the same way: find the pieces in conflict (outside the
window, on a flaw, overlapping after snapping to the lattice), take out as few as a
greedy vertex cover allows, and re-insert them with the bottom-left filler of
:mod:`solver.nest.engine` around the pieces that stay.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import shapely

import untrusted
from solver.jsonfile import read_json
from solver.nest.budget import Deadline, Progress, deadline_of
from solver.nest.fill import fill_search, first_fill_estimate
from solver.nest.instance import Item, NestProblem, affine, angle_of, ccw_ring
from solver.nest.plain import plain_moves


def load_keepouts(path: str | Path) -> list[np.ndarray]:
    """Keep-out polygons (fabric mm) from JSON: ``{"keepouts": [[[x, y], ...], ...]}`` or a list."""
    src = str(path)
    d = read_json(path)
    rings = d.get("keepouts") if isinstance(d, dict) else d
    rings = untrusted.sequence(rings, src, "keepouts", max_len=untrusted.limits.MAX_PIECES)
    out = []
    for i, r in enumerate(rings):
        ring = untrusted.points(r, src, f"keepouts[{i}]", min_len=3)
        if not shapely.Polygon(ring).is_valid:  # before ccw_ring drops repeated points
            raise untrusted.InputError(src, f"keepouts[{i}] crosses itself or has no area")
        out.append(ccw_ring(ring))
    return out


def near_pairs(polys: np.ndarray, gap: float) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i, j) of ``polys`` closer than ``gap`` (that intersect when ``gap`` is
    0), both ways round and each with itself: the caller keeps the pairs it counts."""
    tree = shapely.STRtree(polys)
    if gap > 0:
        return tree.query(polys, predicate="dwithin", distance=gap * (1 - 1e-7))
    return tree.query(polys, predicate="intersects")


def conflicting(problem: NestProblem, polys: np.ndarray) -> np.ndarray:
    """(n,) bool: a small set of pieces whose removal leaves a valid partial layout."""
    g = problem.gap
    n = len(polys)
    bad = np.zeros(n, bool)
    length = problem.length if problem.length is not None else math.inf
    b = shapely.bounds(polys)
    bad |= (b[:, 0] < g - 1e-9) | (b[:, 1] < g - 1e-9) | (b[:, 3] > problem.width - g + 1e-9)
    bad |= b[:, 2] > length - g + 1e-9
    for ring in problem.keepouts:
        k = shapely.Polygon(ring)
        bad |= shapely.dwithin(polys, k, g * (1 - 1e-7)) if g > 0 else (
            shapely.area(shapely.intersection(polys, k)) > 1e-7 * shapely.area(polys))
    i, j = near_pairs(polys, g)
    keep = i < j
    i, j = i[keep], j[keep]
    if g <= 0 and len(i):
        inter = shapely.area(shapely.intersection(polys[i], polys[j]))
        real = inter > 1e-7 * np.minimum(shapely.area(polys[i]), shapely.area(polys[j]))
        i, j = i[real], j[real]
    edges = [(a, c) for a, c in zip(i.tolist(), j.tolist()) if not bad[a] and not bad[c]]
    area = shapely.area(polys)
    while edges:  # greedy vertex cover: most conflicts first, then the smaller piece
        deg = np.bincount(np.array(edges).ravel(), minlength=n)
        v = int(np.lexsort((area, -deg))[0])
        bad[v] = True
        edges = [(a, c) for a, c in edges if a != v and c != v]
    return bad


def repair(problem: NestProblem, items: list[Item], moves: list[np.ndarray], *,
           time_limit: float | Deadline, seed: int | None, progress: Progress | None = None,
           everything: bool = False, interruptible: bool = False,
           ) -> tuple[list[np.ndarray], float] | None:
    """Take out the conflicting pieces of ``moves``, re-insert them around the rest, compact.

    Re-inserted pieces go to the allowed position nearest to where they were, left-most
    first. ``everything`` re-inserts all pieces that way (a global re-snap).
    ``interruptible``: the caller has another result, give up (None) when not even the
    time to shelve the pieces is left; otherwise those not re-inserted by the deadline
    are shelved (:meth:`solver.nest.engine.Filler.shelve`).
    """
    polys = np.array([shapely.Polygon(affine(m, it.ref)) for it, m in zip(items, moves)],
                     dtype=object)
    bad = np.ones(len(items), bool) if everything else conflicting(problem, polys)
    if progress:
        progress(f"repair: re-inserting {int(bad.sum())} of {len(items)} pieces")
    start = [None if b else m for m, b in zip(moves, bad)]
    wish = [m if b else None for m, b in zip(moves, bad)]
    return fill_search(problem, items, time_limit=time_limit, seed=seed, progress=progress,
                       start=start, targets=wish, interruptible=interruptible)


def snap_to_lattice(problem: NestProblem, items: list[Item], moves: list[np.ndarray],
                    ) -> list[np.ndarray]:
    """Each free move replaced by the nearest allowed one (same op, nearest lattice point)."""
    out = []
    for it, g in zip(items, moves):
        lin = g[:, :2]
        diffs = [np.abs(c[:, :2] - lin).max() for c in it.candidates]
        c = it.candidates[int(np.argmin(diffs))]
        if min(diffs) > 1e-6:
            raise ValueError(f"{it.id}: free orientation {angle_of(g, it.mirrored):.3f} deg is "
                             "not one of the print's operations")
        need = g[:, 2] - c[:, 2]
        snapped = c.copy()
        snapped[:, 2] += need - problem.fabric.lattice_residual(need[None])[0]
        out.append(snapped)
    return out


def repair_snapped(problem: NestProblem, items: list[Item], *, time_limit: float | Deadline,
                   seed: int | None, progress: Progress | None = None, extra: float = 0.0,
                   everything: bool = False, interruptible: bool = False,
                   ) -> tuple[list[np.ndarray], float] | None:
    """Sparrow on plain fabric, snapped to the print's lattice, conflicts re-inserted.

    Sparrow stops early enough to leave the re-insertion its estimated time (cut at the
    deadline, it shelves the pieces left: a marker, but a poor one).
    """
    deadline = deadline_of(time_limit)
    fill = first_fill_estimate(items)
    moves, _ = plain_moves(problem, items, extra=extra,
                           time_limit=deadline.before(fill).share(0.8), seed=seed,
                           progress=progress, interruptible=interruptible)
    snapped = snap_to_lattice(problem, items, moves)
    return repair(problem, items, snapped, time_limit=deadline, seed=seed,
                  progress=progress, everything=everything, interruptible=interruptible)
