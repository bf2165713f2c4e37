"""A left/right pair cuts as mirror images: allowance and notches decided once per pair.

Each edge's allowance is decided on its own (the hem test reads heights off the drape or
the panels' placement) and each seam's notches are measured along one of its sides; a
pair whose halves are classed or measured differently used to cut differently, although
its outlines mirror exactly. Here both come out mirrored by construction.
"""

from __future__ import annotations

import numpy as np
import pytest

from solver.align import align
from solver.align.symmetric import align_symmetric
from solver.garment import load_garment
from solver.garment.allowance import AllowanceRules, cut_lines, edge_allowances, open_edges
from solver.garment.notches import cut_ready
from solver.garment.symmetrise import symmetrise
from solver.garment.symmetry import (
    cut_mismatch,
    fit_pairs,
    mirror_gap,
    mirror_pairs,
    mirrored_edges,
)
from solver.reshape import reshape
from solver.wallpaper import Wallpaper
from tests.conftest import DATA

GARMENTS = DATA / "garments"
PMM = Wallpaper("pmm", (60, 0), (0, 80))
WITH_PAIRS = [("berkeley/tshirt-coarse.obj", "m"), ("berkeley/pants-coarse.obj", "m"),
              ("berkeley/skirt-coarse.obj", "m"), ("berkeley/shorts-iso.obj", "m"),
              ("garmentcode/pants_specification.json", None),
              ("garmentcode/tshirt_specification.json", None),
              ("garmentcode/shirt_mean_specification.json", None),
              ("garment_pattern_generator/tee.json", None),
              ("garment_pattern_generator/pants_straight_sides.json", None)]
TOLERANCE_MM = 0.1


def _symmetrised(name: str, units: str | None):
    g = load_garment(GARMENTS / name, units=units)
    sym = symmetrise(g, mirror_pairs(g))
    assert sym.pairs
    return sym


@pytest.mark.parametrize("name,units", WITH_PAIRS, ids=[n for n, _ in WITH_PAIRS])
def test_every_symmetrised_pair_cuts_as_mirror_images(name: str, units: str | None) -> None:
    sym = _symmetrised(name, units)
    h = sym.garment
    cuts, notches = cut_ready(h, AllowanceRules(notch_spacing_mm=100.0))
    for p in sym.pairs:
        cut, notch = cut_mismatch(p, cuts, notches)
        assert cut < TOLERANCE_MM and notch < TOLERANCE_MM, (p.first, p.second, cut, notch)
        assert notches[p.first]  # there is something to compare


def test_mirrored_edges_pair_each_edge_with_its_image() -> None:
    h = _symmetrised("berkeley/tshirt-coarse.obj", "m").garment
    for p in mirror_pairs(h):
        rows = mirrored_edges(h, p)
        bhe = h.boundary_half_edges()
        assert len(rows) == int((h.piece_of_vertex[bhe[:, 0]] == p.first).sum())
        assert (h.piece_of_vertex[rows[:, 2:]] == p.second).all()
        for first, second in ((0, 2), (1, 3)):  # c is the image of a, d of b
            gap = p.map_first_to_second(h.uv[rows[:, first]]) - h.uv[rows[:, second]]
            assert np.abs(gap).max() < 1e-6


def _upside_down(g, piece: int):
    """``g`` as a flat pattern (no placement around the body) with one piece drawn upside
    down (turned 180 degrees about its centre), as digitised pieces often come: the hem
    test, reading heights within each piece, then finds no hem on that piece's leg."""
    g = g.copy()
    g.panel_frames = {}
    on = g.piece_of_vertex == piece
    g.uv = g.uv.copy()
    g.uv[on] = 2 * g.uv[on].mean(axis=0) - g.uv[on]
    return g


