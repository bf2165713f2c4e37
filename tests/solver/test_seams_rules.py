"""The seam inference's rules on small cases made by hand: a dart marked as a CAD marks it
(notches at its legs, a drill hole short of its tip) found as a seam of the piece with
itself; a gathered seam found by its notches alone; seams that would sew one point to two
or close a corner like a bag's excluded."""

from __future__ import annotations

import itertools
import warnings

import ezdxf
import numpy as np
import shapely

from solver.garment.dxf import read_dxf_pattern
from solver.garment.dxf_garment import sew_pieces
from solver.seams import SewPiece, infer_seams
from solver.seams.darts import DRILL_SETBACK_MM, dart_cap
from solver.seams.junctions import junction_conflicts
from solver.seams.match import _pairs
from solver.seams.outline import point_at
from solver.seams.runs import candidate_runs

MOUTH = np.array([[170.0, 400.0], [130.0, 400.0]])  # a waist dart's legs meet the waist here
TIP = np.array([150.0, 280.0])


def _write_darted_front(path) -> None:
    """A 300 x 400 mm front with a waist dart, written as a CAD writes it: the cut line (10
    mm out) runs across the dart's mouth with its take-up, notches on the cut line at the
    legs, a drill hole 1/2 in short of the tip, no seam data."""
    closed = [(0, 0), (300, 0), (300, 400), tuple(MOUTH[0]),
              tuple(dart_cap(MOUTH[0], TIP, MOUTH[1])), tuple(MOUTH[1]), (0, 400)]
    cut = shapely.Polygon(closed).buffer(10.0, join_style="mitre", mitre_limit=2.0).exterior
    doc = ezdxf.new("R12")
    doc.modelspace().add_text("Units: METRIC", dxfattribs={"layer": "1"})
    blk = doc.blocks.new(name="P0")
    blk.add_polyline2d(list(cut.coords)[:-1], close=True, dxfattribs={"layer": "1"})
    for m in MOUTH:
        notch = cut.interpolate(cut.project(shapely.Point(m)))
        blk.add_point((notch.x, notch.y), dxfattribs={"layer": "4"})
    drill = TIP + (MOUTH.mean(0) - TIP) / np.linalg.norm(MOUTH.mean(0) - TIP) * DRILL_SETBACK_MM
    blk.add_point(tuple(drill), dxfattribs={"layer": "13"})
    blk.add_line((150, 50), (150, 250), dxfattribs={"layer": "7"})
    blk.add_text("Piece Name: FRONT", dxfattribs={"layer": "1"})
    doc.modelspace().add_blockref("P0", (0, 0))
    doc.saveas(path)


def test_a_dart_marked_by_notches_and_a_drill_hole_is_sewn_leg_to_leg(tmp_path):
    _write_darted_front(tmp_path / "front.dxf")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pattern = read_dxf_pattern(tmp_path / "front.dxf", allowance_mm=10.0)
    assert "1 dart(s) opened" in pattern.pieces[0].sew_source
    pieces = sew_pieces(pattern.cut_list())
    darts = [s for s in infer_seams(pieces) if s.piece_a == s.piece_b == 0]
    assert len(darts) == 1
    leg = float(np.linalg.norm(MOUTH[0] - TIP))
    assert abs(darts[0].length_mm - leg) < 5.0
    ends = point_at(pieces[0], np.array([darts[0].a_start, darts[0].a_end, darts[0].b_start,
                                         darts[0].b_end]))
    # a_start meets b_end: the two mouth ends, and a_end meets b_start at the tip
    assert np.linalg.norm(ends[1] - TIP) < 5 and np.linalg.norm(ends[2] - TIP) < 5
    mouth = sorted([ends[0].tolist(), ends[3].tolist()])
    assert np.allclose(mouth, sorted(MOUTH.tolist()), atol=5.0)


def _skirt_and_waistband(notched: bool) -> list[SewPiece]:
    """A 600 mm skirt waist gathered onto a 400 mm waistband; the balance notches (a single,
    a double) at the same shares of both, read against each other."""
    skirt = np.array([[0, 0], [600, 0], [600, 500], [0, 500]], float)
    band = np.array([[0, 0], [400, 0], [400, 40], [0, 40]], float)
    # the skirt's waist runs from x=600 to 0, the band's bottom from 0 to 400: a share s of
    # the skirt's waist meets the share 1 - s of the band's
    skirt_notches = [[600 - 0.3 * 600, 500], [600 - 0.7 * 600, 500], [600 - 0.7 * 600 - 6, 500]]
    band_notches = [[0.7 * 400, 0], [0.3 * 400, 0], [0.3 * 400 + 4, 0]]
    return [SewPiece("SKIRT FRONT", skirt, notches=np.array(skirt_notches if notched else [])),
            SewPiece("WAISTBAND FRONT", band, notches=np.array(band_notches if notched else []))]


def test_a_gathered_seam_is_found_by_its_notches():
    seams = [s for s in infer_seams(_skirt_and_waistband(notched=True)) if s.piece_a != s.piece_b]
    assert len(seams) == 1
    s = seams[0]
    lengths = sorted([s.a_end - s.a_start, s.b_end - s.b_start])
    assert np.allclose(lengths, [400, 600], atol=1.0)
    # lengths 1.5 : 1 never match: without the notches there is no seam
    assert not infer_seams(_skirt_and_waistband(notched=False))


def test_two_seams_never_sew_one_point_to_two_or_close_a_corner():
    square = np.array([[0, 0], [200, 0], [200, 200], [0, 200]], float)
    pieces = [SewPiece("A", square), SewPiece("B", square + [300, 0])]
    runs, _ = candidate_runs(pieces)
    pairs = _pairs(runs, [p.length for p in pieces], [np.zeros(0), np.zeros(0)])
    assert len(pairs) == 16  # every side of A against every side of B
    conflicts = {tuple(c) for c in junction_conflicts(pieces, runs, pairs).tolist()}
    for x, y in itertools.combinations(range(len(pairs)), 2):
        (a1, b1), (a2, b2) = (sorted((runs[i], runs[j]), key=lambda r: r.piece)
                              for i, j in pairs[[x, y]].tolist())
        corner_of_a = {a1.start % 800, a1.end % 800} & {a2.start % 800, a2.end % 800}
        corner_of_b = {b1.start % 800, b1.end % 800} & {b2.start % 800, b2.end % 800}
        # sides sharing a corner of A or of B: one point sewn to two, or a bag's corner
        assert ((x, y) in conflicts) == bool(corner_of_a or corner_of_b)
    chosen = infer_seams(pieces)
    assert 1 <= len(chosen) <= 2  # two squares: at most two opposite sides sewn
