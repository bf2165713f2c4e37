"""Pulling pieces back after a bite boundary: the hole a block move leaves, filled.

`solver.nest.bites` moves the whole rest of the marker on by what the pieces straddling
a boundary need; every other piece of that block moved too, for nothing. Here each of
them slides back towards the boundary, in order along the roll, as far as it goes
without coming nearer than the gap to another piece: by whole lattice vectors on a print
(it stays on its print), in small steps along the roll on plain cloth. The next boundary
is then chosen on the compacted marker, so what is pulled back shortens the marker.
"""

from __future__ import annotations

import numpy as np
import shapely

#: candidate slides per piece on plain cloth (the step is the room over this)
PLAIN_STEPS = 48
#: overlap tolerance, as a fraction of the fabric's width
OVERLAP_TOL = 1e-7
#: candidate slides tested together (most pieces stop in the first few)
CHUNK = 32


def pull_back(polygons: list[shapely.Polygon], offsets: np.ndarray, movable: np.ndarray,
              floor_x: float, gap: float, width: float, lattice: np.ndarray | None) -> None:
    """Slide the pieces ``movable`` (bool mask) back along the roll, no piece's left end
    before ``floor_x + gap``; ``offsets`` (n, 2): each piece's move so far from its
    ``polygons`` outline, updated in place."""
    bounds = shapely.bounds(np.array(polygons, dtype=object)) + np.tile(offsets, 2)
    eps = OVERLAP_TOL * width
    for j in np.flatnonzero(movable)[np.argsort(bounds[movable, 0], kind="stable")]:
        room = bounds[j, 0] - (floor_x + gap)
        if room <= eps:
            continue
        moves = _slides(room, gap - bounds[j, 1], width - gap - bounds[j, 3], lattice)
        near = np.flatnonzero((bounds[:, 2] + gap >= bounds[j, 0] - room - eps)
                              & (bounds[:, 0] - gap <= bounds[j, 2]))
        others = _moved([polygons[i] for i in near[near != j]], offsets[near[near != j]])
        move = _furthest_clear(_moved([polygons[j]], offsets[j:j + 1])[0], moves, others,
                               gap, eps)
        if move is not None:
            offsets[j] += move
            bounds[j] += np.tile(move, 2)


def _moved(polygons: list[shapely.Polygon], moves: np.ndarray) -> np.ndarray:
    """Each polygon translated by its row of ``moves`` (m, 2), in one pass over the
    coordinates (a Python call per polygon costs more than the geometry)."""
    geoms = np.array(polygons, dtype=object).reshape(-1)
    per_coord = np.repeat(np.asarray(moves, float).reshape(-1, 2),
                          shapely.get_num_coordinates(geoms), axis=0)
    return shapely.transform(geoms, lambda xy: xy + per_coord)


def _furthest_clear(piece: shapely.Polygon, moves: np.ndarray, others: np.ndarray,
                    gap: float, eps: float) -> np.ndarray | None:
    """The first of ``moves`` (furthest first) at which ``piece`` keeps the gap to every
    one of ``others`` and overlaps none; None if none does."""
    if not len(others):
        return moves[0] if len(moves) else None
    if gap <= 0:
        piece = piece.buffer(-eps)  # touching is allowed: test the piece shrunk by eps
    for k in range(0, len(moves), CHUNK):
        chunk = moves[k:k + CHUNK]
        shifted = _moved([piece] * len(chunk), chunk)[:, None]
        if gap > 0:
            ok = np.all(shapely.distance(shifted, others[None, :]) >= gap - eps, axis=1)
        else:
            ok = ~np.any(shapely.intersects(shifted, others[None, :]), axis=1)
        if ok.any():
            return chunk[int(np.argmax(ok))]
    return None


def _slides(room: float, dy_min: float, dy_max: float, lattice: np.ndarray | None
            ) -> np.ndarray:
    """(m, 2) moves back along the roll by at most ``room``, furthest first, keeping the
    piece across the roll within ``[dy_min, dy_max]``: whole lattice vectors on a print."""
    if lattice is None:
        steps = np.linspace(room, 0.0, PLAIN_STEPS, endpoint=False)
        return np.column_stack([-steps, np.zeros_like(steps)])
    corners = np.array([[-room, 0.0, -room, 0.0], [dy_min, dy_min, dy_max, dy_max]])
    frac = np.linalg.solve(lattice, corners)
    a, b = (g.ravel() for g in np.meshgrid(
        *(np.arange(np.floor(f.min()), np.ceil(f.max()) + 1) for f in frac)))
    v = (lattice @ np.vstack([a, b])).T
    ok = (v[:, 0] >= -room - 1e-9) & (v[:, 0] < -1e-9) & (v[:, 1] >= dy_min - 1e-9) \
        & (v[:, 1] <= dy_max + 1e-9)
    v = v[ok]
    return v[np.lexsort((np.abs(v[:, 1]), v[:, 0]))]
