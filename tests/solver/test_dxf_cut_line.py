"""A DXF garment is cut on the file's own cut line (layer 1, as the pattern maker drew it),
not on one the station offsets from the sew line; the sew line is the file's layer 14, else
the cut line inset by the file's allowance, else by --seam-allowance / station.toml; the
print is matched at the sew line (issue 34). Pattern: a CAD-like export of the bundled GPG
tee (cut line = sew line + 10 mm); the Gerber tee where ../shared is present."""

from __future__ import annotations

import argparse
import json
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import shapely

from solver.garment import load_garment
from solver.garment.allowance import AllowanceRules, cut_lines
from solver.garment.dxf import read_dxf_pattern
from solver.garment.symmetrise import symmetrise
from solver.garment.symmetry import mirror_pairs
from solver.nest.sources import placement_problem
from solver.placement import Placement
from solver.seams.export import export_cad_dxf
from solver.wallpaper import Wallpaper
from station.cli import main
from station.cliload import load_garment_arg
from station.config import load_config
from station.order import OrderGarment
from station.seams_view import read_dxf
from station.steps.dxfseams import dxf_job_garment
from station.steps.order import load_order_garment

GPG_TEE = Path(__file__).resolve().parents[1] / "data" / "garments" / \
    "garment_pattern_generator" / "tee.json"  # MIT, bundled
STATION_RULES = AllowanceRules(seam_mm=15.0, hem_mm=40.0, opening_mm=5.0)  # not the file's


