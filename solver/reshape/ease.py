"""Seams with ease: pull them across, never along.

A seam whose two sides differ in length (a sleeve cap eased into its armhole, a waist
gathered onto a band) cannot fit the print at every sewn vertex pair: the pairs drift
apart along it by construction. The ideal lines and the matched targets still ask each
side to take the other's spacing, while the twin-length term keeps each side's own edge
lengths. The cheapest compromise is an accordion: the vertices reach their targets by
zig-zagging across the seam. Keeping only the part of each target's pull that runs
across the seam (along the outline's normal) removes that conflict; the fit is still
pursued across the seam, where a mismatch shows.
"""

from __future__ import annotations

import numpy as np

from solver.reshape.energy import twin_length_mismatch, twin_lengths
from solver.reshape.ideal import SeamTargets
from solver.reshape.quality import seam_side_lengths

EASE_FRACTION = 0.1  # a seam whose sides differ by more than 10 % of their length is eased


def eased_lines(garment, fraction: float = EASE_FRACTION) -> np.ndarray:
    """(S,) bool: the seam lines whose two sides differ in length by more than
    ``fraction`` of their mean length in the input pattern."""
    a, b = seam_side_lengths(garment, garment.uv)
    return np.abs(a - b) > fraction * 0.5 * (a + b)


def ease_targets(garment, give_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """(E,) per twin pair and (S,) per seam line: the length difference (mm) each keeps.

    A seam line may give up to ``give_mm`` of its drafted ease ``E`` to the fit, taken
    from its pairs in proportion to their length; every pair keeps the rest of its own
    difference, so no point of one side slides along the other by more than ``give_mm``
    (`solver.reshape.quality.sewn_drift`), and a seam drafted with less ease than that is
    pulled to equal side lengths, as the paper asks.
    """
    e = garment.seam_edges
    diff = twin_lengths(garment.uv, e)
    line = np.asarray(garment.seam_line_of_edge, np.int64)
    n = len(garment.seam_lines)
    drafted = np.bincount(line, weights=diff, minlength=n)
    length = 0.5 * (np.linalg.norm(garment.uv[e[:, 1]] - garment.uv[e[:, 0]], axis=1)
                    + np.linalg.norm(garment.uv[e[:, 3]] - garment.uv[e[:, 2]], axis=1))
    given = np.sign(drafted) * np.minimum(give_mm, np.abs(drafted))
    share = length / np.maximum(np.bincount(line, weights=length, minlength=n), 1e-12)[line]
    return diff - given[line] * share, drafted - given


def outline_normals(garment, uv: np.ndarray) -> np.ndarray:
    """(V,2) unit normal of the outline at every outline vertex of ``uv`` (central
    difference along its loop); zero inside the pieces."""
    out = np.zeros_like(uv)
    for i in range(garment.n_pieces):
        for loop in garment.piece_loops(i):
            if len(loop) < 3:
                continue
            t = uv[np.roll(loop, -1)] - uv[np.roll(loop, 1)]
            n = np.column_stack([t[:, 1], -t[:, 0]])
            out[loop] = n / np.maximum(np.linalg.norm(n, axis=1), 1e-12)[:, None]
    return out


def across_only(garment, targets: SeamTargets, uv: np.ndarray,
                eased: np.ndarray) -> SeamTargets:
    """``targets`` with the rows on ``eased`` seam lines moved to their vertex's position
    in ``uv`` plus only the across-the-seam part of the pull."""
    rows = np.flatnonzero(eased[targets.line]) if len(targets.line) else np.zeros(0, int)
    if not rows.size:
        return targets
    v = targets.vertex[rows]
    n = outline_normals(garment, uv)[v]
    pull = targets.target[rows] - uv[v]
    target = targets.target.copy()
    target[rows] = uv[v] + np.einsum("ij,ij->i", pull, n)[:, None] * n
    return SeamTargets(vertex=targets.vertex, target=target, weight=targets.weight,
                       line=targets.line)


class SeamSewing:
    """Whether the twins still sew, the gamma loop's test.

    Keeping ease (ours): each pair keeps its `ease_targets` difference, L measures how
    far the pairs are from it, and the seams sew once every seam line's ease is within
    ``ease_tol_mm`` of its target (what a sewer feels; a per-edge sum can stall on a
    coarse mesh while every seam sews), so within ``give_mm + ease_tol_mm`` of the
    drafted ease. The paper's: L = sum |l_e - l_e'| within eps, half its input value
    (never below ``eps_floor`` of the seam length).
    """

    def __init__(self, garment, *, keep_ease: bool, give_mm: float, ease_tol_mm: float,
                 eps_floor: float) -> None:
        self._garment = garment
        self._seams = garment.seam_edges
        self.keep_ease, self.ease_tol_mm = keep_ease, ease_tol_mm
        if keep_ease and len(self._seams):
            self.pair_ease, self._line_ease = ease_targets(garment, give_mm)
        else:
            self.pair_ease, self._line_ease = None, None
        self._drafted = np.subtract(*seam_side_lengths(garment, garment.uv))
        self.initial_mm = self.mismatch(garment.uv)
        seam_length = float(np.hypot(*(garment.uv[self._seams[:, 1]]
                                       - garment.uv[self._seams[:, 0]]).T).sum())
        self.eps_mm = max(0.5 * self.initial_mm, eps_floor * seam_length)

    def mismatch(self, uv: np.ndarray) -> float:
        """L in mm (see the class docstring)."""
        rest = 0.0 if self.pair_ease is None else self.pair_ease
        return twin_length_mismatch(uv, self._seams, rest)

    def ease_change(self, uv: np.ndarray, target: bool = False) -> float:
        """The largest change of a seam line's ease in ``uv`` (mm) from the drafted one,
        or from its target with ``target``."""
        ease = np.subtract(*seam_side_lengths(self._garment, uv))
        ref = self._line_ease if target and self._line_ease is not None else self._drafted
        return float(np.abs(ease - ref).max(initial=0.0))

    def __call__(self, uv: np.ndarray) -> bool:
        """True when the seams in ``uv`` sew (see the class docstring)."""
        if self.keep_ease:
            return self.ease_change(uv, target=True) <= self.ease_tol_mm
        return self.mismatch(uv) <= self.eps_mm