def test_a_hem_missed_on_one_half_gets_the_hem_allowance_on_both() -> None:
    """Synthetic: one front leg drawn upside down, so the hem test misses that leg's hem
    (an opening, 10 mm) while the other leg's is a hem (20 mm)."""
    sym = _symmetrised("garmentcode/pants_specification.json", None)
    pair = next(p for p in sym.pairs if "pant_f" in sym.garment.piece_names[p.first])
    g = _upside_down(sym.garment, pair.second)
    pair = fit_pairs(g, [(pair.first, pair.second)])[0]  # still a pair, one piece turned
    assert pair.rms_mm < 1e-6
    edges, opening, is_hem = open_edges(g)
    on = g.piece_of_vertex[edges[:, 0]]
    assert is_hem[opening[on == pair.first]].any()  # the fault: one leg's hem is missed
    assert not is_hem[opening[on == pair.second]].any()
    rules = AllowanceRules()
    apart = edge_allowances(g, rules, ())  # each half on its own
    assert apart[pair.first][0].max() == rules.hem_mm
    assert apart[pair.second][0].max() == rules.opening_mm
    both = edge_allowances(g, rules)  # the pairs found: one decision per mirrored edge
    assert both[pair.second][0].max() == rules.hem_mm
    rows = mirrored_edges(g, pair)
    loops = {i: g.piece_loops(i)[0] for i in (pair.first, pair.second)}
    at = {i: {(int(a), int(b)): k for k, (a, b) in enumerate(zip(lp, np.roll(lp, -1)))}
          for i, lp in loops.items()}
    mine = [both[pair.first][0][at[pair.first][(a, b)]] for a, b in rows[:, :2].tolist()]
    theirs = [both[pair.second][0][at[pair.second][(d, c)]] for c, d in rows[:, 2:].tolist()]
    assert mine == theirs
    cuts = cut_lines(g, rules)
    assert mirror_gap(pair, cuts[pair.first].outline, cuts[pair.second].outline) < TOLERANCE_MM
    split = cut_lines(g, rules, ())
    assert mirror_gap(pair, split[pair.first].outline, split[pair.second].outline) > 5.0


def test_an_allowance_named_on_one_half_applies_to_the_pair() -> None:
    sym = _symmetrised("garment_pattern_generator/tee.json", None)
    h, pair = sym.garment, sym.pairs[0]
    rules = AllowanceRules().with_overrides({f"{h.piece_names[pair.first]}/open": 35.0})
    cuts = cut_lines(h, rules)
    assert cuts[pair.second].allowance.max() == 35.0
    assert mirror_gap(pair, cuts[pair.first].outline, cuts[pair.second].outline) < TOLERANCE_MM


@pytest.mark.parametrize("symmetrised", [True, False], ids=["symmetrised", "as-drawn"])
def test_darted_pants_notches_mirror_after_a_plaid_alignment_and_reshape(
        symmetrised: bool) -> None:
    """GarmentCode pants (darted back pieces, waist seams to an unpaired waistband) under a
    pmm plaid, aligned with the pairs mirrored and reshaped with them tied, as `station
    align` and `station reshape` run it. The waist seam's notches were measured along the
    waistband on one half and along the darted (three-run) leg side on the other: 11.5 mm
    apart. Symmetrised, the cut mirrors within 0.1 mm; as drawn the two halves are meshed
    apart, and the notches mirror as well as the cut lines do."""
    g = load_garment(GARMENTS / "garmentcode" / "pants_specification.json")
    pairs = mirror_pairs(g)
    if symmetrised:
        sym = symmetrise(g, pairs)
        g, pairs = sym.garment, sym.pairs
    placement = align_symmetric(g, PMM, pairs, compare=False, method="paper", restarts=1,
                                grain_tol_deg=1.0)
    assert {m for *_, m in placement.pairs} == {"mirror"}
    new, _ = reshape(g, placement, pairs=fit_pairs(g, [p[:2] for p in placement.pairs]))
    cuts, notches = cut_ready(new, AllowanceRules(notch_spacing_mm=100.0, notch_on_print=True),
                              placement)
    for p in fit_pairs(new, [p[:2] for p in placement.pairs]):
        cut, notch = cut_mismatch(p, cuts, notches)
        if symmetrised:
            assert cut < TOLERANCE_MM and notch < TOLERANCE_MM, (p.first, p.second, cut, notch)
        else:
            outline = mirror_gap(p, new.piece_outline(p.first), new.piece_outline(p.second))
            assert notch < 1.5 * outline + 0.05, (p.first, p.second, outline, notch)


