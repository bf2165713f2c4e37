"""DXF-AAMA/ASTM import and export, on files this test writes (and the shared ones if present)."""

from __future__ import annotations

import json

import ezdxf
import numpy as np
import pytest
import shapely

from solver.garment.dxf import read_dxf_pattern
from solver.nest import NestProblem, Piece, verify_layout
from solver.nest.dxf_aama import dxf_sizes, read_dxf_aama, write_dxf_aama
from solver.nest.instance import affine
from station.cli import main


def bodice(size: str, grow: float = 0.0) -> Piece:
    w, h = 200.0 + grow, 300.0 + grow
    outline = [[0, 0], [w, 0], [w, h], [w / 2, h + 40], [0, h]]
    return Piece("front", outline, quantity=2, size=size,
                 holes=[np.array([[50, 50], [70, 50], [70, 70], [50, 70]], float)],
                 grainline=np.array([[100.0, 40.0], [100.0, 260.0]]),  # vertical in the CAD
                 notches=[(np.array([w, 150.0]), np.array([-1.0, 0.0]))],
                 marks=np.array([[100.0, 150.0]]))


def test_round_trip_keeps_outline_grain_notches_marks(tmp_path):
    path = tmp_path / "bodice.dxf"
    write_dxf_aama([bodice("M")], path)
    (p,) = read_dxf_aama(path)
    src = bodice("M")
    # Quantity 2: a left and a right, one mirrored pair
    assert p.name == "front" and p.size == "M" and p.quantity == 1 and p.mirrored_pair
    assert shapely.Polygon(p.outline).area == pytest.approx(src.area, rel=1e-9)
    assert np.allclose(p.grainline, src.grainline)
    assert len(p.holes) == 1 and shapely.Polygon(p.holes[0]).area == pytest.approx(400)
    (at, d, _), = p.notches
    assert np.allclose(at, [200, 150]) and np.allclose(d, [-1, 0], atol=1e-9)
    assert np.allclose(p.marks, [[100, 150]])
    # the reference frame turns the grain along the roll (+x)
    g = affine(p.base, p.grainline)
    assert np.allclose(g[1] - g[0], [220, 0], atol=1e-9)


def test_graded_file_sizes(tmp_path):
    path = tmp_path / "graded.dxf"
    write_dxf_aama([bodice("S", -10), bodice("M"), bodice("L", 10)], path)
    assert dxf_sizes(path) == ["S", "M", "L"]
    (m,) = read_dxf_aama(path, size="M")
    assert m.area == pytest.approx(bodice("M").area)
    two = read_dxf_aama(path, size=["S", "L"])
    assert [p.name for p in two] == ["front S", "front L"]
    assert read_dxf_aama(path)[0].size == "S"  # no sample size: the first
    with pytest.raises(ValueError, match="no size XL"):
        read_dxf_aama(path, size="XL")


def test_accumark_style_split_boundary_inches_and_mirror_line(tmp_path):
    """Boundary in open pieces, units only in a TEXT, a half piece with a mirror line."""
    doc = ezdxf.new("R12")
    msp = doc.modelspace()
    msp.add_text("Units: ENGLISH", dxfattribs={"layer": "1"})
    blk = doc.blocks.new("HALF_1")
    blk.add_text("Piece Name: BACK", dxfattribs={"layer": "1"})
    pts = [(0, 0), (4, 0), (4, 10), (0, 10)]
    blk.add_polyline2d([pts[0], pts[1]], dxfattribs={"layer": "1"})
    blk.add_polyline2d([pts[2], pts[1]], dxfattribs={"layer": "1"})  # reversed piece
    blk.add_polyline2d([pts[2], pts[3], pts[0]], dxfattribs={"layer": "1"})
    blk.add_line((0, 0), (0, 10), dxfattribs={"layer": "6"})  # mirror (fold) line
    blk.add_line((2, 2), (2, 8), dxfattribs={"layer": "7"})
    msp.add_blockref("HALF_1", (100, 0))
    path = tmp_path / "half.dxf"
    doc.saveas(path)
    (p,) = read_dxf_aama(path)
    assert p.name == "BACK"
    assert p.area == pytest.approx(2 * 4 * 10 * 25.4**2, rel=1e-6)  # unfolded, in mm
    lo, hi = p.outline.min(0), p.outline.max(0)
    assert np.allclose(lo, [96 * 25.4, 0], atol=1e-6) and np.allclose(hi, [104 * 25.4, 254])
    (q,) = read_dxf_aama(path, unfold=False)
    assert q.area == pytest.approx(4 * 10 * 25.4**2, rel=1e-6)


