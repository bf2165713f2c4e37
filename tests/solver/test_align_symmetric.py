"""Symmetric placement (solver.align.symmetric): left/right pairs mirror the print exactly."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from solver.align.symmetric import align_symmetric, expand, pair_rule, quotient_garment
from solver.fit import fit_report
from solver.garment import load_garment
from solver.garment.symmetry import mirror_pairs
from solver.placement import Placement
from solver.wallpaper import Wallpaper
from station.cli import main

REPO = Path(__file__).resolve().parents[2]
TSHIRT = REPO / "examples" / "tshirt-iso.obj"
PRINTS = {
    "p4m": Wallpaper("p4m", (50, 0), (0, 50), (7, 3)),
    "pmm": Wallpaper("pmm", (60, 0), (0, 80)),
    "cmm": Wallpaper("cmm", (30, -40), (30, 40)),  # centred cell, mirrors along x and y
    "pmg": Wallpaper("pmg", (40, 0), (0, 55)),
}


@pytest.fixture(scope="module")
def tshirt():
    return load_garment(TSHIRT, units="m")


def _sampled_mirror_mismatch(g, placement: Placement, i: int, j: int, pair) -> float:
    """Max print mismatch between points of piece i (outline and inside) and their mirror
    images on piece j, by Wallpaper.mismatch."""
    rng = np.random.default_rng(1)
    pts = g.uv[g.piece_of_vertex == i]
    pts = pts[rng.choice(len(pts), size=min(200, len(pts)), replace=False)]
    w_i = placement.to_wallpaper(pts, np.full(len(pts), i))
    w_j = placement.to_wallpaper(pair.map_first_to_second(pts), np.full(len(pts), j))
    return float(np.linalg.norm(placement.fabric.mismatch(w_i, w_j), axis=1).max())


@pytest.mark.parametrize("group", sorted(PRINTS))
def test_pairs_mirror_the_print_exactly_on_grain(tshirt, group: str) -> None:
    fabric = PRINTS[group]
    pairs = mirror_pairs(tshirt)
    placement = align_symmetric(tshirt, fabric, pairs, compare=False, method="paper",
                                restarts=3, grain_tol_deg=1.0)
    assert sorted(map(tuple, placement.pairs)) == [(0, 3, "mirror"), (1, 2, "mirror"),
                                                   (4, 5, "mirror")]
    by_pieces = {(p.first, p.second): p for p in pairs}
    for i, j, _ in placement.pairs:
        assert _sampled_mirror_mismatch(tshirt, placement, i, j, by_pieces[(i, j)]) < 0.1
    # the report's E_fit is the garment's own
    assert placement.report["e_fit_aligned_mm2"] == pytest.approx(
        fit_report(tshirt, placement).e_fit_mm2)


def test_quotient_has_the_same_fit_as_the_garment(tshirt) -> None:
    fabric = PRINTS["p4m"]
    rules = [pair_rule(p, fabric) for p in mirror_pairs(tshirt)]
    quotient, keep = quotient_garment(tshirt, rules)
    assert quotient.n_pieces == 3 and len(quotient.seam_edges) == len(tshirt.seam_edges)
    rng = np.random.default_rng(0)
    for _ in range(3):
        q = Placement(rng.uniform(-np.pi, np.pi, 3), rng.uniform(-100, 100, (3, 2)), fabric)
        angles, trans = expand(q, rules, keep, tshirt.n_pieces)
        full = Placement(angles, trans, fabric)
        assert fit_report(tshirt, full).e_fit_mm2 == pytest.approx(
            fit_report(quotient, q).e_fit_mm2, rel=1e-9)


def test_print_without_mirror_keeps_pairs_same_and_says_so(tshirt) -> None:
    fabric = Wallpaper("p1", (50, 0), (10, 45))
    pairs = mirror_pairs(tshirt)
    placement = align_symmetric(tshirt, fabric, pairs, method="paper", restarts=3,
                                grain_tol_deg=1.0)
    assert {mode for _, _, mode in placement.pairs} == {"same"}
    sym = placement.report["symmetry"]
    assert "not mirrored" in sym["note"]
    assert sym["e_fit_unconstrained_mm2"] > 0 and sym["price_ratio"] > 0
    # "same": the print's lattice sits at the mirrored place on the flipped outline
    by_pieces = {(p.first, p.second): p for p in pairs}
    for i, j, _ in placement.pairs:
        anchor = placement.translations[i]  # where the print's origin lies on piece i
        on_j = by_pieces[(i, j)].map_first_to_second(anchor[None])
        w = placement.to_wallpaper(on_j, np.array([j]))
        assert np.linalg.norm(fabric.mismatch(w, np.zeros((1, 2)))) < 1e-6


def test_mirrors_off_grain_fall_back_to_same(tshirt) -> None:
    # a pmm print turned 30 degrees on the fabric has no mirror along the grain
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    fabric = Wallpaper("pmm", (60 * c, 60 * s), (-80 * s, 80 * c))
    rules = [pair_rule(p, fabric) for p in mirror_pairs(tshirt)]
    assert {r.mode for r in rules} == {"same"}
    assert {r.mode for r in (pair_rule(p, PRINTS["pmm"], nap=True)
                             for p in mirror_pairs(tshirt))} == {"mirror"}


def test_flat_pattern_pairs_mirror() -> None:
    g = load_garment(REPO / "tests" / "data" / "garments" / "garmentcode" /
                     "pants_specification.json")
    pairs = mirror_pairs(g)
    placement = align_symmetric(g, PRINTS["pmm"], pairs, compare=False, method="paper",
                                restarts=2, grain_tol_deg=1.0)
    assert len(placement.pairs) == 2 and {m for *_, m in placement.pairs} == {"mirror"}
    by_pieces = {(p.first, p.second): p for p in pairs}
    for i, j, _ in placement.pairs:
        assert _sampled_mirror_mismatch(g, placement, i, j, by_pieces[(i, j)]) < 0.1


def test_station_align_records_pairs_and_their_price(tmp_path: Path, capsys) -> None:
    """`station align`, run in this process as the executable runs it."""
    fabric = tmp_path / "fabric.json"
    fabric.write_text(json.dumps(PRINTS["pmm"].to_dict()))
    out = tmp_path / "placement.json"
    base = ["align", str(TSHIRT), "--units", "m", "--fabric", str(fabric), "--restarts", "2",
            "--grain", "1", "-o", str(out)]
    assert main(base + ["--json"]) == 0, capsys.readouterr().err
    rep = json.loads(capsys.readouterr().out)
    saved = json.loads(out.read_text())
    assert sorted(map(tuple, saved["pairs"])) == [(0, 3, "mirror"), (1, 2, "mirror"),
                                                  (4, 5, "mirror")]
    assert rep["symmetry"]["e_fit_unconstrained_mm2"] > 0
    assert Placement.load(out).pairs == saved["pairs"]
    assert main(base + ["--no-symmetry"]) == 0
    assert json.loads(out.read_text())["pairs"] == []


def test_front_view_shows_each_pair_mirrored(tshirt, tmp_path: Path) -> None:
    from station.front_view import draw_front_view, front_view, worn_up_deg

    pairs = mirror_pairs(tshirt)
    placement = align_symmetric(tshirt, PRINTS["pmm"], pairs, compare=False, method="paper",
                                restarts=2, grain_tol_deg=1.0)
    shown, moved, axes = front_view(tshirt, placement, pairs)
    # the right way up, as worn: what is up on the body (the neck; a sleeve's cap, so it
    # hangs) points up the page on every piece; a pair's second piece is its first's
    # mirror image, so it is up only as far as the drape is symmetric
    worn = worn_up_deg(tshirt) + np.degrees(moved.angles - placement.angles)
    off = np.abs((worn - 90.0 + 180.0) % 360.0 - 180.0)
    assert off[[p.first for p in pairs]].max() < 1e-6
    assert off.max() < 15.0
    fabric = placement.fabric
    for p in pairs:
        i, j = p.first, p.second
        a, b = shown.uv[shown.piece_of_vertex == i], shown.uv[shown.piece_of_vertex == j]
        # j is i's mirror image across one vertical axis, print included
        axis = axes[(i, j)]
        mirrored = a * [-1, 1] + [2 * axis, 0]
        d = np.min(np.linalg.norm(mirrored[:, None] - b[None], axis=2), axis=1)
        assert np.median(d) < 5.0
        inside = a[::7]
        w_i = moved.to_wallpaper(inside, np.full(len(inside), i))
        w_j = moved.to_wallpaper(inside * [-1, 1] + [2 * axis, 0], np.full(len(inside), j))
        assert np.linalg.norm(fabric.mismatch(w_i, w_j), axis=1).max() < 0.5
    image = draw_front_view(tshirt, placement, pairs, tmp_path / "front.png")
    assert image.shape[1] == 1600 and (tmp_path / "front.png").stat().st_size > 10_000


def test_reshaped_pairs_move_as_mirror_images(tshirt) -> None:
    from solver.garment.refine import refined
    from solver.reshape import reshape
    from solver.reshape.energy import signed_areas
    from solver.reshape.pairs import PairTie

    pairs = mirror_pairs(tshirt)
    fabric = PRINTS["p4m"]
    placement = align_symmetric(tshirt, fabric, pairs, compare=False, method="paper",
                                restarts=3, grain_tol_deg=1.0)
    new, report = reshape(tshirt, placement, pairs=pairs)
    base, _ = refined(tshirt, fabric.covering_radius)
    assert new.n_vertices == base.n_vertices
    moved = new.uv - base.uv
    assert np.abs(moved).max() > 1.0  # it did reshape
    # every vertex of a second piece moved as the mirror of its first piece's displacement
    # there (interpolated in the first piece's mesh)
    assert PairTie(base, pairs).mirror_error(moved) < 0.1
    assert report.e_fit_after_mm2 < report.e_fit_before_mm2
    assert np.all(signed_areas(new.uv, new.faces) > 0)


def test_a_print_slightly_off_the_roll_still_mirrors_on_grain(tshirt) -> None:
    """A detected check lies a fraction of a degree off the roll: its mirror still keeps
    both pieces of every pair within the grain tolerance."""
    c, s = np.cos(np.radians(0.3)), np.sin(np.radians(0.3))
    fabric = Wallpaper("pmm", (60 * c, 60 * s), (-80 * s, 80 * c))
    pairs = mirror_pairs(tshirt)
    placement = align_symmetric(tshirt, fabric, pairs, compare=False, method="paper",
                                restarts=2, grain_tol_deg=1.0)
    assert {m for *_, m in placement.pairs} == {"mirror"}
    by_pieces = {(p.first, p.second): p for p in pairs}
    for i, j, _ in placement.pairs:
        assert _sampled_mirror_mismatch(tshirt, placement, i, j, by_pieces[(i, j)]) < 0.1
    assert placement.report["off_grain_max_deg"] <= 1.0 + 1e-6


@pytest.mark.parametrize("group", ["p1", "p4"])
def test_same_pairs_report_the_fit_of_the_garment_cut(tshirt, group: str,
                                                      tmp_path: Path) -> None:
    # no mirror on grain: the search runs on the garment's own E_fit, j following i
    fabric = {"p1": Wallpaper("p1", (30, 0), (9, 27)),
              "p4": Wallpaper("p4", (40, 0), (0, 40), (3, 5))}[group]
    placement = align_symmetric(tshirt, fabric, mirror_pairs(tshirt), compare=False,
                                method="paper", restarts=3, grain_tol_deg=1.0)
    assert {mode for *_, mode in placement.pairs} == {"same"}
    path = tmp_path / "placement.json"
    placement.save(path)
    written = Placement.load(path)
    reported = placement.report["e_fit_aligned_mm2"]
    assert fit_report(tshirt, written).e_fit_mm2 == pytest.approx(reported, rel=1e-6)
    assert placement.report["symmetry"]["e_fit_symmetric_mm2"] == reported
    # the quotient's stand-in answer is where the search started, never better
    assert reported <= placement.report["symmetry"]["e_fit_quotient_search_mm2"]
    # a local optimum of the real E_fit: no small tied move of a pair's first piece helps
    rules = [pair_rule(p, fabric) for p in mirror_pairs(tshirt)]
    quotient, keep = quotient_garment(tshirt, rules)
    first = [int(np.flatnonzero(keep == q)[0]) for q in range(quotient.n_pieces)]
    rng = np.random.default_rng(2)
    for _ in range(6):
        q = Placement(written.angles[first], written.translations[first]
                      + rng.normal(0, 0.3, (quotient.n_pieces, 2)), fabric)
        angles, trans = expand(q, rules, keep, tshirt.n_pieces)
        moved = fit_report(tshirt, Placement(angles, trans, fabric)).e_fit_mm2
        assert moved >= reported * (1 - 1e-6)


def test_tie_gradient_matches_finite_differences(tshirt) -> None:
    from solver.align.problem import AlignProblem
    from solver.align.refine import _energy_grad
    from solver.align.symmetric import PairTie

    fabric = Wallpaper("pmg", (40, 0), (0, 55))  # "mirror" rules with a glide: tau != 0
    rules = [pair_rule(p, fabric) for p in mirror_pairs(tshirt)]
    assert any(np.abs(r.op[:2, 2]).max() > 1 for r in rules)
    _, keep = quotient_garment(tshirt, rules)
    tie = PairTie(tuple(rules), keep)
    full = AlignProblem.build(tshirt, fabric)
    rec = np.arange(full.frames.n_edges)
    w = full.weight * full.frames.length[rec]

    def energy(q_a, q_t):
        a, t = tie.expand(q_a, q_t)
        return _energy_grad(full, a, t, rec, w), a

    rng = np.random.default_rng(3)
    q_a, q_t = rng.uniform(-np.pi, np.pi, 3), rng.uniform(-50, 50, (3, 2))
    (e, g_a, g_t), a = energy(q_a, q_t)
    gq_a, gq_t = tie.pull_back(a, g_a, g_t)
    h = 1e-6
    for k in range(3):
        da = np.zeros(3)
        da[k] = h
        num = (energy(q_a + da, q_t)[0][0] - energy(q_a - da, q_t)[0][0]) / (2 * h)
        assert num == pytest.approx(gq_a[k], rel=1e-4, abs=1e-3)
        for x in range(2):
            dt = np.zeros((3, 2))
            dt[k, x] = h
            num = (energy(q_a, q_t + dt)[0][0] - energy(q_a, q_t - dt)[0][0]) / (2 * h)
            assert num == pytest.approx(gq_t[k, x], rel=1e-4, abs=1e-3)
