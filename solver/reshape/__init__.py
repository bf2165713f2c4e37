"""Sewing-pattern shape optimisation (paper Sec. 5): ideal seams, Eq. (10), L-BFGS.

    from solver.reshape import reshape
    new_garment, report = reshape(garment, placement)   # placement from solver.align
    report.seams, report.roughness_p95_mm                # what a pattern maker checks

Wolff and Sorkine-Hornung, "Wallpaper Pattern Alignment along Garment Seams",
ACM Trans. Graph. 38(4), 2019, Sec. 5.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial import cKDTree

from solver.fit import fit_report
from solver.garment.refine import refined
from solver.reshape.ideal import IdealSeams, SeamTargets, ideal_seams, matched_seams, reach_mm
from solver.reshape.optimise import (  # the driver optimise() stays in its module, so
    OptimiseResult,  # that ``solver.reshape.optimise`` keeps naming the module: bound
    OptimiseState,  # here under another name
    ReshapeOptions,
    optimise_step,
)
from solver.reshape.optimise import optimise as _optimise
from solver.reshape.quality import outline_roughness, seam_ease_changes, sewn_drift
from solver.reshape.report import ReshapeReport, reshape_report

__all__ = [
    "IdealSeams",
    "OptimiseResult",
    "OptimiseState",
    "ReshapeOptions",
    "ReshapeReport",
    "SeamTargets",
    "ideal_seams",
    "matched_seams",
    "optimise_step",
    "outline_roughness",
    "reshape",
    "reshape_report",
    "seam_ease_changes",
    "sewn_drift",
]


def reshape(garment, placement, *, fixed: np.ndarray | None = None,
            options: ReshapeOptions | None = None,
            progress: Callable[[dict], None] | None = None, pairs=()):
    """Reshaped copy of ``garment`` (3D kept, pattern replaced) and its `ReshapeReport`.

    A mesh whose seam edges are on average longer than the print's covering radius is
    first subdivided (`solver.garment.refine`; ``options.refine``), so the copy then has
    more vertices: a seam cannot follow a print that repeats within one of its edges. A
    pattern that already fits perfectly is left as it is, mesh included.
    ``progress`` gets each finished round's record (targets, gamma, L, E_fit, iterations).
    ``pairs`` (`solver.garment.symmetry.MirrorPair`) keep their halves mirrored: the
    second piece's displacement is the mirror of the first's.
    """
    if placement.n_pieces != garment.n_pieces:
        raise ValueError(f"placement is for {placement.n_pieces} pieces but the garment "
                         f"has {garment.n_pieces}")
    options = options or ReshapeOptions()
    if not options.max_move_mm > 0:
        raise ValueError(f"the largest move must be > 0 mm, got {options.max_move_mm}")
    levels = 0
    if options.refine and fit_report(garment, placement).e_fit_mm2 > 0:
        garment, levels = refined(garment, placement.fabric.covering_radius)
    result = _optimise(garment, placement, fixed=fixed, options=options, progress=progress,
                      pairs=pairs)
    new = garment.with_uv(result.uv)
    new.grainlines, new.notches = _carry_marks(garment, result.uv)
    return new, reshape_report(garment, placement, result, subdivisions=levels,
                               max_move_mm=options.max_move_mm,
                               reach_mm=reach_mm(placement, options.reach, options.max_move_mm))


def _carry_marks(garment, uv: np.ndarray):
    """Grain lines moved with the displacement of their nearest pattern vertex (they stay
    on their piece); notches kept at the same place along their outline edge (the same
    fraction of the same edge), so a notch stays on the reshaped outline and, since twin
    edges keep their lengths, at the same sewn position as its partner across the seam."""
    disp = uv - garment.uv
    grains, notches = {}, {}
    edges = garment.boundary_half_edges()
    for i in set(garment.grainlines):
        verts = np.flatnonzero(garment.piece_of_vertex == i)
        p = np.asarray(garment.grainlines[i], float).reshape(-1, 2)
        a, b = p + disp[verts[cKDTree(garment.uv[verts]).query(p)[1]]]
        grains[i] = (tuple(map(float, a)), tuple(map(float, b)))
    for i, marks in garment.notches.items():
        if marks:
            own = edges[garment.piece_of_vertex[edges[:, 0]] == i]
            notches[i] = [tuple(map(float, q))
                          for q in _along_edges(garment.uv, uv, own, np.asarray(marks, float))]
    return grains, notches


def _along_edges(before: np.ndarray, after: np.ndarray, edges: np.ndarray,
                 points: np.ndarray) -> np.ndarray:
    """(N,2) ``points`` moved from ``before`` to ``after`` at the same fraction of their
    nearest edge of ``edges`` (B,2) (vectorised over points x edges)."""
    a, b = before[edges[:, 0]], before[edges[:, 1]]
    ab = b - a
    t = np.einsum("nbk,bk->nb", points[:, None] - a[None], ab) / np.maximum(
        np.einsum("bk,bk->b", ab, ab), 1e-24)
    t = np.clip(t, 0.0, 1.0)
    foot = a[None] + t[..., None] * ab[None]
    k = np.argmin(np.linalg.norm(points[:, None] - foot, axis=-1), axis=1)
    tk = t[np.arange(len(points)), k][:, None]
    offset = points - foot[np.arange(len(points)), k]  # a notch drawn just off the line
    return (1.0 - tk) * after[edges[k, 0]] + tk * after[edges[k, 1]] + offset
