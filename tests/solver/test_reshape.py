"""Reshaping (paper Sec. 5) on real garments: ideal seams, E_fit, flips, L, invariants."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely

from solver.fit import fit_report
from solver.garment import build_garment, load_garment, save_obj
from solver.placement import Placement
from solver.reshape import ReshapeOptions, ideal_seams, reshape
from solver.reshape.ease import ease_targets
from solver.reshape.energy import signed_areas, twin_length_mismatch, twin_lengths
from solver.reshape.quality import outline_roughness, seam_ease_changes
from solver.wallpaper import Wallpaper

DATA = Path(__file__).resolve().parents[1] / "data" / "garments"
P4M = Wallpaper("p4m", (50.0, 0.0), (0.0, 50.0))


@pytest.fixture(scope="module")
def shorts():
    return load_garment(DATA / "berkeley" / "shorts-iso.obj", units="m")


@pytest.fixture(scope="module")
def placement(shorts):
    """The team's global alignment (solver.align, paper Sec. 4 and beyond) of the shorts."""
    from solver.align.driver import align

    return align(shorts, P4M, method="global", restarts=3, seed=0)


@pytest.fixture(scope="module")
def shorts_run(shorts, placement):
    new, report = reshape(shorts, placement)
    return placement, new, report


def test_ideal_lines_fit_perfectly_and_keep_twin_lengths(shorts, placement):
    ideal = ideal_seams(shorts, placement)
    k = len(ideal.vertex) // 2
    v1, v2 = ideal.vertex[:k], ideal.vertex[k:]
    piece = shorts.piece_of_vertex
    p = placement.to_wallpaper(ideal.target[:k], piece[v1])
    q = placement.to_wallpaper(ideal.target[k:], piece[v2])
    assert np.abs(P4M.mismatch(p, q)).max() < 1e-8  # principle (1): every vertex pair
    # principle (2): within a seam line the two ideal lines are congruent
    for line in np.unique(ideal.line[:k]):
        m = ideal.line[:k] == line
        a, b = ideal.target[:k][m], ideal.target[k:][m]
        da = np.linalg.norm(a[:, None] - a[None], axis=-1)
        db = np.linalg.norm(b[:, None] - b[None], axis=-1)
        assert np.abs(da - db).max() < 1e-8
    # both sides move about equally (half each), unlike replacing S1 by S1*
    d1 = np.hypot(*(ideal.target[:k] - shorts.uv[v1]).T)
    d2 = np.hypot(*(ideal.target[k:] - shorts.uv[v2]).T)
    assert d1.mean() > 0 and d2.mean() > 0
    assert 0.2 < d1.mean() / d2.mean() < 5


def test_reshape_halves_e_fit_without_flips_and_meets_length_target(shorts, shorts_run):
    placement, new, report = shorts_run
    assert report.e_fit_after_mm2 <= 0.5 * report.e_fit_before_mm2
    assert report.e_fit_after_mm2 == pytest.approx(fit_report(new, placement).e_fit_mm2)
    assert report.flipped_triangles == 0
    assert signed_areas(new.uv, new.faces).min() > 0
    assert report.length_mismatch_final_mm <= report.epsilon_mm
    # L measures how far each twin pair's length difference is from the one it keeps:
    # its drafted ease, less up to 0.5 mm per seam line given to the fit
    kept, _ = ease_targets(shorts, ReshapeOptions().ease_give_mm)
    assert report.length_mismatch_initial_mm == pytest.approx(np.abs(
        twin_lengths(shorts.uv, shorts.seam_edges) - kept).sum())
    assert report.length_mismatch_final_mm == pytest.approx(twin_length_mismatch(
        new.uv, new.seam_edges, kept))
    np.testing.assert_array_equal(new.xyz, shorts.xyz)  # the drape is kept
    assert report.max_displacement_mm == pytest.approx(np.hypot(*(new.uv - shorts.uv).T).max())
    assert report.subdivisions == 0  # 20 mm seam edges are fine enough for a 50 mm repeat
    assert all(shapely.LinearRing(new.piece_outline(i)).is_simple  # still cuttable
               for i in range(new.n_pieces))


def test_fixed_piece_does_not_move_and_zero_weight_seams_are_ignored(shorts, placement):
    fixed = np.zeros(shorts.n_pieces, bool)
    fixed[0] = True
    opts = ReshapeOptions(max_rounds=2)
    new, report = reshape(shorts, placement, fixed=fixed, options=opts)
    on0 = shorts.piece_of_vertex == 0
    np.testing.assert_array_equal(new.uv[on0], shorts.uv[on0])
    assert np.abs(new.uv[~on0] - shorts.uv[~on0]).max() > 0.1
    assert report.flipped_triangles == 0
    # all seams weighted 0: no ideal targets, the fit is not pursued
    zero = shorts.with_seam_weights({i: 0.0 for i in range(len(shorts.seam_lines))})
    assert len(ideal_seams(zero, placement).vertex) == 0


def _two_squares(shift: float, cells: int = 5) -> object:
    """Two 100 mm squares, the right side of the first sewn to the left side of the second,
    each cut into ``cells`` x ``cells`` squares of two triangles."""
    n = cells + 1
    xs = np.linspace(0.0, 100.0, n)
    gx, gy = np.meshgrid(xs, xs, indexing="ij")
    grid = np.column_stack([gx.ravel(), gy.ravel()])
    idx = np.arange(n * n).reshape(n, n)
    quads = np.column_stack([idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(),
                             idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()])
    tri = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    uv = np.concatenate([grid, grid + [shift, 0.0]])
    faces = np.concatenate([tri, tri + n * n])
    point = np.arange(2 * n * n)
    point[n * n + idx[0]] = idx[-1]  # second square's left column = first square's right
    return build_garment(uv, faces, point, xyz=None, source="two-squares", kind="test")


