"""A skirt gathered onto its bodice, on pieces made by hand: a waist 2.5 times the bodice's
(a usual fullness) is sewn to it when the two carry matching notches inside the seam, and
left open when they carry none (nothing else tells a gather from a chance pairing)."""

from __future__ import annotations

import numpy as np

from solver.seams import SewPiece, infer_seams
from solver.seams.outline import point_at

BODICE_MM = 200.0  # the bodice's waist
FULLNESS = 2.5  # the skirt's waist is this times longer
NOTCH_AT = 0.3  # one balance notch at this share of each waist, from the left


def _pieces(notched: bool) -> list[SewPiece]:
    """A 200 x 300 mm bodice above a skirt whose 500 mm waist is sewn to its bottom edge;
    turn points at every corner, a notch at the same share of both waists."""
    waist = BODICE_MM * FULLNESS
    bodice = np.array([[0, 0], [BODICE_MM, 0], [BODICE_MM, 300], [0, 300]], float)
    skirt = np.array([[-250, -600], [waist + 50, -600], [waist, -40], [0, -40]], float)
    skirt[:, 0] -= 0.5 * (waist - BODICE_MM)  # centred under the bodice
    marks = ([[NOTCH_AT * BODICE_MM, 0]], [[skirt[3, 0] + NOTCH_AT * waist, -40]])
    return [SewPiece(name, loop, turns=loop, notches=np.array(n if notched else [], float))
            for name, loop, n in (("p0", bodice, marks[0]), ("p1", skirt, marks[1]))]


def test_a_gathered_waist_is_sewn_by_its_notches():
    pieces = _pieces(notched=True)
    seams = infer_seams(pieces)
    assert len(seams) == 1  # the sides and hems have no partner
    s = seams[0]
    a, b = (s.a_start, s.a_end), (s.b_start, s.b_end)
    lengths = {s.piece_a: a[1] - a[0], s.piece_b: b[1] - b[0]}
    assert abs(lengths[0] - BODICE_MM) < 2 and abs(lengths[1] - FULLNESS * BODICE_MM) < 2
    on_bodice = point_at(pieces[0], np.array(a if s.piece_a == 0 else b))
    assert np.allclose(on_bodice[:, 1], 0, atol=1)  # along the bodice's bottom edge
    assert not infer_seams(_pieces(notched=False))
