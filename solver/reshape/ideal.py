"""Ideal seam lines (paper Sec. 5, "Ideal seam lines"), vectorised over seam lines.

For every seam line S with twin lines S1 (piece i) and S2 (piece j) the paper builds a
replacement S1* that fits S2 perfectly and has S2's edge lengths:

1. move S2 into the wallpaper space of piece i (both lines to wallpaper coordinates);
2. apply each of the group's n operations to the whole line: n candidates;
3. move each candidate by the whole lattice vector that brings it closest to S1
   (the least-squares optimum is the lattice vector closest to the mean offset);
4. keep the candidate closest to S1 (sum of squared vertex distances).

The displacement is then split in half so both sides move equally: a rigid Procrustes
fit (rotation only, no reflection, no scale) of S1 onto S1* gives the angle theta and
centroids c1, c*; S1_ideal is S1* turned back by theta/2 about its centroid and moved to
(c1 + c*)/2, and S2_ideal is the image of S1_ideal under the inverse of the symmetry
map that took S2 to S1*. Both ideal lines are rigid images of S1* and S2, so they still
fit perfectly and keep equal twin lengths (the paper's principles 1 and 2). Where one
piece is fixed, the other side takes the whole displacement.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solver.placement import Placement, rotation_matrices


@dataclass(frozen=True)
class IdealSeams:
    """Proximity targets for E_prox: one row per (seam line, seam vertex).

    ``vertex`` (K,) pattern vertex, ``target`` (K,2) its ideal position in mm,
    ``weight`` (K,) the seam line's weight, ``line`` (K,) its seam line.
    Per seam line: ``op`` (S,) the chosen symmetry, ``theta`` (S,) the Procrustes angle
    of S1 onto S1* (radians), ``shift`` (S,) distance between the centroids of S1 and S1*.
    """

    vertex: np.ndarray
    target: np.ndarray
    weight: np.ndarray
    line: np.ndarray
    op: np.ndarray
    theta: np.ndarray
    shift: np.ndarray


def _homogeneous(rot: np.ndarray, trans: np.ndarray) -> np.ndarray:
    """(N,2,2) rotations and (N,2) translations -> (N,3,3) affine maps."""
    h = np.zeros((len(rot), 3, 3))
    h[:, :2, :2], h[:, :2, 2], h[:, 2, 2] = rot, trans, 1.0
    return h


def _apply(h: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Row-wise affine maps (N,3,3) applied to points (N,2)."""
    return np.einsum("nij,nj->ni", h[:, :2, :2], p) + h[:, :2, 2]