def test_bad_files_give_one_line_errors(tmp_path):
    empty = tmp_path / "empty.dxf"
    ezdxf.new("R12").saveas(empty)
    with pytest.raises(ValueError, match="no pattern pieces"):
        read_dxf_aama(empty)
    junk = tmp_path / "junk.dxf"
    junk.write_text("this is not a dxf\n")
    with pytest.raises(ValueError, match="junk.dxf"):
        read_dxf_aama(junk)


def test_nest_a_dxf_marker_from_the_console(tmp_path, capsys, monkeypatch):
    path = tmp_path / "marker.dxf"
    write_dxf_aama([bodice("M"), Piece("sleeve", [[0, 0], [250, 0], [200, 120], [50, 120]],
                                       grainline=np.array([[0.0, 60.0], [250.0, 60.0]]))], path)
    out = tmp_path / "LAYOUT.json"
    png = tmp_path / "marker.png"
    rc = main(["nest", str(path), "-o", str(out), "--width", "900", "--gap", "3", "--time", "1",
               "--pairs", "--json", "--png", str(png)])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["pieces"] == 4 and 0 < summary["density"] < 1
    assert png.stat().st_size > 1000
    from solver.nest import Layout

    layout = Layout.load(out)
    pieces = read_dxf_aama(path)
    for p in pieces:
        p.mirrored_pair = True
    assert verify_layout(layout, NestProblem(pieces, 900.0, gap=3.0)) == []
    # grain along the roll: every placed grain line is horizontal
    for p in layout.pieces:
        d = p.grainline[1] - p.grainline[0]
        assert abs(d[1]) < 1e-6 * np.linalg.norm(d)
    # no --width and the DXF does not say it: the station's roll (station.toml, 1000 mm)
    monkeypatch.delenv("STATION_CONFIG", raising=False)
    monkeypatch.chdir(tmp_path)
    assert main(["nest", str(path), "-o", str(out), "--time", "1", "--json"]) == 0
    assert json.loads(out.read_text())["width"] == 1000.0
    (tmp_path / "station.toml").write_text("[nest]\nwidth_mm = 700.0\n")
    assert main(["nest", str(path), "-o", str(out), "--time", "1", "--json"]) == 0
    assert json.loads(out.read_text())["width"] == 700.0


def test_shared_industry_files_import(shared_data):
    files = sorted((shared_data / "garments" / "astm_aama_dxf").glob("*.[dD][xX][fF]"))
    assert files
    files = [f for f in files if f.stat().st_size < 150_000]  # the small ones keep this fast
    for f in files:
        pieces = read_dxf_aama(f)
        assert pieces, f
        for p in pieces:
            assert shapely.Polygon(p.outline).is_valid, (f.name, p.name)
            assert p.area > 100.0 and p.grainline is not None
        assert len(dxf_sizes(f)) >= 1


@pytest.mark.parametrize("garment", ["berkeley/skirt-coarse.obj",
                                     "garmentcode/pants_specification.json"])
