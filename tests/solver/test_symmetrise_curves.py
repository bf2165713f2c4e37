"""``--symmetrise`` keeps the pattern's own curves: both halves of a pair are still cut on
the Beziers and arcs, the second the exact mirror of the first (issue 34: the rebuilt
garment had lost ``edge_curves`` and was cut on the mesh's chords again)."""

from __future__ import annotations

import numpy as np
import shapely

from solver.garment.allowance import AllowanceRules, cut_lines
from solver.garment.curves import CHORD_TOL_MM, fine_loop
from solver.garment.spec import load_spec
from solver.garment.symmetrise import symmetrise
from solver.garment.symmetry import mirror_pairs
from tests.solver.test_curves import GC_TEE, _shift, _true_panels


def test_symmetrised_pairs_are_cut_on_the_curves_and_mirror_each_other() -> None:
    g = load_spec(GC_TEE)
    sym = symmetrise(g, mirror_pairs(g))
    h = sym.garment
    assert len(sym.pairs) == 4 and not sym.skipped and sym.moves  # rebuilt, not copied
    assert len(h.edge_curves) == len(g.edge_curves) > 100
    true = _true_panels(GC_TEE)
    moved = {m.piece: m.max_mm for m in sym.moves}
    bare = cut_lines(h, AllowanceRules(0.0, 0.0, 0.0))  # cut on the sew line itself
    chords = h.copy()
    chords.edge_curves = {}
    bare_chords = cut_lines(chords, AllowanceRules(0.0, 0.0, 0.0))
    worst_chord = 0.0
    for p in sym.pairs:
        first, _ = fine_loop(h.uv, h.piece_loops(p.first)[0], h.edge_curves)
        second, _ = fine_loop(h.uv, h.piece_loops(p.second)[0], h.edge_curves)
        assert len(second) == len(first) > len(h.piece_loops(p.first)[0])
        # the second piece's fine outline is the first's mirrored, point for point
        gap = np.linalg.norm(p.map_first_to_second(first)[:, None] - second[None], axis=2)
        assert gap.min(axis=1).max() < 1e-6 and gap.min(axis=0).max() < 1e-6
        # the first piece's cut stays on its true curves, but for how far averaging moved it
        i = p.first
        edges = true[g.piece_names[i]]
        shift = _shift(g.uv[g.piece_loops(i)[0]], np.array([e[0] for e in edges]))
        ring = shapely.LinearRing(np.concatenate([e[:-1] for e in edges]) + shift)
        on_curves = shapely.distance(shapely.points(bare[i].outline), ring).max()
        on_chords = shapely.distance(shapely.points(
            np.asarray(shapely.segmentize(bare_chords[i].cut.exterior, 0.5).coords)),
            ring).max()
        assert on_curves <= CHORD_TOL_MM + moved[i]
        worst_chord = max(worst_chord, on_chords)
    # without the curves the same cut strays far more (the necklines' chords)
    assert worst_chord > 2 * (CHORD_TOL_MM + max(moved.values()))
