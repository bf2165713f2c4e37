"""Which line a pattern's seams are read on when the file does not say where it sews.

A DXF with no sew line (layer 14) and no stated seam allowance leaves the sew line a guess:
the cut line inset by the station's allowance. A net pattern (drawn on its sew line, as a
CAD exports a pattern whose allowance is added at the marker) read so has every convex
curve shortened by its turn times the inset and every concave one lengthened: a sleeve cap
and its armhole, equal as drawn, come out 8 % apart, and their seam is lost. A sewer
matches the edges as they lie. So the seams are inferred on both lines, the guessed sew
line and the drawn line, and kept from the one on which more seam length is surely sewn;
seams found on the drawn line are carried onto the sew line point by point (the sew line
stays the allowance's, which the operator may correct).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from solver.seams import Seam, SewPiece, infer_seams
from solver.seams.outline import arc_position, point_at

__all__ = ["DRAWN_MARGIN", "carried", "infer_on_either", "sewn_weight"]

#: the drawn line's seams must weigh this much more than the guessed line's to be kept (the
#: allowance the station was given is believed first). On the seams bench (`SEAMS_NET`), the
#: exports read at their true inset weigh at most 9 % more on the drawn line (straight seams
#: lose nothing there); 17 of 29 net ones read 10 mm in weigh 10-80 % more on it, and the
#: rest lose little or nothing on the guessed line (89.2 % found in all, 82.1 % without)
DRAWN_MARGIN = 1.1


def sewn_weight(seams: list[Seam]) -> float:
    """How much seam is surely sewn: each seam's length times its confidence (mm)."""
    return float(sum(s.length_mm * s.confidence for s in seams))


def carried(seams: list[Seam], src: list[SewPiece], dst: list[SewPiece]) -> list[Seam]:
    """``seams`` on the pieces ``src`` carried onto the same pieces' lines ``dst``: every
    arc position to the nearest point of the other line, laps kept (an end or a matched
    notch past the loop's start stays past it)."""
    def to(i: int, arcs: list[float]) -> np.ndarray:
        return arc_position(dst[i], point_at(src[i], np.asarray(arcs, float)))

    out = []
    for s in seams:
        sides = []
        for i, ends, inner in ((s.piece_a, (s.a_start, s.a_end), [x for x, _ in s.matched]),
                               (s.piece_b, (s.b_start, s.b_end), [y for _, y in s.matched])):
            start, end, *mid = to(i, [*ends, *inner])
            lap = dst[i].length
            end = end + lap if end <= start else end
            sides.append((float(start), float(end),
                          [float(m + lap if m < start else m) for m in mid]))
        (a0, a1, ma), (b0, b1, mb) = sides
        out.append(dataclasses.replace(s, a_start=a0, a_end=a1, b_start=b0, b_end=b1,
                                       matched=tuple(zip(ma, mb, strict=True))))
    return out


def infer_on_either(guessed: list[SewPiece], drawn: list[SewPiece], *,
                    declared: list[Seam] = (), vetoed: set[frozenset[int]] = frozenset()
                    ) -> tuple[list[Seam], bool]:
    """(the seams on the ``guessed`` sew lines, whether they were read on the ``drawn``
    lines): inferred on both (the operator's ``declared`` seams, given on the guessed
    lines, carried to the drawn ones), kept from the line where they weigh more."""
    on_guess = infer_seams(guessed, declared=declared, vetoed=vetoed)
    on_drawn = infer_seams(drawn, declared=carried(list(declared), guessed, drawn),
                           vetoed=vetoed)
    if sewn_weight(on_drawn) > DRAWN_MARGIN * sewn_weight(on_guess):
        return list(declared) + carried(on_drawn[len(declared):], drawn, guessed), True
    return on_guess, False
