"""Notches matched inside a seam are pinned together: an eased side is not eased evenly, so
the seam's points follow its notches, not its length alone (pieces made by hand)."""

from __future__ import annotations

import numpy as np

from solver.seams import SewPiece, infer_seams
from solver.seams.outline import point_at
from solver.seams.score import STEP_MM, Correspondence, sample_seams, score_seams

SIDE_MM = 500.0  # the sewn side of each piece
NOTCH_A, NOTCH_B = 150.0, 178.0  # one notch on each, this far up: the same notch, eased


def _pieces() -> list[SewPiece]:
    """A's right side sewn to B's left side (both at y = 0..500, the only sides of one
    length), a notch on each at heights 28 mm apart: 5.6 % of the side, within tolerance."""
    a = np.array([[0, 0], [200, 0], [200, SIDE_MM], [0, 440]], float)
    b = np.array([[300, 0], [450, 0], [450, 400], [300, SIDE_MM]], float)
    return [SewPiece("p0", a, turns=a, notches=np.array([[200, NOTCH_A]])),
            SewPiece("p1", b, turns=b, notches=np.array([[300, NOTCH_B]]))]


def _truth() -> Correspondence:
    """The side sewn height to height, notch to notch, evenly between them."""
    y = np.arange(STEP_MM / 2, SIDE_MM, STEP_MM)
    yb = np.interp(y, [0, NOTCH_A, SIDE_MM], [0, NOTCH_B, SIDE_MM])
    return Correspondence(np.tile([0, 1], (len(y), 1)), np.column_stack([np.full_like(y, 200), y]),
                          np.column_stack([np.full_like(y, 300), yb]), np.full(len(y), STEP_MM))


def test_matched_notches_are_sewn_to_each_other():
    pieces = _pieces()
    seams = infer_seams(pieces)
    assert len(seams) == 1
    s = seams[0]
    assert len(s.matched) == 1
    arc_a, arc_b = s.matched[0] if s.piece_a == 0 else s.matched[0][::-1]
    assert np.allclose(point_at(pieces[0], np.array([arc_a])), [[200, NOTCH_A]], atol=1)
    assert np.allclose(point_at(pieces[1], np.array([arc_b])), [[300, NOTCH_B]], atol=1)
    score = score_seams(_truth(), sample_seams(seams, pieces))
    assert score.recall > 0.98 and score.precision > 0.98  # in proportion: 71 %
