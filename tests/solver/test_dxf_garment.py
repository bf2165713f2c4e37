"""DXF-AAMA/ASTM read as a cutting room reads it (issue 34, item 1), on the shared Gerber
files (skipped, saying so, where ../shared is absent) and on files this test writes."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
import shapely

from solver.garment import load_garment
from solver.garment.dxf import read_dxf_pattern
from solver.nest.dxf_aama import read_dxf_aama

TEE = "garments/astm_aama_dxf/MEN_CLASSIC_TEE.DXF"
SHARED_DATA = Path(__file__).resolve().parents[3] / "shared" / "data"


@pytest.fixture(scope="module")
def tee(request):
    path = SHARED_DATA / TEE
    if not path.is_file():
        pytest.skip(f"{path} is absent (fresh clone): the Gerber tee tests are skipped")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return path, read_dxf_pattern(path, size=["48", "50"], allowance_mm=10.0)


def by(pattern, name, size):
    (p,) = [p for p in pattern.pieces if p.name == name and p.size == size]
    return p


def test_quantity_is_carried_to_every_size_and_zero_is_not_cut(tee):
    _, pat = tee
    for size in ("48", "50"):
        assert by(pat, "REGULAR TEESL BK", size).quantity == 2  # stated on size 50 only
        assert by(pat, "REGULAR TEESL1", size).quantity == 0  # the one-piece alternative
    assert any("Quantity 0, not cut" in n and "TEESL1" in n for n in pat.notes)
    cut = [p.name for p in pat.cut_list()]
    assert not any("TEESL1" in n for n in cut)
    assert cut.count("REGULAR TEESL BK 48 L") == 1 and cut.count("REGULAR TEESL BK 48 R") == 1


def test_a_piece_cut_twice_is_a_left_and_a_mirrored_right(tee):
    _, pat = tee
    left, right = [p for p in pat.cut_list() if p.name.startswith("REGULAR TEESL FR 50")]
    assert not left.mirrored and right.mirrored
    a, b = shapely.Polygon(left.cut), shapely.Polygon(right.cut)
    assert a.area == pytest.approx(b.area, rel=1e-9)
    flipped = right.cut * [-1, 1]  # mirrored back: congruent to the left, not the same
    moved = flipped - flipped.mean(0) + left.cut.mean(0)
    assert shapely.Polygon(moved).symmetric_difference(a).area < 1e-6 * a.area
    nests = read_dxf_aama(tee[0], size="50")
    assert {p.name: p.mirrored_pair for p in nests}["REGULAR TEESL FR"]


def test_a_piece_cut_on_the_fold_is_unfolded_about_its_mirror_line(tee):
    path, pat = tee
    front = by(pat, "REGULAR TEEFR", "50")
    half = read_dxf_pattern(path, size="50", unfold_folds=False)
    half_front = by(half, "REGULAR TEEFR", "50")
    whole, part = shapely.Polygon(front.cut), shapely.Polygon(half_front.cut)
    assert whole.area == pytest.approx(2 * part.area, rel=1e-3)
    assert front.fold is not None
    assert len(front.notches) == 2 * len(half_front.notches)


def test_notches_and_turn_points_are_graded_from_the_sample_size(tee):
    _, pat = tee
    sample, graded = by(pat, "REGULAR TEEBK", "50"), by(pat, "REGULAR TEEBK", "48")
    assert "notches" in graded.carried and "turn points" in graded.carried
    assert not sample.carried
    assert len(graded.notches) == len(sample.notches) > 0
    ring = shapely.LinearRing(graded.cut)
    at = np.array([a for a, _ in graded.notches])
    assert ring.distance(shapely.points(at)).max() < 0.01  # on the size-48 outline
    # carried, not copied: size 48 is smaller, its notches move with its outline
    assert np.abs(at - np.array([a for a, _ in sample.notches])).max() > 1.0


def test_units_from_the_file_and_overridden(tee):
    path, pat = tee
    assert pat.units == "in"
    front = by(pat, "REGULAR TEEFR", "50")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        as_mm = read_dxf_pattern(path, size="50", units="mm")
    small = by(as_mm, "REGULAR TEEFR", "50")
    np.testing.assert_allclose(np.ptp(front.cut, 0), 25.4 * np.ptp(small.cut, 0), rtol=1e-9)
    assert "--units" in as_mm.notes[0]


def test_the_sew_line_is_the_cut_line_inset_by_the_allowance_and_said_so(tee):
    _, pat = tee
    p = by(pat, "REGULAR TEEBK", "50")
    assert p.sew_source.startswith("the cut line inset by 10 mm")
    d = shapely.LinearRing(p.cut).distance(shapely.points(p.sew))
    assert d.min() == pytest.approx(10.0, abs=0.01)


def test_the_tee_loads_as_a_garment_with_file_grain_and_inferred_seams(tee):
    path, _ = tee
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        g = load_garment(path)
    assert g.kind == "dxf" and g.units_in_file == "in"
    assert g.n_pieces == 7  # FR, BK, CO, two sleeve backs, two sleeve fronts; SL1/SFCO not cut
    assert "REGULAR_TEESL_FR_L" in g.piece_names  # one word: G-code piece markers split on spaces
    assert all(gr.source == "file" for gr in g.grains())
    assert len(g.seam_lines) > 0


def test_nest_units_scale_a_strip_packing_instance_never_ignored():
    """`station nest shirts.json --units cm` reads the instance in centimetres."""
    from solver.nest.sources import load_problem

    path = Path(__file__).resolve().parents[1] / "data" / "nesting" / "shirts.json"
    mm, cm = load_problem([path]), load_problem([path], units="cm")
    assert cm.width == pytest.approx(10 * mm.width)
    for a, b in zip(mm.pieces, cm.pieces, strict=True):
        assert shapely.Polygon(b.outline).area == pytest.approx(100 * a.area, rel=1e-9)


def test_size_picks_a_graded_size_and_is_refused_for_other_formats(tee, tmp_path):
    from solver.garment import GarmentError

    path, _ = tee
    assert {s.size for s in read_dxf_pattern(path, size="42").pieces} == {"42"}
    spec = Path(__file__).resolve().parents[1] / "data" / "garments" / \
        "garment_pattern_generator" / "tee.json"
    with pytest.raises(GarmentError, match="--size '42' is for a graded DXF"):
        load_garment(spec, size="42")


def test_nesting_a_dxf_on_a_print_says_it_is_not_print_matched(tmp_path, capsys):
    import json

    from solver.nest import Piece
    from solver.nest.dxf_aama import write_dxf_aama
    from station.cli import main

    path = tmp_path / "p.dxf"
    write_dxf_aama([Piece("front", [[0, 0], [200, 0], [200, 300], [0, 300]])], path)
    fabric = tmp_path / "F.json"
    fabric.write_text(json.dumps({"group": "p4m", "w1": [60, 0], "w2": [0, 60],
                                  "origin": [0, 0], "units": "mm"}))
    assert main(["nest", str(path), "--fabric", str(fabric), "-o", str(tmp_path / "L.json"),
                 "--width", "900", "--time", "1"]) == 0
    err = capsys.readouterr().err
    assert "not matched to the print" in err and "station align" in err


def test_a_job_takes_its_size_and_a_wrong_one_is_refused_at_submit(tee):
    """`station submit TEE.DXF --size 44`: the job's check loads that size."""
    from station.config import load_config
    from station.steps.submission import check_job

    path, _ = tee
    config = load_config(None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_job(str(path), None, {"size": "44"}, config)
        with pytest.raises(ValueError, match="no size XL; sizes are 42, 44"):
            check_job(str(path), None, {"size": "XL"}, config)
        with pytest.raises(ValueError, match="a size is a name"):
            check_job(str(path), None, {"size": 44}, config)
