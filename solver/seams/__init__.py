"""Seams found from a flat pattern itself, as a sewer finds them: lengths, notches, names.

    seams = infer_seams([SewPiece(name, sew_loop, turns, notches), ...])

A CAD pattern (DXF-AAMA / ASTM D6673) says nothing of which edge is sewn to which; the
sewer reads it from the pieces. :mod:`solver.seams.outline` cuts each sew line into edges,
:mod:`solver.seams.match` chooses the seams jointly, :mod:`solver.seams.export` writes
CAD-like exports of garments whose seams are known and :mod:`solver.seams.score` scores
the inference against them.
"""

from __future__ import annotations

from solver.seams.match import Seam, candidate_runs, choose_seams
from solver.seams.outline import SewPiece

__all__ = ["Seam", "SewPiece", "infer_seams"]


def infer_seams(pieces: list[SewPiece], *, declared: list[Seam] = (),
                vetoed: set[frozenset[int]] = frozenset()) -> list[Seam]:
    """The seams between ``pieces`` (each edge sewn at most once), each with a confidence:
    the operator's ``declared`` seams first, none between a ``vetoed`` pair of pieces."""
    runs, cuts = candidate_runs(pieces)
    return choose_seams(pieces, runs, cuts, fixed=list(declared), vetoed=set(vetoed))
