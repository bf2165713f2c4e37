"""The "garment front view": left and right pieces side by side as they are worn.

A person judges a garment's symmetry at a glance when the two halves of every pair stand
mirrored next to each other, the right way up, print on. Each piece is turned rigidly so
that what is up when the garment is worn points up (`worn_up_deg`: the neck at the top,
a sleeve hanging from its cap), which moves its print with it (the placement is carried
along); the second piece of a pair is drawn as the mirror of the first across a vertical
axis (the centre seam where the pair has one), and the panels are laid out in a row;
then `station.render.draw_fit` draws them.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from solver.fit import fit_report
from solver.garment.grain import drape_grain, panel_positions
from solver.garment.symmetry import FLIP, MirrorPair, centre_seams
from solver.placement import Placement, rotation_matrices
from station.render import draw_fit

GAP_MM = 60.0


def _rigid(angle: float, shift: np.ndarray) -> np.ndarray:
    out = np.eye(3)
    out[:2, :2] = rotation_matrices(np.array([angle]))[0]
    out[:2, 2] = shift
    return out


def worn_up_deg(garment) -> np.ndarray:
    """(P,) degrees: per piece the pattern direction that points up as the garment is
    worn. From the drape (or a specification's panel placement): towards the neck or
    waist on a body piece, towards the cap on a sleeve or leg, so that it hangs. Without
    either, each piece's grain, whose sense a flat pattern does not tell."""
    if garment.xyz is not None or panel_positions(garment) is not None:
        return drape_grain(garment)[0]
    return np.array([g.deg for g in garment.grains()])


def front_view(garment, placement: Placement, pairs: Sequence[MirrorPair]):
    """(garment, placement, axes) with every piece moved to its place in the front view;
    ``axes`` maps each pair (first, second) to the x of its vertical mirror axis."""
    g = garment
    n = g.n_pieces
    moves = np.tile(np.eye(3), (n, 1, 1))  # proper rigid motion of each piece
    worn = np.radians(worn_up_deg(g))
    for c in range(n):
        moves[c] = _rigid(np.pi / 2 - worn[c], np.zeros(2))
    panels: list[list[int]] = []
    paired: set[int] = set()
    axes: dict[tuple[int, int], float] = {}
    centre = set(centre_seams(g, pairs))
    for p in pairs:
        i, j = p.first, p.second
        axis_x = _mirror_axis_x(g, moves[i], i, j, centre)
        # j shown = reflect_x(axis) o move_i o M^-1 : proper, and the mirror of i's view
        reflect = np.eye(3)
        reflect[0, 0], reflect[0, 2] = -1.0, 2.0 * axis_x
        inv_m = np.eye(3)
        inv_m[:2, :2] = FLIP @ p.rotation.T
        inv_m[:2, 2] = -FLIP @ p.rotation.T @ p.translation
        moves[j] = reflect @ moves[i] @ inv_m
        axes[(i, j)] = axis_x
        panels.append([i, j])
        paired.update((i, j))
    panels += [[c] for c in range(n) if c not in paired]
    uv = np.empty_like(g.uv)
    x_cursor = 0.0
    for panel in panels:
        on = np.isin(g.piece_of_vertex, panel)
        piece = g.piece_of_vertex[on]
        pts = np.einsum("nij,nj->ni", moves[piece][:, :2, :2], g.uv[on]) + moves[piece][:, :2, 2]
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        shift = np.array([x_cursor - lo[0], -hi[1]])  # top-aligned, left to right
        for c in panel:
            moves[c][:2, 2] += shift
        if len(panel) == 2:
            axes[tuple(panel)] += shift[0]
        uv[on] = pts + shift
        x_cursor += hi[0] - lo[0] + GAP_MM
    shown = g.with_uv(uv)
    angles = placement.angles + np.arctan2(moves[:, 1, 0], moves[:, 0, 0])
    trans = np.einsum("nij,nj->ni", moves[:, :2, :2], placement.translations) + moves[:, :2, 2]
    return shown, Placement(angles, trans, placement.fabric, piece_names=g.piece_names), axes


def _mirror_axis_x(g, move: np.ndarray, i: int, j: int, centre: set[int]) -> float:
    """x of the vertical mirror axis in piece i's view: on the pair's centre seam, else a
    gap to the right of the piece."""
    lines = [k for k in centre if {g.seam_lines[k].piece_a, g.seam_lines[k].piece_b} == {i, j}]
    pts = g.uv[g.piece_of_vertex == i] @ move[:2, :2].T + move[:2, 2]
    if lines:
        edges = g.seam_edges[np.isin(g.seam_line_of_edge, lines)]
        verts = np.where(g.piece_of_vertex[edges[:, 0]] == i, edges[:, 0], edges[:, 2])
        return float((g.uv[verts] @ move[:2, :2].T + move[:2, 2])[:, 0].mean())
    return float(pts[:, 0].max() + GAP_MM / 2)


def draw_front_view(garment, placement: Placement, pairs: Sequence[MirrorPair],
                    path: str | Path, **options) -> np.ndarray:
    """Draw the front view (pairs mirrored side by side, print on, seams coloured)."""
    shown, moved, _ = front_view(garment, placement, pairs)
    kept = ", ".join(f"{p.first}~{p.second}" for p in pairs) or "no pairs"
    return draw_fit(shown, moved, fit_report(shown, moved), path,
                    title=f"{placement.fabric.group} front view, pairs {kept}", **options)
