"""Wallpaper alignment (paper Sec. 4 and the global method) on garments whose answer is
known: pieces cut from one printed sheet, and small real garments from tests/data."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from garments_synthetic import cut_sheet  # noqa: E402

from solver.align import align, align_global, align_paper  # noqa: E402
from solver.align.brute import brute_force  # noqa: E402
from solver.align.frames import seam_frames  # noqa: E402
from solver.align.problem import AlignProblem  # noqa: E402
from solver.fit import fit_report  # noqa: E402
from solver.garment import load_garment  # noqa: E402
from solver.placement import Placement  # noqa: E402
from solver.wallpaper import GROUP_NAMES, GROUPS, Wallpaper  # noqa: E402

BERKELEY = Path(__file__).resolve().parents[1] / "data" / "garments" / "berkeley"


def print_for(group: str, a: float = 40.0) -> Wallpaper:
    """A print of ``group`` with a generic (turned, offset) lattice of repeat ``a`` mm."""
    lattice = GROUPS[group].lattice
    w = {"oblique": ((a, 3.0), (7.0, 0.8 * a)),
         "rectangular": ((a, 0.0), (0.0, 1.3 * a)),
         "rhombic": ((a, 0.6 * a), (a, -0.6 * a)),
         "square": ((a, 0.0), (0.0, a)),
         "hexagonal": ((a, 0.0), (-a / 2, a * np.sqrt(3) / 2))}[lattice]
    return Wallpaper(group, *w, origin=(3.0, 4.0)).moved(0.3)


@pytest.fixture(scope="module")
def sheet2():
    """A 200 x 150 mm sheet cut once, the two pieces moved and turned at random."""
    return cut_sheet(width=200, height=150, nx=10, ny=8, cuts_x=(0.5,), cuts_y=(), seed=3)


@pytest.fixture(scope="module")
def sheet4():
    """The sheet cut in four (a cycle of four seams), without a drape (2D-only)."""
    return cut_sheet(width=200, height=150, nx=10, ny=8, cuts_x=(0.5,), cuts_y=(0.5,), seed=3,
                     drape=False)


@pytest.fixture(scope="module")
def sheet7():
    """Seven pieces: a vertical, a horizontal and a diagonal cut (several cycles)."""
    return cut_sheet(width=200, height=150, nx=10, ny=8, cuts_x=(0.4,), cuts_y=(0.5,),
                     cuts_diag=(0.2,), seed=1)


@pytest.fixture(scope="module")
def pants():
    return load_garment(BERKELEY / "pants-coarse.obj", units="m")


# ---------------------------------------------------------------- building blocks
@pytest.mark.parametrize("drape", [True, False])
def test_frames_lay_each_twin_edge_onto_the_other(drape):
    """On a sheet cut in pieces, A^-1 C is the rotation between the two pieces' cuts."""
    g, ang, _ = cut_sheet(width=120, height=90, nx=6, ny=5, cuts_x=(0.5,), cuts_y=(0.4,),
                          seed=2, drape=drape)
    fr = seam_frames(g)
    assert fr.drape == drape
    m = fr.A_inv @ fr.C
    expect = ang[fr.piece] - ang[fr.other]
    rot = np.stack([np.stack([np.cos(expect), -np.sin(expect)], -1),
                    np.stack([np.sin(expect), np.cos(expect)], -1)], -2)
    np.testing.assert_allclose(m, rot, atol=1e-9)


# ---------------------------------------------------------------- perfect fits
@pytest.mark.parametrize("group", GROUP_NAMES)
def test_sheet_cut_in_two_is_reassembled_by_both_methods(sheet2, group):
    g, ang, t = sheet2
    wp = print_for(group)
    assert fit_report(g, Placement(ang, t, wp)).e_fit_mm2 < 1e-8  # the truth is perfect
    problem = AlignProblem.build(g, wp)
    paper = align_paper(problem, restarts=15, seed=0)
    glob = align_global(problem, restarts=15, seed=0)
    random = paper.random_energies.mean()
    assert paper.energy < 1e-6 * random
    assert glob.energy <= paper.energy + 1e-12
    assert fit_report(g, Placement(glob.angles, glob.translations, wp)).e_fit_mm2 < 1e-6 * random


