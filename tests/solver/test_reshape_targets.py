"""Reshaping's targets and safeguards: matched seams, the reach rule, crossing outlines,
subdivision of coarse meshes, and the issue's check on every bundled Berkeley garment."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely

from solver.fit import fit_report
from solver.garment import load_garment
from solver.garment.refine import refined, subdivided
from solver.placement import Placement
from solver.reshape import ideal_seams, matched_seams, reshape
from solver.reshape.ideal import UNIT_MM, ideal_move_rms, initial_targets
from solver.reshape.outline import OutlineGuard
from solver.wallpaper import Wallpaper

BERKELEY = Path(__file__).resolve().parents[1] / "data" / "garments" / "berkeley"
P4M = Wallpaper("p4m", (50.0, 0.0), (0.0, 50.0))


@pytest.fixture(scope="module")
def skirt():
    return load_garment(BERKELEY / "skirt-coarse.obj", units="m")


@pytest.fixture(scope="module")
def shorts_aligned():
    """The shorts under the paper's alignment (quick; test_reshape.py uses the global one),
    turned freely: these tests are about the targets' geometry, not the grain."""
    from solver.align.driver import align

    g = load_garment(BERKELEY / "shorts-iso.obj", units="m")
    return g, align(g, P4M, method="paper", restarts=3, seed=0, grain_tol_deg=None)


def test_matched_targets_fit_each_edge_under_its_own_symmetry(shorts_aligned):
    g, placement = shorts_aligned
    t = matched_seams(g, placement)
    e = g.seam_edges
    k = len(e)
    # rows: [end a side 1, end a side 2, end b side 1, end b side 2], each (E,)
    tv = t.target.reshape(4, k, 2)
    piece = g.piece_of_vertex
    for side1, side2 in ((0, 1), (2, 3)):
        p = placement.to_wallpaper(tv[side1], piece[e[:, 0]])
        q = placement.to_wallpaper(tv[side2], piece[e[:, 2]])
        assert np.abs(P4M.mismatch(p, q)).max() < 1e-8  # both ends land on equivalent points
    # each side moves half the way: the midpoints' mismatch is within the covering
    # radius, the ends' within that plus the seam edge
    move = np.hypot(*(t.target - g.uv[t.vertex]).T)
    longest = fit_report(g, placement).length.max()
    assert move.max() <= 0.5 * (P4M.covering_radius + 2 * longest)
    # weights integrate along the seam: half an edge's length per end, per UNIT_MM
    lengths = fit_report(g, placement).length
    assert t.weight.sum() == pytest.approx(4 * 0.5 * lengths.sum() / UNIT_MM)


def test_ideal_lines_beyond_the_covering_radius_start_from_matched_targets(shorts_aligned):
    g, placement = shorts_aligned
    ideal = ideal_seams(g, placement)
    start = initial_targets(g, placement, ideal)
    n = len(g.seam_lines)
    d2 = np.sum((ideal.target - g.uv[ideal.vertex]) ** 2, axis=1)
    rms = np.sqrt(np.bincount(ideal.line, d2, n) / np.maximum(np.bincount(ideal.line, None, n), 1))
    near = np.flatnonzero(rms <= P4M.covering_radius)
    assert len(near) >= 3
    for line in near:  # lines within reach keep their ideal targets exactly
        a, b = ideal.line == line, start.line == line
        np.testing.assert_array_equal(start.vertex[b], ideal.vertex[a])
        np.testing.assert_array_equal(start.target[b], ideal.target[a])
    # a print with a 5 mm repeat: every ideal line is many covering radii away, and the
    # matched targets that replace them ask for far smaller moves
    tiny = Placement(placement.angles, placement.translations,
                     Wallpaper("p4m", (5.0, 0.0), (0.0, 5.0)))
    far_ideal = ideal_seams(g, tiny)
    far = initial_targets(g, tiny, far_ideal)
    move = np.hypot(*(far.target - g.uv[far.vertex]).T)
    ideal_move = np.hypot(*(far_ideal.target - g.uv[far_ideal.vertex]).T)
    longest = fit_report(g, tiny).length.max()
    assert move.max() <= 0.5 * (tiny.fabric.covering_radius + 2 * longest)
    assert move.max() < ideal_move.max()


