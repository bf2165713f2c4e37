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
        """(V,) bool: the vertices of every piece whose outline crosses in ``uv``."""
        bad = self._checked[~self._valid(uv)]
        return np.isin(self._piece_of_vertex, bad)

    def __call__(self, uv: np.ndarray) -> bool:
        """True when no checked piece's outline crosses itself or its holes."""
        return bool(self._valid(uv).all())