@pytest.mark.parametrize("group", GROUP_NAMES)
def test_sheet_cut_in_four_is_reassembled_by_the_global_method(sheet4, group):
    g, _, _ = sheet4
    problem = AlignProblem.build(g, print_for(group))
    res = align_global(problem, restarts=15, seed=0)
    assert res.energy < 1e-6 * res.random_energies.mean()
    assert res.energy <= res.info["paper_energy"]


@pytest.mark.parametrize("group", ["pg", "pgg", "p6"])
def test_global_reassembles_seven_pieces_where_restarts_struggle(sheet7, group):
    g, _, _ = sheet7
    problem = AlignProblem.build(g, print_for(group))
    res = align_global(problem, restarts=15, seed=0)
    assert res.energy < 1e-6 * res.random_energies.mean()
    assert res.energy <= res.info["paper_energy"]


@pytest.mark.parametrize("method", ["paper", "global"])
def test_moving_the_whole_pattern_keeps_the_optimum(sheet2, pants, method):
    c, s = np.cos(0.7), np.sin(0.7)
    turn = np.array([[c, -s], [s, c]])
    # a garment with a perfect fit keeps it wherever the pattern lies
    g = sheet2[0]
    wp = print_for("p4g")
    for garment in (g, g.with_uv(g.uv @ turn.T + [1234.5, -321.0])):
        out = align(garment, wp, method=method, restarts=15, seed=0)
        assert out.report["e_fit_aligned_mm2"] < 1e-6 * out.report["e_fit_random_mm2"]
    # and on a real garment the optimum found, carried along with the pattern, keeps
    # exactly its E_fit (so the optimal value cannot depend on where the pattern lies)
    base = align(pants, wp, method=method, restarts=5, seed=1, fix=["0"])
    moved = pants.with_uv(pants.uv @ turn.T + [1234.5, -321.0])
    carried = Placement(base.angles + 0.7, base.translations @ turn.T + [1234.5, -321.0], wp)
    assert fit_report(moved, carried).e_fit_mm2 == pytest.approx(
        base.report["e_fit_aligned_mm2"], rel=1e-9)


# ---------------------------------------------------------------- user control
@pytest.mark.parametrize("method", ["paper", "global"])
def test_fixed_pieces_do_not_move(pants, method):
    wp = print_for("cmm")
    rng = np.random.default_rng(5)
    init = Placement(rng.uniform(0, 6, pants.n_pieces), rng.uniform(-50, 50, (4, 2)), wp)
    out = align(pants, wp, method=method, restarts=4, seed=2, init=init,
                fix=[pants.piece_names[0], "1:rot", "2:trans"])
    assert np.all(out.angles[[0, 1]] == init.angles[[0, 1]])
    assert np.all(out.translations[[0, 2]] == init.translations[[0, 2]])
    assert abs(out.angles[2] - init.angles[2]) > 1e-6  # the free parts did move
    assert np.abs(out.translations[1] - init.translations[1]).max() > 1e-6


def test_translation_only_keeps_rotations(pants):
    wp = print_for("p2")
    out = align(pants, wp, restarts=3, rotation=False)
    assert np.all(out.angles == 0.0)
    assert out.report["e_fit_aligned_mm2"] < out.report["e_fit_random_mm2"]


@pytest.mark.parametrize("method", ["paper", "global"])
def test_rotation_only_keeps_translations(pants, method):
    wp = print_for("p4")
    init = Placement(np.zeros(4), [[1.0, 2.0], [3.0, 4.0], [5.0, 6.0], [7.0, 8.0]], wp)
    out = align(pants, wp, method=method, restarts=2, translation=False, init=init)
    assert np.array_equal(out.translations, init.translations)
    assert np.any(out.angles != 0.0)


