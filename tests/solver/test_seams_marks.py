"""What a CAD file's marks say about seams (solver.seams.marks), on pieces made by hand: a
side seam ends at the turn point where its slit begins, and a file that notches its seams
leaves a long edge with no notch unsewn."""

from __future__ import annotations

import numpy as np

from solver.seams import SewPiece, infer_seams
from solver.seams.outline import point_at

SLIT_MM = 150.0  # the bottom of each side is a slit, open
NOTCH_Y = 330.0  # one balance notch on each side seam


def _panel(name: str, shift: float) -> SewPiece:
    """A 200 x 600 mm panel (front or back of a straight skirt): turn points at its corners
    and where each side's slit begins, a notch on each side seam, none on waist or hem."""
    loop = np.array([[0, 0], [200, 0], [200, 600], [0, 600]], float)
    turns = np.vstack([loop, [[200, SLIT_MM], [0, SLIT_MM]]])
    notches = np.array([[200, NOTCH_Y], [0, NOTCH_Y]])
    return SewPiece(name, loop + [shift, 0], turns=turns + [shift, 0],
                    notches=notches + [shift, 0])


def test_side_seams_stop_where_the_slits_begin_and_the_unnotched_edges_stay_open():
    pieces = [_panel("p0", 0.0), _panel("p1", 400.0)]
    seams = infer_seams(pieces)
    # both sides sewn, each from the waist down to the slit's turn point: 450 mm, not the
    # whole 600 mm side (both pieces alike, the slits match as well as the seams do)
    assert len(seams) == 2
    for s in seams:
        assert abs(s.length_mm - (600 - SLIT_MM)) < 2
        ends = np.sort(point_at(pieces[s.piece_a], np.array([s.a_start, s.a_end]))[:, 1])
        assert np.allclose(ends, [SLIT_MM, 600], atol=2)
    # without the notches the file says nothing against the unnotched waist and hem, and
    # without the turn points nothing against the slits: the whole sides are sewn then
    bare = [SewPiece(p.name, p.loop) for p in pieces]
    assert sorted(round(s.length_mm) for s in infer_seams(bare)) == [600, 600]
