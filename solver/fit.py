"""The fit measure E_fit of the paper (Eq. 1), vectorised over seam edges.

``E_fit = sum_S w_S sum_(e,e') l_e d(v_e)``: for each pair of twin seam edges, the
midpoint seen on both pieces is taken to wallpaper space and ``d`` is the distance to
the closest equivalent point (`Wallpaper.mismatch`). ``l_e`` is the mean 2D length of
the two twin edges, which makes the measure independent of which side is called
``e`` (the paper's twins have nearly equal lengths, so the values agree).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solver.placement import Placement


@dataclass(frozen=True)
class FitReport:
    """Per seam edge mismatch and the total, in mm and mm²."""

    vector: np.ndarray  # (E, 2) d(v_e) in wallpaper space of the first twin's piece
    distance: np.ndarray  # (E,) |d(v_e)| mm
    length: np.ndarray  # (E,) l_e mm
    weight: np.ndarray  # (E,) w_S of each edge's seam line

    @property
    def e_fit_mm2(self) -> float:
        return float(np.sum(self.weight * self.length * self.distance))

    @property
    def e_fit_cm2(self) -> float:
        return self.e_fit_mm2 / 100.0

    def summary(self) -> dict[str, float]:
        d = self.distance
        return {
            "e_fit_mm2": self.e_fit_mm2,
            "e_fit_cm2": self.e_fit_cm2,
            "mismatch_mean_mm": float(d.mean()) if len(d) else 0.0,
            "mismatch_max_mm": float(d.max()) if len(d) else 0.0,
        }


def seam_midpoints(uv: np.ndarray, seam_edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Midpoints (E, 2) of both twins of every seam edge in pattern space."""
    return (
        0.5 * (uv[seam_edges[:, 0]] + uv[seam_edges[:, 1]]),
        0.5 * (uv[seam_edges[:, 2]] + uv[seam_edges[:, 3]]),
    )


def seam_lengths(uv: np.ndarray, seam_edges: np.ndarray) -> np.ndarray:
    """l_e: mean 2D length of each pair of twin edges."""
    l1 = np.linalg.norm(uv[seam_edges[:, 1]] - uv[seam_edges[:, 0]], axis=1)
    l2 = np.linalg.norm(uv[seam_edges[:, 3]] - uv[seam_edges[:, 2]], axis=1)
    return 0.5 * (l1 + l2)


def fit_report(garment, placement: Placement, *, weights: np.ndarray | None = None,
               uv: np.ndarray | None = None) -> FitReport:
    """E_fit of ``garment`` with the print ``placement.fabric`` placed per piece.

    ``weights`` overrides the garment's seam weights per seam edge; ``uv`` overrides
    its pattern (reshaping evaluates candidate patterns without copying the garment).
    """
    if placement.n_pieces != garment.n_pieces:
        raise ValueError(f"placement is for {placement.n_pieces} pieces but the garment "
                         f"has {garment.n_pieces}")
    uv = garment.uv if uv is None else uv
    edges = garment.seam_edges
    w = garment.seam_weights() if weights is None else np.asarray(weights, float)
    m1, m2 = seam_midpoints(uv, edges)
    piece1 = garment.piece_of_vertex[edges[:, 0]]
    piece2 = garment.piece_of_vertex[edges[:, 2]]
    p = placement.to_wallpaper(m1, piece1)
    q = placement.to_wallpaper(m2, piece2)
    vec = placement.fabric.mismatch(p, q)
    return FitReport(vector=vec, distance=np.hypot(vec[:, 0], vec[:, 1]),
                     length=seam_lengths(uv, edges), weight=w)


def e_fit(garment, placement: Placement, **kw) -> float:
    """E_fit in mm² (Eq. 1)."""
    return fit_report(garment, placement, **kw).e_fit_mm2
