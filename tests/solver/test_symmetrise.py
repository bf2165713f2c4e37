"""--symmetrise (solver.garment.symmetrise): a near pair becomes one pattern cut twice, and
stays one through alignment, reshaping and the cut lines."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from solver.align.symmetric import align_symmetric
from solver.garment import load_garment
from solver.garment.allowance import AllowanceRules
from solver.garment.notches import cut_ready
from solver.garment.symmetrise import symmetrise, symmetrise_as_recorded
from solver.garment.symmetry import (
    centre_seams,
    cut_mismatch,
    fit_pairs,
    mirror_correspondence,
    mirror_gap,
    mirror_pairs,
)
from solver.reshape import reshape
from solver.wallpaper import Wallpaper

REPO = Path(__file__).resolve().parents[2]
DATA = REPO / "tests" / "data" / "garments"
TSHIRT = DATA / "berkeley" / "tshirt-coarse.obj"
# three kinds of pair: Berkeley (simulator output, pairs 1-3 mm apart, drape, centre
# seams), Garment-Pattern-Generator (sleeves sewn to an unpaired front and back),
# GarmentCode (every piece paired, centre front and back)
GARMENTS = {"berkeley/tshirt-coarse.obj": "m", "garment_pattern_generator/tee.json": None,
            "garmentcode/tshirt_specification.json": None}
PMM = Wallpaper("pmm", (60, 0), (0, 80))
P1 = Wallpaper("p1", (50, 0), (10, 45))


def _load(name: str):
    return load_garment(DATA / name, units=GARMENTS[name])


def _seam_structure(g) -> list[tuple[str, int, int, int]]:
    """Per seam line in order: name, pieces, number of twin edges."""
    return [(s.name, s.piece_a, s.piece_b, int((g.seam_line_of_edge == k).sum()))
            for k, s in enumerate(g.seam_lines)]


@pytest.mark.parametrize("name", sorted(GARMENTS))
def test_a_symmetrised_pair_is_one_pattern_cut_twice(name: str) -> None:
    g = _load(name)
    pairs = mirror_pairs(g)
    sym = symmetrise(g, pairs)
    h = sym.garment
    assert not sym.skipped and len(sym.pairs) == len(pairs)
    assert h.n_pieces == g.n_pieces and h.piece_names == g.piece_names
    for p in sym.pairs:
        copy = mirror_correspondence(h, p)
        assert copy is not None  # vertex for vertex
        second = np.flatnonzero(h.piece_of_vertex == p.second)
        assert np.abs(p.map_first_to_second(h.uv[copy]) - h.uv[second]).max() < 1e-9
        assert mirror_gap(p, h.piece_outline(p.first), h.piece_outline(p.second)) < 1e-9
        # the pairs found again on the new garment are the same, and exact
        again = fit_pairs(h, [(p.first, p.second)])[0]
        assert again.rms_mm < 1e-6 and np.allclose(again.rotation, p.rotation)
    # the seams are re-derived, not lost: the same seam lines (numbers and names, which
    # --weights and allowances use) between the same pieces with as many edges, each line
    # near where it was, centre seams still on the centre line
    assert _seam_structure(h) == _seam_structure(g)
    for k in range(len(g.seam_lines)):
        here, there = (x.uv[x.seam_edges[x.seam_line_of_edge == k]].mean(axis=(0, 1))
                       for x in (g, h))
        assert np.linalg.norm(here - there) < 10.0
    centre = centre_seams(h, sym.pairs)
    assert len(centre) == len(centre_seams(g, pairs))
    by_pieces = {frozenset((p.first, p.second)): p for p in sym.pairs}
    for k in centre:  # a centre seam sews each edge to its own mirror image, exactly
        p = by_pieces[frozenset((h.seam_lines[k].piece_a, h.seam_lines[k].piece_b))]
        e = h.seam_edges[h.seam_line_of_edge == k]
        on_first = (h.piece_of_vertex[e[:, 0]] == p.first)[:, None]
        here, there = np.where(on_first, e[:, :2], e[:, 2:]), np.where(on_first, e[:, 2:],
                                                                     e[:, :2])
        gap = p.map_first_to_second(h.uv[here.ravel()]) - h.uv[there.ravel()]
        assert np.abs(gap).max() < 1e-9
    # the average: each piece moves at most about the pair's own difference, area ~kept
    rms = {k: p.rms_mm for p in pairs for k in (p.first, p.second)}
    assert {m.piece for m in sym.moves} == set(rms)
    for m in sym.moves:
        assert m.rms_mm <= 2 * rms[m.piece] + 0.1 and abs(m.area_change_pct) < 0.5
    if h.xyz is not None:  # twins meet in 3D, and the drape keeps its scale
        e = h.seam_edges
        assert np.abs(h.xyz[e[:, 0]] - h.xyz[e[:, 2]]).max() < 1e-9
        edge = h.xyz[h.faces[:, 0]] - h.xyz[h.faces[:, 1]]
        edge_old = g.xyz[g.faces[:, 0]] - g.xyz[g.faces[:, 1]]
        assert np.median(np.linalg.norm(edge, axis=1)) == pytest.approx(
            np.median(np.linalg.norm(edge_old, axis=1)), rel=0.05)


def test_the_berkeley_pairs_move_and_the_report_says_how_far() -> None:
    g = load_garment(TSHIRT, units="m")
    sym = symmetrise(g, mirror_pairs(g))
    assert max(m.max_mm for m in sym.moves) > 1.0  # the halves differed by millimetres
    text = sym.lines()
    assert len(text) == 6 and all("moved" in t and "RMS" in t and "area" in t for t in text)
    # the same pattern whatever order the pairs come in
    assert np.array_equal(symmetrise(g, mirror_pairs(g)[::-1]).garment.uv, sym.garment.uv)
    record = json.loads(json.dumps(sym.to_dict()))
    again = symmetrise_as_recorded(g, record)  # what later commands rebuild
    assert np.array_equal(again.garment.uv, sym.garment.uv)
    # symmetrising twice changes nothing
    twice = symmetrise(sym.garment, sym.pairs)
    assert not twice.moves and np.array_equal(twice.garment.uv, sym.garment.uv)


def test_a_pair_whose_seams_do_not_correspond_is_left_alone() -> None:
    """A declared "pair" of a sleeve and the front: no edge-for-edge seams, so nothing is
    forced; the report says why."""
    g = _load("garment_pattern_generator/tee.json")
    names = g.piece_names
    bad = fit_pairs(g, [(names.index("lfsleeve"), names.index("front"))])
    sym = symmetrise(g, bad)
    assert not sym.pairs and len(sym.skipped) == 1 and sym.skipped[0][2]
    assert np.array_equal(sym.garment.uv, g.uv)


@pytest.mark.parametrize("name,fabric", [("berkeley/tshirt-coarse.obj", PMM),
                                         ("berkeley/tshirt-coarse.obj", P1),
                                         ("garment_pattern_generator/tee.json", PMM)])
def test_reshaping_keeps_a_symmetrised_pair_one_pattern(name: str, fabric: Wallpaper) -> None:
    g = _load(name)
    sym = symmetrise(g, mirror_pairs(g))
    h = sym.garment
    placement = align_symmetric(h, fabric, sym.pairs, compare=False, method="paper",
                                restarts=1, grain_tol_deg=1.0)
    modes = {m for *_, m in placement.pairs}
    assert modes == ({"mirror"} if fabric.group == "pmm" else {"same"})
    new, report = reshape(h, placement, pairs=fit_pairs(h, [p[:2] for p in placement.pairs]))
    assert report.max_displacement_mm > 0.5  # it did reshape
    for p in fit_pairs(new, [p[:2] for p in placement.pairs]):
        assert mirror_correspondence(new, p) is not None
        assert mirror_gap(p, new.piece_outline(p.first), new.piece_outline(p.second)) < 0.1
    # 3. the cut: cut lines and notches of the two pieces mirror each other too
    cuts, notches = cut_ready(new, AllowanceRules(), placement if fabric is PMM else None)
    for p in fit_pairs(new, [p[:2] for p in placement.pairs]):
        assert max(cut_mismatch(p, cuts, notches)) < 0.1


def test_station_align_fit_and_inspect_symmetrise(tmp_path: Path, capsys) -> None:
    from station.cli import main

    fabric = tmp_path / "pmm.json"
    fabric.write_text(json.dumps(PMM.to_dict()))
    out = tmp_path / "placement.json"
    assert main(["align", str(TSHIRT), "--units", "m", "--fabric", str(fabric),
                 "--restarts", "1", "--symmetrise", "--json", "-o", str(out)]) == 0
    run = capsys.readouterr()
    rep = json.loads(run.out)
    assert sorted(map(tuple, rep["symmetrise"]["pairs"])) == [(0, 1), (2, 3), (4, 5)]
    assert len(rep["symmetrise"]["moves"]) == 6 and "moved" in run.err
    saved = json.loads(out.read_text())
    assert saved["report"]["symmetrise"] == rep["symmetrise"]
    # `station fit` on the placement measures the pattern it was made on
    assert main(["fit", str(TSHIRT), "--units", "m", "--fabric", str(fabric),
                 "--placement", str(out), "--json"]) == 0
    fit = capsys.readouterr()
    assert "as the placement was made" in fit.err
    assert json.loads(fit.out)["e_fit_mm2"] == pytest.approx(rep["e_fit_aligned_mm2"])
    saved["report"]["symmetrise"]["pairs"] = [[0, "piece1"]]  # a malformed record
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(saved))
    assert main(["fit", str(TSHIRT), "--units", "m", "--fabric", str(fabric),
                 "--placement", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(bad) in err and "symmetrise" in err
    assert main(["inspect", str(TSHIRT), "--units", "m", "--symmetrise", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["symmetrise"]["moves"] == \
        rep["symmetrise"]["moves"]


def test_shared_garments_symmetrise_exactly_or_say_why(shared_data: Path) -> None:
    """Every Berkeley, GarmentCode and Garment-Pattern-Generator garment with pairs: each
    pair is made exactly one pattern with its seams kept, or left alone with a reason."""
    root = shared_data / "garments"
    files = [f for f in sorted((root / "berkeley_garment_library").rglob("*.obj"))
             if not f.stem.endswith(("-m", "-w"))]
    files += sorted((root / "garment_pattern_generator").glob("*.json"))
    files += sorted((root / "garmentcode").rglob("*specification*.json"))
    assert files
    made = total = 0
    for f in files:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            g = load_garment(f, units="m" if f.suffix == ".obj" else None)
        pairs = mirror_pairs(g)
        sym = symmetrise(g, pairs)
        h = sym.garment
        assert len(sym.pairs) + len(sym.skipped) == len(pairs), f.name
        assert all(why for *_, why in sym.skipped)
        assert len(h.seam_lines) == len(g.seam_lines), f.name
        for p in sym.pairs:
            assert mirror_correspondence(h, p) is not None, (f.name, p.first, p.second)
        made += len(sym.pairs)
        total += len(pairs)
    assert made >= 0.9 * total  # nearly every pair of the library (70 of 73 today)