def seam_vertex_pairs(garment) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unique twin vertex pairs (v1 on the first twin's piece, v2, seam line) of all seams."""
    e = garment.seam_edges
    line = np.asarray(garment.seam_line_of_edge, dtype=np.int64)
    pairs = np.concatenate([
        np.column_stack([e[:, 0], e[:, 2], line]),
        np.column_stack([e[:, 1], e[:, 3], line]),
    ])
    pairs = np.unique(pairs, axis=0)
    return pairs[:, 0], pairs[:, 1], pairs[:, 2]


def ideal_seams(garment, placement: Placement, *, uv: np.ndarray | None = None,
                fixed: np.ndarray | None = None) -> IdealSeams:
    """Ideal seam lines of every weighted seam line of ``garment`` under ``placement``.

    ``uv`` (V,2) overrides the garment's pattern; ``fixed`` (n_pieces,) bool marks pieces
    that must not move (their twins take the whole displacement).
    """
    uv = garment.uv if uv is None else np.asarray(uv, float)
    fixed = (np.zeros(garment.n_pieces, bool) if fixed is None
             else np.asarray(fixed, bool).reshape(garment.n_pieces))
    v1, v2, line = seam_vertex_pairs(garment)
    n_lines = len(garment.seam_lines)
    line_w = np.array([s.weight for s in garment.seam_lines], float).reshape(n_lines)
    keep = line_w[line] > 0
    v1, v2, line = v1[keep], v2[keep], line[keep]
    if len(v1) == 0:
        empty = np.zeros(0, np.int64)
        return IdealSeams(empty, np.zeros((0, 2)), np.zeros(0), empty,
                          np.zeros(n_lines, np.int64), np.zeros(n_lines), np.zeros(n_lines))
    piece = garment.piece_of_vertex
    pi, pj = piece[v1], piece[v2]
    wp = placement.fabric
    ops = wp.cartesian_ops()  # (n,3,3) in wallpaper mm
    n_ops = len(ops)

    # step 1: both twin lines into wallpaper space (S2 "moved into P_i" = same wp coords)
    a_i = _homogeneous(rotation_matrices(placement.angles[pi]), placement.translations[pi])
    a_j = _homogeneous(rotation_matrices(placement.angles[pj]), placement.translations[pj])
    p_wp = placement.to_wallpaper(uv[v1], pi)
    q_wp = placement.to_wallpaper(uv[v2], pj)
    # step 2: every operation applied to the whole twin line -> (K, n, 2) candidates
    cand = np.einsum("kij,pj->pki", ops[:, :2, :2], q_wp) + ops[None, :, :2, 2]
    diff = p_wp[:, None, :] - cand  # (K, n, 2)
    # step 3: per (line, op) the closest whole lattice vector to the mean offset
    count = np.bincount(line, minlength=n_lines).astype(float)
    mean = np.stack([
        np.stack([np.bincount(line, weights=diff[:, k, c], minlength=n_lines)
                  for c in range(2)], -1)
        for k in range(n_ops)
    ], 1) / np.maximum(count, 1.0)[:, None, None]  # (S, n, 2)
    lattice = mean - wp.lattice_residual(mean)  # (S, n, 2) whole lattice vectors
    # step 4: the candidate closest to S1
    resid = diff - lattice[line]
    cost = np.stack([np.bincount(line, weights=np.einsum("pi,pi->p", resid[:, k], resid[:, k]),
                                 minlength=n_lines) for k in range(n_ops)], 1)
    best = np.argmin(cost, axis=1)  # (S,)
    lat_best = lattice[np.arange(n_lines), best]  # (S, 2)
    # M: pattern of piece j -> pattern of piece i, taking S2 onto S1*
    shift_h = np.tile(np.eye(3), (n_lines, 1, 1))
    shift_h[:, :2, 2] = lat_best
    g = shift_h @ ops[best]  # (S,3,3) in wallpaper space
    m = a_i @ g[line] @ np.linalg.inv(a_j)  # (K,3,3)
    s1 = uv[v1]
    s1_star = _apply(m, uv[v2])

    # Procrustes (rotation only) of S1 onto S1*, per line, uniform vertex weights
    def centroid(x: np.ndarray) -> np.ndarray:
        return np.stack([np.bincount(line, weights=x[:, c], minlength=n_lines)
                         for c in range(2)], -1) / np.maximum(count, 1.0)[:, None]

    c1, cs = centroid(s1), centroid(s1_star)
    x, y = s1 - c1[line], s1_star - cs[line]
    dot = np.bincount(line, weights=np.einsum("pi,pi->p", x, y), minlength=n_lines)
    crs = np.bincount(line, weights=x[:, 0] * y[:, 1] - x[:, 1] * y[:, 0], minlength=n_lines)
    theta = np.arctan2(crs, dot)  # S1 rotated by theta best matches S1*

    # how much of the displacement S1 takes: half, all (twin fixed) or none (own piece fixed)
    line_pi = np.zeros(n_lines, np.int64)
    line_pj = np.zeros(n_lines, np.int64)
    line_pi[line], line_pj[line] = pi, pj
    fi, fj = fixed[line_pi], fixed[line_pj]
    share = np.where(fi, 0.0, np.where(fj, 1.0, 0.5))  # fraction of the way from S1 to S1*
    back = (1.0 - share)  # S1_ideal = S1* turned back by back*theta, centroid interpolated
    rot_back = rotation_matrices(-back * theta)
    centre = c1 + share[:, None] * (cs - c1)
    s1_ideal = np.einsum("pij,pj->pi", rot_back[line], y) + centre[line]
    s2_ideal = _apply(np.linalg.inv(m), s1_ideal)

    # own piece fixed: S1 stays, S2 takes the whole way (S2* built from S1, roles swapped)
    own = (fi & ~fj)[line]
    s1_ideal[own] = s1[own]
    s2_ideal[own] = _apply(np.linalg.inv(m[own]), s1[own])
    both = (fi & fj)[line]  # nothing can move: keep current positions as targets
    s1_ideal[both] = s1[both]
    s2_ideal[both] = uv[v2][both]
    return IdealSeams(
        vertex=np.concatenate([v1, v2]),
        target=np.concatenate([s1_ideal, s2_ideal]),
        weight=np.concatenate([line_w[line], line_w[line]]),
        line=np.concatenate([line, line]),
        op=best,
        theta=theta,
        shift=np.hypot(*(cs - c1).T),
    )