@pytest.mark.parametrize("method", ["paper", "global"])
def test_a_seam_of_weight_zero_has_no_influence(pants, method):
    wp = print_for("p4m", 35.0)
    line = 1
    # (piece 0 held still: three moving pieces keep the global method's joint grid small)
    zero = align(pants, wp, method=method, restarts=3, seed=4, weights={line: 0.0}, fix=["0"])
    # the same garment without that seam line at all
    keep = pants.seam_line_of_edge != line
    cut = pants.copy()
    cut.seam_edges = pants.seam_edges[keep]
    remap = np.cumsum(np.arange(len(pants.seam_lines)) != line) - 1
    cut.seam_line_of_edge = remap[pants.seam_line_of_edge[keep]]
    cut.seam_lines = [s for i, s in enumerate(pants.seam_lines) if i != line]
    without = align(cut, wp, method=method, restarts=3, seed=4, fix=["0"])
    np.testing.assert_allclose(zero.angles, without.angles, atol=1e-7)
    np.testing.assert_allclose(zero.translations, without.translations, atol=1e-6)


@pytest.mark.parametrize("method", ["paper", "global"])
def test_grain_keeps_every_piece_within_tolerance_of_the_print(pants, method):
    wp = print_for("p4m")
    free = align(pants, wp, method=method, restarts=3, seed=0, fix=["0"])
    out = align(pants, wp, method=method, restarts=3, seed=0, grain_tol_deg=2.0, fix=["0"])
    gamma = np.array([g.deg for g in pants.grains()])  # no grain lines: from the drape
    rel = (np.degrees(out.angles) - gamma)[1:] % 180.0  # against the fabric's grain (x);
    assert np.all(np.minimum(rel, 180.0 - rel) <= 2.0 + 1e-9)  # piece 0 is fixed
    assert out.report["e_fit_aligned_mm2"] >= 0.5 * free.report["e_fit_aligned_mm2"]


def test_grain_line_of_the_piece_is_used(pants):
    g = pants.copy()
    g.grainlines = {0: ((0.0, 0.0), (1.0, 1.0))}  # piece 0's grain at 45 degrees
    g.grain = ()  # inferred again, now with the file's line
    out = align(g, print_for("p1"), restarts=4, grain_tol_deg=1.0)
    assert out.grains[0]["grain_source"] == "file"
    rel0 = (np.degrees(out.angles[0]) - 45.0) % 180.0
    assert min(rel0, 180.0 - rel0) <= 1.0 + 1e-9


def test_reflection_option_runs_and_reports(pants):
    out = align(pants, print_for("pmm"), restarts=4, reflect=True)
    assert out.report["reflect"] is True
    assert out.report["e_fit_aligned_mm2"] < out.report["e_fit_random_mm2"]


def test_same_seed_same_answer(pants):
    a = align(pants, print_for("p6m"), restarts=5, seed=11)
    b = align(pants, print_for("p6m"), restarts=5, seed=11)
    assert np.array_equal(a.angles, b.angles) and np.array_equal(a.translations, b.translations)


# ---------------------------------------------------------------- global optimum
@pytest.mark.parametrize("group", ["pgg", "p6m"])
def test_global_is_within_two_percent_of_brute_force(pants, group):
    """Three movable pieces (one fixed): a 12 x 12 grid per piece over its cell, all
    12^6 combinations, best ones refined; rotations from the global result."""
    wp = print_for(group, 50.0)
    fix = np.zeros(pants.n_pieces, bool)
    fix[0] = True
    problem = AlignProblem.build(pants, wp, fix_rot=fix, fix_trans=fix)
    res = align_global(problem, restarts=6, seed=0)
    paper = align_paper(problem, restarts=6, seed=0)
    assert res.energy <= paper.energy
    _, ref = brute_force(problem, res.angles, res.translations, grid=12)
    assert res.energy <= 1.02 * ref


def test_bad_input_is_reported(pants):
    with pytest.raises(ValueError, match="no piece 'sleeve'"):
        align(pants, print_for("p1"), fix=["sleeve"])
    with pytest.raises(ValueError, match="unknown method"):
        align(pants, print_for("p1"), method="magic")
    with pytest.raises(ValueError, match="restarts"):
        align(pants, print_for("p1"), restarts=0)
