"""Candidate seam sides: runs of consecutive edges of one piece's sew line.

A run ends where the line turns a sharp convex corner, but runs on past a reflex one (a
flared panel's seam pivots there: :mod:`solver.seams.pivot`), and a dart: a waist or side seam is
sewn across the darts on it with the darts closed, so a run may hold whole darts, which it
skips (its sewn length, notches and line leave them out). A dart's mouth notches mark its
legs, not where two pieces meet, so they are no balance notches of any run.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from solver.seams.outline import DART_TIP_DEG, MERGE_MM, SewPiece, sewn_line

__all__ = ["Run", "candidate_runs", "run_line"]

MAX_RUN = 8  # edges in one candidate run
MIN_LENGTH_MM = 15.0  # shorter runs are no seam of their own
SHARP_DEG = 50.0  # a run never turns a corner sharper than this (a seam ends there)


@dataclass(frozen=True)
class Run:
    """Edges ``first`` .. ``first + count - 1`` of a piece: arc interval, sewn length (the
    darts it skips left out), notches."""

    piece: int
    first: int
    count: int
    start: float
    end: float  # may exceed the loop length (wraps)
    length: float
    straightness: float  # chord / length
    notches: tuple[tuple[float, int], ...]  # (share of the sewn run from its start, count)
    end_notches: tuple[int, int] = (0, 0)  # notch count at the run's start and end
    skips: tuple[tuple[float, float], ...] = ()  # darts inside: arc spans in (start, end)
    whole: bool = False  # the run goes from a corner of the line to a corner

    def arc_at(self, u: float, *, after: bool) -> float:
        """Arc position of sewn length ``u`` from the start; at a skipped dart, its far side
        when ``after``, else its near side."""
        pos, tol = self.start + u, 1e-6
        for d0, d1 in self.skips:
            if pos > d0 + tol or (after and pos > d0 - tol):
                pos += d1 - d0
        return pos

    def skip_offsets(self) -> list[float]:
        """Sewn length from the start at which each skipped dart lies."""
        done, out = 0.0, []
        for d0, d1 in self.skips:
            out.append(d0 - self.start - done)
            done += d1 - d0
        return out


def _inside(s: np.ndarray, start: float, end: float, length: float) -> bool:
    """Whether any arc position of ``s`` lies strictly inside (start, end), laps counted."""
    for lap in (0.0, length):
        if np.any((s + lap > start + MERGE_MM) & (s + lap < end - MERGE_MM)):
            return True
    return False


def _skipped(darts: list[tuple[float, float]], start: float, end: float, length: float
             ) -> tuple[tuple[float, float], ...]:
    """The darts wholly inside (start, end), as arc spans in the run's own lap."""
    out = []
    for d0, d1 in darts:
        for lap in (-length, 0.0, length):
            if d0 + lap > start + MERGE_MM and d1 + lap < end - MERGE_MM:
                out.append((d0 + lap, d1 + lap))
    return tuple(sorted(out))


def _sharp_outside(sharp: np.ndarray, skips, length: float) -> np.ndarray:
    """The sharp corners not at a skipped dart (its mouth, tip, mouth)."""
    keep = np.ones(len(sharp), bool)
    for d0, d1 in skips:
        for lap in (-length, 0.0, length):
            keep &= ~((sharp + lap >= d0 - MERGE_MM) & (sharp + lap <= d1 + MERGE_MM))
    return sharp[keep]


def _balance_notches(piece: SewPiece, darts: list[tuple[float, float]]
                     ) -> list[tuple[float, int]]:
    """The piece's notch groups less the notch at each dart's mouth (it marks a leg)."""
    return piece.notch_groups(without=[v for d in darts for v in d])


def run_line(piece: SewPiece, run: Run) -> np.ndarray:
    """The run's line as sewn (its darts closed: skipped)."""
    return sewn_line(piece, run.start, run.end, run.skips)


def candidate_runs(pieces: list[SewPiece]) -> tuple[list[Run], list[np.ndarray]]:
    """Every run of 1..:data:`MAX_RUN` edges of every piece that turns no sharp corner
    (a seam ends where the outline turns out by more than :data:`SHARP_DEG`, or in as
    sharply as a dart's tip) but at the darts it holds whole, and each piece's breakpoints."""
    runs, cuts = [], []
    for i, p in enumerate(pieces):
        b = p.breakpoints()
        cuts.append(b)
        n = len(b)
        if n == 0:
            continue
        sharp, turn = p.corners(SHARP_DEG)
        sharp = sharp[(turn > 0) | (turn < -DART_TIP_DEG)]  # a seam pivots at a reflex corner
        corner = p.corners()[0]
        darts = p.darts()
        groups = _balance_notches(p, darts)
        for first in range(n):
            for count in range(1, min(MAX_RUN, n) + 1):
                if count == n and n > 1:
                    continue  # the whole loop is no seam
                start = b[first]
                end = b[(first + count) % n] + (p.length if first + count >= n else 0.0)
                if n == 1:
                    end = start + p.length
                skips = _skipped(darts, start, end, p.length) if count > 2 else ()
                length = end - start - sum(d1 - d0 for d0, d1 in skips)
                if length < MIN_LENGTH_MM or (count > 1 and _inside(
                        _sharp_outside(sharp, skips, p.length), start, end, p.length)):
                    continue
                line = sewn_line(p, start, end, skips)
                chord = float(np.linalg.norm(line[-1] - line[0]))
                whole = all(np.any(np.abs(np.mod(corner - v + p.length / 2, p.length)
                                          - p.length / 2) <= MERGE_MM) for v in (start, end))
                runs.append(Run(i, first, count, float(start), float(end), float(length),
                                chord / length, *_run_notches(groups, start, end, p.length,
                                                              skips), skips, whole))
    return runs, cuts


def _run_notches(groups: list[tuple[float, int]], start: float, end: float, length: float,
                 skips: tuple[tuple[float, float], ...] = ()
                 ) -> tuple[tuple[tuple[float, int], ...], tuple[int, int]]:
    """The notch groups inside a run (share of its sewn length, count) and the counts at
    its two ends."""
    inner, at_ends = [], [0, 0]
    sewn = end - start - sum(d1 - d0 for d0, d1 in skips)
    for s, c in groups:
        for lap in (0.0, length):
            at = s + lap
            if abs(at - start) <= MERGE_MM:
                at_ends[0] = c
            elif abs(at - end) <= MERGE_MM:
                at_ends[1] = c
            elif start < at < end and not any(d0 <= at <= d1 for d0, d1 in skips):
                u = at - start - sum(d1 - d0 for d0, d1 in skips if d1 <= at)
                inner.append((round(u / sewn, 4), c))
    return tuple(sorted(inner)), (at_ends[0], at_ends[1])


Couples = dict[tuple[int, int], list[tuple[int, Run, Run]]]  # (piece a, piece b) -> candidates


def by_couple(runs: list[Run], pairs: np.ndarray) -> Couples:
    """The candidates (index, run on the lower piece, run on the higher) that join two
    different pieces, grouped by those two pieces (lower first)."""
    out: Couples = defaultdict(list)
    for k, (i, j) in enumerate(pairs.tolist()):
        a, b = runs[i], runs[j]
        if a.piece != b.piece:
            a, b = (a, b) if a.piece < b.piece else (b, a)
            out[(a.piece, b.piece)].append((k, a, b))
    return out