def test_cut_and_sew_lines_round_trip_on_layers_1_and_14(tmp_path, data_dir, garment):
    from solver.garment import load_garment
    from solver.nest.sources import garment_pieces

    g = load_garment(data_dir / "garments" / garment,
                     units="m" if garment.startswith("berkeley") else None)
    pieces = garment_pieces(g)
    write_dxf_aama(pieces, tmp_path / "p.dxf")
    doc = ezdxf.readfile(tmp_path / "p.dxf")
    layers = {str(e.dxf.layer) for b in doc.blocks for e in b if e.dxftype() == "POLYLINE"}
    assert {"1", "14"} <= layers
    back = read_dxf_aama(tmp_path / "p.dxf")
    assert [p.name for p in back] == [p.name for p in pieces]
    for p, q in zip(pieces, back):
        np.testing.assert_allclose(q.outline, p.outline, atol=1e-6)  # layer 1: the cut line
        np.testing.assert_allclose(q.sew_line, p.sew_line, atol=1e-6)  # layer 14
        assert shapely.Polygon(q.outline).contains(shapely.Polygon(q.sew_line))


def test_without_layer_14_the_sew_line_is_the_stated_allowance_inside(tmp_path):
    write_dxf_aama([bodice("M")], tmp_path / "net.dxf")
    (piece,) = read_dxf_aama(tmp_path / "net.dxf", allowance_mm=10.0)
    cut, sew = shapely.Polygon(piece.outline), shapely.Polygon(piece.sew_line)
    assert cut.contains(sew)
    d = cut.exterior.distance(shapely.points(np.asarray(piece.sew_line)))
    assert d.min() == pytest.approx(10.0, abs=1e-6)
    assert read_dxf_aama(tmp_path / "net.dxf")[0].sew_line is None  # nothing stated


def test_a_piece_too_narrow_for_the_allowance_is_told_not_silently_left_without_sew_line(
        tmp_path, capsys):
    """A 16 mm binding strip under a 10 mm allowance has no sew line inside it: the
    console says so on one line, naming the file and the piece, and still nests."""
    path = tmp_path / "strip.dxf"
    write_dxf_aama([bodice("M"), Piece("binding", [[0, 0], [300, 0], [300, 16], [0, 16]])],
                   path)
    with pytest.warns(UserWarning, match="'binding' is too narrow for a 10 mm seam"):
        pieces = read_dxf_aama(path, allowance_mm=10.0)
    assert [p.sew_line is None for p in pieces] == [False, True]
    rc = main(["nest", str(path), "-o", str(tmp_path / "L.json"), "--width", "900",
               "--time", "1", "--seam-allowance", "10"])
    warned = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert rc == 0
    assert len(warned) == 1 and warned[0].startswith("station nest: warning: ")
    assert str(path) in warned[0] and "'binding'" in warned[0]


def test_notches_as_cads_draw_them_slit_v_polyline_and_v_of_two_lines(tmp_path):
    """A slit, a V drawn as one polyline and a V drawn as two LINEs meeting at the tip:
    three notches, each at its mouth on the outline and pointing into the piece (the two
    LINEs of a V are one notch, not a double notch)."""
    doc = ezdxf.new("R12")
    blk = doc.blocks.new("SQUARE")
    blk.add_text("Piece Name: PANEL", dxfattribs={"layer": "1"})
    blk.add_polyline2d([(0, 0), (200, 0), (200, 100), (0, 100)], close=True,
                       dxfattribs={"layer": "1"})
    blk.add_line((50, 0), (50, 6), dxfattribs={"layer": "4"})  # slit on the bottom
    blk.add_polyline2d([(200, 40), (194, 46), (200, 52)], dxfattribs={"layer": "4"})
    blk.add_line((120, 100), (123, 94), dxfattribs={"layer": "4"})  # V of two lines, top
    blk.add_line((123, 94), (126, 100), dxfattribs={"layer": "4"})
    doc.modelspace().add_blockref("SQUARE", (0, 0))
    path = tmp_path / "notches.dxf"
    doc.saveas(path)
    (piece,) = read_dxf_pattern(path, units="mm", allowance_mm=10.0).pieces
    got = sorted((tuple(np.round(a, 6)), tuple(np.round(d, 6))) for a, d in piece.notches)
    assert got == [((50.0, 0.0), (0.0, 1.0)), ((123.0, 100.0), (0.0, -1.0)),
                   ((200.0, 46.0), (-1.0, 0.0))]