@pytest.mark.parametrize("cells", [5, 1])  # 20 mm seam edges, and 100 mm ones
def test_a_perfect_fit_is_returned_unchanged(cells):
    g = _two_squares(200.0, cells)  # 200 mm = 4 repeats: the print runs on across the seam
    placement = Placement.identity(g.n_pieces, P4M)
    assert fit_report(g, placement).e_fit_mm2 == pytest.approx(0.0, abs=1e-9)
    new, report = reshape(g, placement)
    assert report.max_displacement_mm < 1e-6
    assert report.subdivisions == 0  # even the coarse one keeps its mesh
    assert np.abs(new.uv - g.uv).max() < 1e-6


def test_a_small_offset_is_removed_almost_entirely():
    g = _two_squares(212.0)  # 12 mm off the repeat
    placement = Placement.identity(g.n_pieces, P4M)
    new, report = reshape(g, placement)
    assert report.e_fit_before_mm2 > 100
    assert report.e_fit_after_mm2 < 0.05 * report.e_fit_before_mm2
    assert report.flipped_triangles == 0


def test_obj_export_reimports_to_the_same_outlines(tmp_path, shorts_run):
    _, new, _ = shorts_run
    path = tmp_path / "out.obj"
    save_obj(new, path)
    back = load_garment(path)
    assert back.n_pieces == new.n_pieces
    for i in range(new.n_pieces):
        a, b = new.piece_outline(i), back.piece_outline(i)
        assert a.shape == b.shape
        assert np.abs(np.sort(a, axis=0) - np.sort(b, axis=0)).max() < 1e-6
    np.testing.assert_allclose(back.xyz[:, :], back.xyz)  # 3D present
    assert back.xyz is not None


def test_a_heavier_seam_fits_better(shorts, placement, shorts_run):
    _, plain, _ = shorts_run
    line = int(np.argmax(np.bincount(shorts.seam_line_of_edge)))  # the longest seam line
    heavy_g = shorts.with_seam_weights({line: 10.0})
    heavy, _ = reshape(heavy_g, placement)
    on = shorts.seam_line_of_edge == line

    def mismatch(g):
        return fit_report(g, placement, weights=np.ones(len(g.seam_edges))).distance[on].sum()

    assert mismatch(heavy) < mismatch(plain)


def test_written_obj_has_fair_outlines_and_seams_that_sew(tmp_path, shorts, shorts_run):
    """Issue 36's checks, measured as a pattern maker would: from the OBJ files (the input
    and the reshaped garment written and read back, same numbering)."""
    _, new, report = shorts_run
    save_obj(shorts, tmp_path / "aligned.obj")
    save_obj(new, tmp_path / "reshaped.obj")
    before, after = load_garment(tmp_path / "aligned.obj"), load_garment(tmp_path / "reshaped.obj")
    np.testing.assert_array_equal(before.faces, after.faces)
    rough = outline_roughness(before, after.uv)
    assert np.percentile(rough, 95) <= 0.3 and rough.max() <= 1.0
    seams = seam_ease_changes(before, after.uv)
    ease = [abs(s["ease_change_mm"]) for s in seams]
    assert max(ease) <= 1.0
    # and no point of a seam slid along its twin by more than 1 mm: notches still meet
    assert max(s["sewn_drift_mm"] for s in seams) <= 1.0
    # the report says the same, seam by seam
    assert report.ease_change_max_mm == pytest.approx(max(ease), abs=1e-3)
    assert report.roughness_max_mm == pytest.approx(rough.max(), abs=1e-6)
    assert len(report.seams) == len(shorts.seam_lines)
    assert report.e_fit_after_mm2 <= 0.7 * report.e_fit_before_mm2


def test_paper_method_pulls_twins_to_equal_lengths_unbounded(shorts, placement):
    """Sec. 5 as written: eps is half the input's twin length mismatch, no move bound."""
    new, report = reshape(shorts, placement, options=ReshapeOptions.paper())
    assert report.epsilon_mm == pytest.approx(0.5 * report.length_mismatch_initial_mm)
    assert report.length_mismatch_final_mm <= report.epsilon_mm
    assert report.length_mismatch_final_mm == pytest.approx(
        twin_length_mismatch(new.uv, new.seam_edges))
    assert report.e_fit_after_mm2 <= 0.5 * report.e_fit_before_mm2
    assert report.flipped_triangles == 0
    assert report.max_move_bound_mm == np.inf
    assert report.max_displacement_mm > 10.0  # beyond what our bound allows


def test_notches_keep_their_place_along_their_edge():
    """A notch halfway along a seam edge stays halfway along it on the reshaped outline,
    on both sides of the seam, so the two still meet when sewn."""
    g = _two_squares(212.0)
    g.notches = {0: [(100.0, 50.0)], 1: [(212.0, 50.0)]}  # halfway between y = 40 and 60
    placement = Placement.identity(g.n_pieces, P4M)
    new, report = reshape(g, placement)
    assert report.max_displacement_mm > 1.0
    for piece, x in ((0, 100.0), (1, 212.0)):
        ends = np.flatnonzero((g.piece_of_vertex == piece) & np.isclose(g.uv[:, 0], x)
                              & np.isin(g.uv[:, 1], [40.0, 60.0]))
        assert len(ends) == 2
        np.testing.assert_allclose(new.notches[piece][0], new.uv[ends].mean(axis=0),
                                   atol=1e-9)
