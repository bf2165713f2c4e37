"""What a file's marks say against a candidate seam: where seams end, where they are notched.

A pattern CAD writes a turn point (layer 2) where the line turns and where a seam ends on a
smooth line (a slit's top, a sleeve cap's break); a balance notch marks a point along a
seam, where its two sides are matched. So a candidate side that ends at a notch, with no
turn point there, is a seam cut short by chance, and one that runs on past a turn point
where the line does not turn is two seams, or a seam and an opening (a side seam and the
slit below it, both pieces alike). A file with no turn points, or with one on every vertex
or along its curves (AccuMark's digitised lines), says neither. And a file that notches its
seams (nearly every piece carries notches) leaves a long stretch with no notch on either side
unsewn: a neckline and a sleeve's hem, a vest's two front edges, a slit, are as long and as
straight as a seam.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solver.seams.outline import CORNER_DEG, MERGE_MM, SewPiece, arc_position
from solver.seams.runs import Run

__all__ = ["FileMarks", "PieceMarks"]

BEND_DEG = CORNER_DEG - 2.0  # a line turning less than this at a turn point runs on
# smoothly there: the turn point is no corner, it marks a seam's end (a corner may read a
# degree or two less once offset and read back; 15 degrees kept GC dress_circle's waistband
# ends, turning 26 degrees, inside its waist seam) ...
BEND_NEAR_MM = 12.0  # ... within this of the turn point (simplified, offset: a corner turning
# t moves allowance x tan(t / 2) along the line inset, 8.4 mm for a flared skirt's 80-degree
# pivot at 10 mm; 8 read that pivot's turn point as a seam's end on a smooth line)
SMOOTH_EXTRA = 2  # a piece marks a seam's end on a smooth line at most this many times
# more often than it turns a corner; one that marks more marks points along its curves
UNMARKED_END = 0.3  # per end of either side at no turn point (at a notch) ...
CROSSED_MARK = 0.5  # ... and per turn point on a smooth line either side runs past
NOTCHED_SHARE = 0.75  # a file notches its seams when this share of its pieces carry notches
# (a small piece whose seams are all short may carry none; the Gerber tee: 5 of 7) ...
NOTCHED_MM = 100.0  # ... and there two sides this long with no notch,
UNNOTCHED = 1.0  # not even at an end, are no seam by this much


class PieceMarks:
    """A piece's turn points as seam ends: all of them (``ends``), and those on a smooth
    stretch of line (``smooth``: no bend there); ``ends`` None where the file says
    nothing."""

    def __init__(self, piece: SewPiece) -> None:
        raw = arc_position(piece, piece.turns)
        self.length = piece.length
        self.ends: np.ndarray | None = None
        self.smooth = np.zeros(0)
        if not len(raw) or len(piece.turning_points()) < len(raw):
            return  # none, or one on every vertex: kept only where the line turns
        corners = piece.corners()[0]
        smooth = raw[~_near_any(raw, piece.corners(BEND_DEG)[0], piece.length, BEND_NEAR_MM)]
        if len(np.unique(np.round(smooth / MERGE_MM))) > len(corners) + SMOOTH_EXTRA:
            return  # marks along its curves (AccuMark's sleeves): they say no seam's end
        self.ends = np.concatenate([raw, corners])
        self.smooth = smooth

    def unmarked(self, run: Run) -> tuple[int, int]:
        """(how many of the run's two ends lie at no turn point, how many turn points on a
        smooth line lie inside it, darts it skips left out); (0, 0) where the file says
        nothing."""
        if self.ends is None:
            return 0, 0
        ends = int((~_near_any(np.array([run.start, run.end]), self.ends,
                               self.length)).sum())
        inside = 0
        for s in self.smooth.tolist():
            for at in (s, s + self.length):
                if run.start + MERGE_MM < at < run.end - MERGE_MM and not any(
                        d0 - MERGE_MM <= at <= d1 + MERGE_MM for d0, d1 in run.skips):
                    inside += 1
        return ends, inside


@dataclass
class FileMarks:
    """The marks of every piece of one file, and whether the file notches its seams."""

    pieces: list[PieceMarks]
    notched: bool

    @staticmethod
    def of(pieces: list[SewPiece]) -> FileMarks:
        notched = sum(bool(len(p.notches)) for p in pieces)
        return FileMarks([PieceMarks(p) for p in pieces],
                         bool(pieces) and notched >= NOTCHED_SHARE * len(pieces))

    def penalty(self, a: Run, b: Run) -> float:
        """What the marks say against sewing run ``a`` to run ``b`` (0 when nothing)."""
        ends, inside = np.add(self.pieces[a.piece].unmarked(a), self.pieces[b.piece].unmarked(b))
        out = UNMARKED_END * float(ends) + CROSSED_MARK * float(inside)
        if self.notched and min(a.length, b.length) >= NOTCHED_MM and not any(
                (*a.notches, *b.notches, *a.end_notches, *b.end_notches)):
            out += UNNOTCHED
        return out


def _near_any(x: np.ndarray, marks: np.ndarray, length: float, near: float = MERGE_MM
              ) -> np.ndarray:
    """(k,) whether each arc position of ``x`` lies within ``near`` of a mark."""
    if not len(marks) or not len(x):
        return np.zeros(len(x), bool)
    d = np.abs(np.mod(x[:, None] - marks[None, :] + length / 2, length) - length / 2)
    return (d <= near).any(1)