@pytest.fixture(scope="module")
def tee_dxf(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("cad") / "tee.dxf"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        export_cad_dxf(load_garment(GPG_TEE), out, allowance_mm=10.0, seed=3)
    return out


def _same_shape(a: np.ndarray, b: np.ndarray) -> float:
    """Hausdorff distance (mm) of two rings once laid corner to corner (the garment only
    moves pieces side by side)."""
    b = b + (a.min(axis=0) - b.min(axis=0))
    return float(shapely.hausdorff_distance(shapely.LinearRing(a), shapely.LinearRing(b)))


def test_pieces_are_cut_on_the_files_line_and_matched_at_the_sew_line(tee_dxf) -> None:
    found = read_dxf(tee_dxf, allowance_mm=10.0)
    g = found.garment
    drawn = [p.cut for p in read_dxf_pattern(tee_dxf, allowance_mm=10.0).cut_list()]
    assert sorted(g.cut_outlines) == list(range(g.n_pieces)) == list(range(len(drawn)))
    station_made = g.copy()
    station_made.cut_outlines = {}
    own = cut_lines(station_made, STATION_RULES)
    for i, cut in enumerate(cut_lines(g, STATION_RULES)):
        assert _same_shape(cut.outline, drawn[i]) < 1e-6  # the file's line, as drawn
        assert _same_shape(own[i].outline, drawn[i]) > 5.0  # what the station would cut
        # each sew edge carries the file's 10 mm, whatever the station's rules say
        assert np.median(cut.allowance) == pytest.approx(10.0, abs=0.05)
    # the seams' twin vertices, where E_fit matches the print, lie on the sew line, one
    # allowance inside the cut line, never on it
    cut_of = {i: shapely.LinearRing(g.cut_outlines[i]) for i in g.cut_outlines}
    twins = np.unique(g.seam_edges)
    gap = [shapely.distance(shapely.Point(g.uv[v]), cut_of[int(g.piece_of_vertex[v])])
           for v in twins]
    assert min(gap) >= 9.9
    # the marker's pieces (the daemon's nest step) carry the file's cut line, and inside
    # it the sew line with the file's allowance
    placement = Placement.identity(g.n_pieces, Wallpaper("p4m", [60.0, 0.0], [0.0, 60.0]))
    problem = placement_problem(g, placement, width=2000.0, allowance=STATION_RULES)
    for i, piece in enumerate(problem.pieces):
        assert _same_shape(piece.outline, g.cut_outlines[i]) < 1e-6
        assert shapely.Polygon(piece.outline).contains(shapely.Polygon(piece.sew_line))
        assert np.median(piece.allowance) == pytest.approx(10.0, abs=0.05)
    # a reshape moves the sew line: the file's allowance no longer holds, the station cuts
    assert g.with_uv(g.uv + 1e-3).cut_outlines == {}


def test_the_sew_line_inset_comes_from_the_job_or_the_station(tee_dxf, tmp_path) -> None:
    config = load_config(None, {"allowance": {"seam_mm": 12.0},
                                "seams": {"confirm_below": 0.0}})  # never wait here
    job = SimpleNamespace(id=1, garment=str(tee_dxf), options={"seam_allowance": 14.0})
    for options, mm in (({"seam_allowance": 14.0}, 14.0), ({}, 12.0)):
        job.options = options
        g = dxf_job_garment(job, tmp_path, config)
        assert np.median(np.concatenate([c.allowance for c in cut_lines(g)])) == \
            pytest.approx(mm, abs=0.05)
    args = argparse.Namespace(garment=str(tee_dxf), units=None, size=None, command="fit",
                              seam_allowance=8.0)
    g = load_garment_arg(args)
    assert np.median(cut_lines(g)[0].allowance) == pytest.approx(8.0, abs=0.05)
    # an order's garment: the inset the daemon's plan and the order commands hand it
    g = load_order_garment(OrderGarment(tee_dxf, None, 1), (9.0, "the station's"))
    assert np.median(cut_lines(g)[0].allowance) == pytest.approx(9.0, abs=0.05)


def test_inspect_says_where_the_lines_come_from(shared_data, tmp_path, monkeypatch,
                                                capsys) -> None:
    tee = shared_data / "garments" / "astm_aama_dxf" / "MEN_CLASSIC_TEE.DXF"
    (tmp_path / "station.toml").write_text("[allowance]\nseam_mm = 12.0\n")
    monkeypatch.setenv("STATION_CONFIG", str(tmp_path / "station.toml"))
    assert main(["inspect", str(tee), "--json"]) == 0
    notes = json.loads(capsys.readouterr().out)["dxf"]["notes"]
    assert "cut line: the file's layer 1, as the pattern maker drew it (the allowance it " \
           "carries is the file's)" in notes
    assert "sew line of 7 piece(s): the cut line inset by 12 mm (station.toml " \
           "allowance.seam_mm)" in notes


def test_symmetrised_pairs_keep_the_files_cut_lines(tee_dxf) -> None:
    """A CAD's left and right are mirror copies: ``--symmetrise`` hardly moves them, so
    both are still cut on the file's line (the second on its first's, mirrored)."""
    g = read_dxf(tee_dxf, allowance_mm=10.0).garment
    sym = symmetrise(g, mirror_pairs(g))
    h = sym.garment
    assert len(sym.pairs) == 2 and sym.moves and sorted(h.cut_outlines) == sorted(g.cut_outlines)
    worst = max(m.max_mm for m in sym.moves)
    for p in sym.pairs:
        was = shapely.LinearRing(g.cut_outlines[p.second])
        now = shapely.LinearRing(h.cut_outlines[p.second])
        assert shapely.hausdorff_distance(was, now) <= 2 * worst + 0.05
    assert all(np.median(c.allowance) == pytest.approx(10.0, abs=0.1) for c in cut_lines(h))


def test_a_fold_is_listed_as_the_pieces_centre_seam(shared_data) -> None:
    """The tee's front and back are cut on the fold: each mirror line is listed as the
    piece's centre seam with itself, across its whole sew line, and it is the axis the
    unfolded piece is symmetric about."""
    found = read_dxf(shared_data / "garments" / "astm_aama_dxf" / "MEN_CLASSIC_TEE.DXF")
    folds = found.folds()
    assert [found.pieces[i].name for i, _ in folds] == ["REGULAR_TEEFR", "REGULAR_TEEBK"]
    listed = found._facts()["centre_seams"]
    assert [c["piece"] for c in listed] == ["REGULAR_TEEFR", "REGULAR_TEEBK"]
    for (i, line), item in zip(folds, listed, strict=True):
        sew = found.pieces[i].loop
        a, b = line
        d = (b - a) / np.linalg.norm(b - a)
        mirrored = a + (sew - a) @ (2 * np.outer(d, d) - np.eye(2))
        assert shapely.hausdorff_distance(shapely.Polygon(sew), shapely.Polygon(mirrored)) < 0.5
        # it runs from edge to edge of the sew line: both ends on it
        ring = shapely.LinearRing(sew)
        assert max(shapely.distance(shapely.points(line), ring)) < 1e-6
        assert item["length_mm"] == pytest.approx(np.linalg.norm(b - a), abs=0.1)
        assert item["length_mm"] > 500
