"""A piece cut on the fold is aligned as a tailor centres a print on a centre front: the
print mirrors about the fold, i.e. the fold lies on a mirror axis of the print (issue 34,
item 1). Measured on the Gerber tee (front and back cut on the fold) where ../shared is
present; the tie's maths (projection and its chain rule) on a made-up pair always."""

from __future__ import annotations

import numpy as np
import pytest

from solver.align.symmetric import PairTie, align_symmetric, pair_rule
from solver.garment.dxf_garment import load_dxf
from solver.garment.symmetry import MirrorPair, fold_pairs, mirror_pairs
from solver.geometry import FLIP, rotation_matrix
from solver.placement import Placement
from solver.wallpaper import Wallpaper
from tests.conftest import SHARED_DATA

P4M = Wallpaper("p4m", (60.0, 0.0), (0.0, 60.0))  # a 60 mm square check with mirrors


def fold_mismatch_mm(garment, placement: Placement, fold: MirrorPair) -> float:
    """Largest distance (mm) between the print at each vertex of the piece and the print
    at its mirror image across the fold, up to the print's symmetries (`Wallpaper.mismatch`)."""
    on = garment.uv[garment.piece_of_vertex == fold.first]
    piece = np.full(len(on), fold.first)
    here = placement.to_wallpaper(on, piece)
    there = placement.to_wallpaper(fold.map_first_to_second(on), piece)
    return float(np.hypot(*placement.fabric.mismatch(there, here).T).max())


@pytest.fixture(scope="module")
def gerber_tee():
    """The tee read once for the module (the `shared_data` fixture is per test)."""
    path = SHARED_DATA / "garments" / "astm_aama_dxf" / "MEN_CLASSIC_TEE.DXF"
    if not path.is_file():
        pytest.skip(f"{path} is absent (fresh clone): the Gerber tee's folds not tested")
    garment = load_dxf(path, size="50")
    return garment, mirror_pairs(garment)


def test_the_print_mirrors_about_each_fold(gerber_tee) -> None:
    garment, pairs = gerber_tee
    folds = fold_pairs(garment)
    assert [garment.piece_names[f.first] for f in folds] == ["REGULAR_TEEFR", "REGULAR_TEEBK"]
    assert all(f.relative_rms < 0.01 for f in folds)  # each piece is its own mirror image
    tied = align_symmetric(garment, P4M, pairs, compare=False, restarts=3)
    free_garment = garment.copy()
    free_garment.folds = {}  # as before: the folds not known to alignment
    free = align_symmetric(free_garment, P4M, pairs, compare=False, restarts=3)
    for fold in folds:
        assert fold_mismatch_mm(garment, tied, fold) < 1e-6
        assert fold_mismatch_mm(garment, free, fold) > 10.0
    report = tied.report["symmetry"]
    assert [f["mode"] for f in report["folds"]] == ["mirror", "mirror"]
    assert max(f["print_mismatch_mm"] for f in report["folds"]) < 1e-6
    assert "folds" not in free.report["symmetry"]
    assert tied.report["off_grain_max_deg"] <= 1.0 + 1e-6  # the fold turned along the grain
    assert max(report["pair_print_mismatch_mm"]) < 1e-6  # the sleeves still mirror


def test_a_print_without_mirrors_is_centred_and_said(gerber_tee) -> None:
    garment, pairs = gerber_tee
    p4 = Wallpaper("p4", (60.0, 0.0), (0.0, 60.0))
    placed = align_symmetric(garment, p4, pairs, compare=False, restarts=2)
    report = placed.report["symmetry"]
    assert [f["mode"] for f in report["folds"]] == ["same", "same"]
    assert "no mirror or glide along the fold" in report["fold_note"]
    assert placed.report["off_grain_max_deg"] <= 1.0 + 1e-6


def _made_up_tie() -> tuple[PairTie, MirrorPair]:
    """Piece 0 cut on a fold at 30 degrees through (40, 10); piece 1 its mirrored copy."""
    d = np.array([np.cos(np.radians(30.0)), np.sin(np.radians(30.0))])
    reflection = 2.0 * np.outer(d, d) - np.eye(2)
    a = np.array([40.0, 10.0])
    fold = MirrorPair(0, 0, 0.0, 100.0, reflection @ FLIP, a - reflection @ a)
    pair = MirrorPair(0, 1, 0.0, 100.0, rotation_matrix(0.4), np.array([300.0, -20.0]))
    rules = (pair_rule(fold, P4M, nap=True), pair_rule(pair, P4M))  # grain along the fold
    return PairTie(rules, np.array([0, 0]), P4M), fold


def test_the_fold_tie_is_a_projection_with_its_chain_rule() -> None:
    tie, fold = _made_up_tie()
    assert tie.rules[0].mode == "mirror"  # p4m has a mirror along the fold
    q_a, q_t = np.array([0.61]), np.array([[13.0, -7.0]])
    angles, trans = tie.expand(q_a, q_t)
    placement = Placement(angles, trans, P4M)
    inside = np.random.default_rng(0).uniform(0.0, 100.0, (50, 2))
    zero = np.zeros(len(inside), int)
    mirrored = P4M.mismatch(placement.to_wallpaper(fold.map_first_to_second(inside), zero),
                            placement.to_wallpaper(inside, zero))
    assert np.abs(mirrored).max() < 1e-9
    again = tie.expand(angles[:1], trans[:1])  # on the constraint already: unchanged
    assert np.allclose(again[0][0], angles[0]) and np.allclose(again[1][0], trans[0])
    weights_a, weights_t = np.array([0.7, -1.3]), np.array([[0.2, 0.5], [-0.9, 0.4]])

    def f(a, t):
        ea, et = tie.expand(a, t)
        return float(ea @ weights_a + (et * weights_t).sum())

    g_a, g_t = tie.pull_back(angles, weights_a, weights_t)
    h = 1e-6
    for k in range(2):
        step = np.zeros((1, 2))
        step[0, k] = h
        assert (f(q_a, q_t + step) - f(q_a, q_t - step)) / (2 * h) == pytest.approx(
            g_t[0, k], abs=1e-6)
    assert (f(q_a + h, q_t) - f(q_a - h, q_t)) / (2 * h) == pytest.approx(g_a[0], abs=1e-6)


def test_a_fold_lands_on_a_mirror_line_not_a_glide_line() -> None:
    """cmm with a cell three times longer across the fold than along it: mirror lines
    every 60 mm, glide lines between them; the nearest line is often a glide's."""
    cmm = Wallpaper("cmm", (20.0, -60.0), (20.0, 60.0))
    fold = MirrorPair(0, 0, 0.0, 100.0, np.diag([1.0, -1.0]) @ FLIP, np.zeros(2))  # along x
    tie = PairTie((pair_rule(fold, cmm, nap=True),), np.array([0]), cmm)
    inside = np.random.default_rng(1).uniform(0.0, 100.0, (40, 2))
    zero = np.zeros(len(inside), int)
    for across in np.linspace(0.0, 120.0, 13):  # 30-42 mm and 90-102 mm: nearer a glide
        angles, trans = tie.expand(np.array([0.0]), np.array([[3.0, across]]))
        placement = Placement(angles, trans, cmm)
        mirrored = cmm.mismatch(placement.to_wallpaper(fold.map_first_to_second(inside), zero),
                                placement.to_wallpaper(inside, zero))
        assert np.abs(mirrored).max() < 1e-9, across