def test_ideal_lines_beyond_the_move_bound_start_matched_and_the_fit_gains(skirt):
    """An ideal line within the covering radius but beyond the move bound cannot be
    reached: it starts from matched targets, and the skirt on a plaid fits better for it
    (main pulled towards those lines and stopped at E_fit 0.611 of the aligned)."""
    from solver.align.driver import align

    plaid = Wallpaper("pmm", (80.0, 0.0), (0.0, 60.0))
    placement = align(skirt, plaid, method="global", restarts=4, seed=0)
    ideal = ideal_seams(skirt, placement)
    rms = ideal_move_rms(skirt, ideal)
    beyond = (rms > 10.0) & (rms <= plaid.covering_radius)  # the rule's new case
    assert beyond.any() and (rms <= 10.0).any()
    start = initial_targets(skirt, placement, ideal, max_move_mm=10.0)
    matched = matched_seams(skirt, placement)
    for line in range(len(skirt.seam_lines)):
        a, b = start.line == line, (matched if rms[line] > 10.0 else ideal).line == line
        np.testing.assert_array_equal(start.target[a],
                                      (matched if rms[line] > 10.0 else ideal).target[b])
    new, report = reshape(skirt, placement)  # the station's bound: 10 mm
    assert report.e_fit_ratio < 0.56
    assert report.max_displacement_mm <= 10.0 and report.area_change_max_pct <= 1.0
    for seam in report.seams:  # each seam says whether it could be fitted within the bound
        assert seam["within_reach"] == (seam["ideal_move_rms_mm"] <= 10.0)
        assert (seam["seam"] in report.seams_out_of_reach) != seam["within_reach"]
    assert report.seams_out_of_reach


def test_outline_guard_names_the_vertices_near_a_crossing(skirt):
    guard = OutlineGuard(skirt)
    assert guard(skirt.uv)
    loop = skirt.piece_loops(0)[0]
    uv = skirt.uv.copy()
    centre = uv[loop].mean(axis=0)
    uv[loop[0]] = centre + 3.0 * (centre - uv[loop[0]])  # pushed through the far side
    assert not guard(uv)
    near = guard.crossing_vertices(uv)
    assert near[loop[0]] or near[loop[1]] or near[loop[-1]]
    assert near.sum() < np.sum(skirt.piece_of_vertex == 0)  # not the whole piece
    assert not near[skirt.piece_of_vertex != 0].any()


def test_subdivision_keeps_outline_drape_and_seams(skirt):
    weighted = skirt.with_seam_weights({0: 0.0, 1: 3.0})
    fine = subdivided(weighted)
    assert len(fine.faces) == 4 * len(skirt.faces)
    assert len(fine.seam_edges) == 2 * len(skirt.seam_edges)
    assert fine.piece_names == skirt.piece_names

    def lines(g):
        return sorted((min(s.piece_a, s.piece_b), max(s.piece_a, s.piece_b), s.name, s.weight)
                      for s in g.seam_lines)

    assert lines(fine) == lines(weighted)
    for i in range(skirt.n_pieces):  # same outline: the old one, with midpoints added
        a = shapely.Polygon(skirt.piece_outline(i))
        b = shapely.Polygon(fine.piece_outline(i))
        assert a.symmetric_difference(b).area < 1e-6 * a.area
        assert len(fine.piece_outline(i)) == 2 * len(skirt.piece_outline(i))
    # every fine 3D point lies on the coarse drape (old points or edge midpoints)
    assert fine.xyz.min(axis=0) == pytest.approx(skirt.xyz.min(axis=0))
    assert fine.xyz.max(axis=0) == pytest.approx(skirt.xyz.max(axis=0))
    same, levels = refined(fine, 1e6)
    assert same is fine and levels == 0


@pytest.mark.parametrize("name", ["skirt-coarse", "pants-coarse", "tshirt-coarse"])
def test_berkeley_p4m_after_global_alignment_lowers_e_fit_within_the_bounds(name):
    """The issue's check on the bundled coarse Berkeley garments (50 mm p4m, global
    alignment); the bundled shorts-iso is checked in test_reshape.py."""
    from solver.align.driver import align

    g = load_garment(BERKELEY / f"{name}.obj", units="m")
    placement = align(g, P4M, method="global", restarts=3, seed=0)
    new, report = reshape(g, placement)
    assert report.subdivisions == 1  # 35-70 mm seam edges against a 50 mm repeat
    assert len(new.faces) == len(g.faces) * 4 ** report.subdivisions
    # issue 4 asked for half; issue 13 bounds every move by 10 mm and issue 36 keeps every
    # seam's ease and the outlines fair, which costs these coarse garments most: the pants
    # reach 0.69 here (0.70 after 15 starts, 0.37 with a 20 mm bound: BENCHMARKS.md, E_fit
    # against the move bound)
    assert report.e_fit_after_mm2 <= 0.7 * report.e_fit_before_mm2
    assert report.flipped_triangles == 0
    # a change a pattern maker accepts: every vertex within 10 mm, every area within 1 %
    assert np.hypot(*(new.uv - refined(g, P4M.covering_radius)[0].uv).T).max() <= 10.0
    assert report.area_change_max_pct <= 1.0
    assert max(p["max_move_mm"] for p in report.pieces) == pytest.approx(
        report.max_displacement_mm, abs=1e-4)
    assert report.ease_change_max_mm <= 1.0  # every seam still sews as it was drafted
    assert all(shapely.LinearRing(new.piece_outline(i)).is_simple
               for i in range(new.n_pieces))
    # the report's E_fit is what `station fit` measures on the written garment
    assert report.e_fit_after_mm2 == pytest.approx(fit_report(new, placement).e_fit_mm2)
