"""A file that does not say where it sews: its seams read on the guessed sew line and on the
drawn line, kept from the one where they agree (solver.seams.readings)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from solver.garment import load_garment
from solver.garment.dxf import read_dxf_pattern
from solver.garment.dxf_garment import garment_of_pattern, infer_pattern_seams, sew_pieces
from solver.seams import infer_seams
from solver.seams.export import export_cad_dxf
from solver.seams.outline import point_at
from solver.seams.readings import carried
from solver.seams.score import onto, sample_seams, score_seams

SKIRT = Path(__file__).resolve().parents[1] / "data" / "garments" / "berkeley" \
    / "skirt-coarse.obj"


@pytest.fixture(scope="module")
def exports(tmp_path_factory):
    """(truth, pattern read as the station reads a file that says no allowance) of the
    skirt written net and with a 10 mm allowance."""
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        garment = load_garment(SKIRT, units="m")
        for allowance in (0.0, 10.0):
            path = tmp_path_factory.mktemp("dxf") / f"skirt-{allowance:g}.dxf"
            truth = export_cad_dxf(garment, path, allowance_mm=allowance, seed=0)
            out[allowance] = truth, read_dxf_pattern(path, allowance_mm=10.0)
    return out


def test_a_net_pattern_read_10_mm_in_has_its_seams_read_on_the_drawn_line(exports):
    """Its six gores' curved hips and waist, read 10 mm inside, lose their seams (56.7 %
    found on the seams bench); read on the drawn line, where the pattern maker drew them
    alike, they are found, and carried onto the sew line the station uses."""
    truth, pattern = exports[0.0]
    seams, pieces, note = infer_pattern_seams(pattern.cut_list())
    assert note is not None and "drawn line" in note
    found = score_seams(onto(truth, pieces), sample_seams(seams, pieces))
    guessed_only = score_seams(onto(truth, pieces), sample_seams(infer_seams(pieces), pieces))
    assert guessed_only.recall < 0.8  # the case this reading is for
    assert found.recall >= 0.95 and found.precision >= 0.95, found
    with pytest.warns(UserWarning, match="seams read on the drawn line"):  # to the job log
        garment_of_pattern(pattern)
    assert any("drawn line" in n for n in pattern.notes)  # and to `inspect --json`


def test_a_pattern_read_at_its_own_allowance_keeps_the_guessed_line(exports):
    _, pattern = exports[10.0]
    seams, pieces, note = infer_pattern_seams(pattern.cut_list())
    assert note is None
    assert seams == infer_seams(pieces)


def test_seams_carried_between_the_lines_keep_their_laps_and_their_places(exports):
    """A seam or a matched notch past a loop's start stays past it when carried (a notch
    taken modulo the loop had sent the seam's sampling back across the piece: 44 % found),
    and a seam carried there and back lands where it was."""
    _, pattern = exports[0.0]
    cut = pattern.cut_list()
    guessed, drawn = sew_pieces(cut), sew_pieces(cut, drawn=True)
    on_drawn = infer_seams(drawn)
    assert any(s.a_end > drawn[s.piece_a].length or s.b_end > drawn[s.piece_b].length
               for s in on_drawn)  # some seam runs past its loop's start
    there = carried(on_drawn, drawn, guessed)
    assert any(s.matched for s in there)
    for s in there:
        assert all(s.a_start < x < s.a_end and s.b_start < y < s.b_end for x, y in s.matched)
    back = carried(there, guessed, drawn)
    for s, r in zip(on_drawn, back, strict=True):
        for piece, arcs, again in ((s.piece_a, (s.a_start, s.a_end), (r.a_start, r.a_end)),
                                   (s.piece_b, (s.b_start, s.b_end), (r.b_start, r.b_end))):
            moved = point_at(drawn[piece], np.array(arcs)) - point_at(drawn[piece],
                                                                      np.array(again))
            assert np.hypot(*moved.T).max() < 15.0  # an inset corner sits 10 / sin mm off