def test_shared_jacket_cut_lines_mirror(shared_data) -> None:
    """ARCSim's jacket: its up axis is found across the body, so one armhole counted as
    a hem (20 mm) and its mirror image as an opening (10 mm)."""
    from bench.paircut import load

    g = load(shared_data / "garments" / "arcsim_meshes" / "jacket.obj")
    sym = symmetrise(g, mirror_pairs(g))
    assert len(sym.pairs) == 3
    cuts, notches = cut_ready(sym.garment, AllowanceRules(notch_spacing_mm=100.0))
    for p in sym.pairs:
        cut, notch = cut_mismatch(p, cuts, notches)
        assert cut < TOLERANCE_MM and notch < TOLERANCE_MM, (p.first, p.second, cut, notch)


def test_shared_garments_cut_pairs_as_mirror_images(shared_data) -> None:
    """Every Berkeley, GarmentCode, GPG and ARCSim garment with pairs, symmetrised: each
    pair's cut lines and notches mirror within 0.1 mm (``python -m bench paircut`` also
    aligns and reshapes them under a plaid)."""
    from bench.paircut import check, garments, load

    checked = 0
    for path in garments(shared_data / "garments"):
        g = load(path)
        pairs = mirror_pairs(g)
        if not pairs:
            continue
        sym = symmetrise(g, pairs)
        for i, j, cut, notch in check(sym.garment, sym.pairs):
            assert cut < TOLERANCE_MM and notch < TOLERANCE_MM, (path.name, i, j, cut, notch)
            checked += 1
    assert checked >= 70


def test_shared_dress_keeps_or_drops_a_notch_with_its_mirror_image(shared_data) -> None:
    """GarmentCode's pencil dress under a pmm plaid: one front's waist notch came too
    close to the (unpaired, reshaped) skirt's sew line and was dropped on that half only,
    so the fronts had 19 and 20 notches."""
    from bench.paircut import aligned_reshaped, check, load

    g = load(shared_data / "garments" / "garmentcode" / "repo_specs"
             / "dress_pencil_specification.json")
    sym = symmetrise(g, mirror_pairs(g))
    new, placement = aligned_reshaped(sym.garment, sym.pairs)
    found = check(new, fit_pairs(new, [p[:2] for p in placement.pairs]), placement)
    assert found
    for i, j, cut, notch in found:
        assert cut < TOLERANCE_MM and notch < TOLERANCE_MM, (i, j, cut, notch)


def test_pairs_an_alignment_left_apart_are_not_mirrored_by_the_cut() -> None:
    """An operator's veto (or ``--no-symmetry``) is what the placement records: the cut
    honours it, and only a placement from no alignment takes the pairs the garment shows."""
    sym = _symmetrised("garmentcode/pants_specification.json", None)
    pair = next(p for p in sym.pairs if "pant_f" in sym.garment.piece_names[p.first])
    g = _upside_down(sym.garment, pair.second)
    rules = AllowanceRules()
    kept = align_symmetric(g, PMM, fit_pairs(g, [(pair.first, pair.second)]), restarts=1)
    vetoed = align(g, PMM, restarts=1)  # what `station align --no-symmetry` runs
    assert kept.pairs and not vetoed.pairs and vetoed.report
    for placement, mirrored in ((kept, True), (vetoed, False)):
        cuts, _ = cut_ready(g, rules, placement)
        assert (cuts[pair.second].allowance.max() == rules.hem_mm) == mirrored
    cuts, _ = cut_ready(g, rules)  # no alignment: the pairs the garment shows
    assert cuts[pair.second].allowance.max() == rules.hem_mm
