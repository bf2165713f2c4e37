"""Sewing-pattern shape optimisation (paper Sec. 5): ideal seams, Eq. (10), L-BFGS.

    from solver.reshape import reshape
    new_garment, report = reshape(garment, placement)   # placement from solver.align

Wolff and Sorkine-Hornung, "Wallpaper Pattern Alignment along Garment Seams",
ACM Trans. Graph. 38(4), 2019, Sec. 5.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from solver.reshape.ideal import IdealSeams, SeamTargets, ideal_seams, matched_seams
from solver.reshape.optimise import (  # the driver optimise() stays in its module, so
    OptimiseResult,  # that ``solver.reshape.optimise`` keeps naming the module
    OptimiseState,
    ReshapeOptions,
    optimise_step,
)
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
    "reshape",
    "reshape_report",
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
    from solver.fit import fit_report
    from solver.garment.refine import refined
    from solver.reshape.optimise import optimise

    options = options or ReshapeOptions()
    if not options.max_move_mm > 0:
        raise ValueError(f"the largest move must be > 0 mm, got {options.max_move_mm}")
    levels = 0
    if options.refine and fit_report(garment, placement).e_fit_mm2 > 0:
        garment, levels = refined(garment, placement.fabric.covering_radius)
    result = optimise(garment, placement, fixed=fixed, options=options, progress=progress,
                      pairs=pairs)
    new = garment.with_uv(result.uv)
    new.grainlines, new.notches = _carry_marks(garment, result.uv)
    return new, reshape_report(garment, placement, result, subdivisions=levels,
                               max_move_mm=options.max_move_mm)


def _carry_marks(garment, uv: np.ndarray):
    """Grain lines and notches moved with the displacement of their nearest pattern vertex,
    so that notches stay on the reshaped outline and grain lines on their piece."""
    from scipy.spatial import cKDTree

    disp = uv - garment.uv
    grains, notches = {}, {}
    for i in set(garment.grainlines) | set(garment.notches):
        verts = np.flatnonzero(garment.piece_of_vertex == i)
        tree = cKDTree(garment.uv[verts])

        def move(points, verts=verts, tree=tree):
            p = np.asarray(points, float).reshape(-1, 2)
            return p + disp[verts[tree.query(p)[1]]]

        if i in garment.grainlines:
            a, b = move(garment.grainlines[i])
            grains[i] = (tuple(map(float, a)), tuple(map(float, b)))
        if garment.notches.get(i):
            notches[i] = [tuple(map(float, q)) for q in move(garment.notches[i])]
    return grains, notches
