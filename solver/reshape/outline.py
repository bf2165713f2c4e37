"""Keep reshaped pieces cuttable: no outline may cross itself or one of its holes.

The barrier of Eq. (10) forbids flipped triangles, which keeps the map locally
injective, but a boundary can still fold over another part of the same piece without
flipping anything (the two legs of a dart pulled across each other, a neckline corner
pushed through the shoulder). A cutter cannot follow such an outline, so the solver
treats it like a flip: the energy is +inf there and the line search backs off.
"""

from __future__ import annotations

import numpy as np
import shapely


class OutlineGuard:
    """Which pieces' outlines (with holes) must stay simple, and the check itself.

    Pieces whose input outline already crosses itself are left out: reshaping cannot be
    asked to repair what it was given.
    """

    def __init__(self, garment) -> None:
        self._loops = [garment.piece_loops(i) for i in range(garment.n_pieces)]
        self._piece_of_vertex = garment.piece_of_vertex
        self._checked = np.arange(garment.n_pieces)
        self._checked = self._checked[self._valid(garment.uv)]

    def _valid(self, uv: np.ndarray) -> np.ndarray:
        """(checked pieces,) bool: outline and holes form a valid polygon."""
        polys = [shapely.Polygon(uv[lp[0]], [uv[h] for h in lp[1:] if len(h) >= 3])
                 if len(lp[0]) >= 3 else shapely.Polygon()
                 for lp in (self._loops[i] for i in self._checked)]
        return shapely.is_valid(np.array(polys, dtype=object))

    def crossing_vertices(self, uv: np.ndarray) -> np.ndarray:
        """(V,) bool: the outline vertices near where an outline crosses in ``uv`` (within
        four of its longest boundary edges of a crossing point), so that only they sit
        the step out; every vertex of the piece where no crossing point can be named."""
        out = np.zeros(len(uv), bool)
        for i in self._checked[~self._valid(uv)]:
            ring_ids = np.concatenate(self._loops[i])
            rings = [uv[lp] for lp in self._loops[i] if len(lp) >= 3]
            noded = shapely.node(shapely.MultiLineString([np.vstack([r, r[:1]]) for r in rings]))
            parts = shapely.get_parts(noded)
            ends = np.concatenate([shapely.get_coordinates(shapely.get_point(parts, k))
                                   for k in (0, -1)])
            pts = uv[ring_ids]
            dist = np.linalg.norm(ends[:, None] - pts[None], axis=-1)
            crossings = ends[dist.min(axis=1) > 1e-9]
            if not len(crossings):
                out[self._piece_of_vertex == i] = True
                continue
            reach = 4.0 * max(np.linalg.norm(np.diff(r, axis=0), axis=1).max() for r in rings)
            near = np.linalg.norm(pts[:, None] - crossings[None], axis=-1).min(axis=1) < reach
            out[ring_ids[near]] = True
        return out

    def __call__(self, uv: np.ndarray) -> bool:
        """True when no checked piece's outline crosses itself or its holes."""
        return bool(self._valid(uv).all())
