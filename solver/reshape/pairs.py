"""Reshaping that keeps left and right pieces mirrored: one displacement for a pair.

A pair's second piece j moves as the mirror image of its first piece i: its displacement
at each vertex q is the mirrored displacement of i at ``M^-1 q``, interpolated in i's
mesh (barycentric, so meshes that differ between the two halves still tie),

    D_j = B D_i L^T        L = R_m FLIP (the pair's linear mirror map)

with B a sparse (n_j, n_i) interpolation matrix. The optimiser keeps every step in that
subspace by projecting gradients and directions orthogonally onto it,

    (I + B^T B) D_i = A_i + B^T A_j L,       D_j = B D_i L^T,

one small sparse factorisation per pair. A symmetrised pair (j a mirrored copy of i's
mesh) has B a permutation, and stays exactly one pattern.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu
from scipy.spatial import cKDTree

from solver.garment.model import Garment
from solver.garment.symmetry import FLIP, MirrorPair

_CANDIDATES = 12  # nearest triangles (by centroid) tried for each interpolated point


@dataclass
class _Tie:
    first: np.ndarray  # (n_i,) vertex indices of the first piece
    second: np.ndarray  # (n_j,) vertex indices of the second piece
    interp: sp.csr_matrix  # B, (n_j, n_i)
    mirror: np.ndarray  # L, (2, 2)
    solve: object  # factorised I + B^T B


def barycentric_matrix(points: np.ndarray, uv: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    """(len(points), len(uv)) sparse rows interpolating at each point from the mesh's
    vertices: inside a triangle its barycentric weights, outside the nearest triangle's
    weights clamped onto it (points just beyond the outline)."""
    tri = uv[faces]  # (F,3,2)
    tree = cKDTree(tri.mean(axis=1))
    k = min(_CANDIDATES, len(faces))
    _, cand = tree.query(points, k=k)
    cand = cand.reshape(len(points), k)
    a, b, c = (tri[cand, m] for m in range(3))  # (N,k,2)
    v0, v1, v2 = b - a, c - a, points[:, None, :] - a
    d00 = (v0 * v0).sum(-1)
    d01 = (v0 * v1).sum(-1)
    d11 = (v1 * v1).sum(-1)
    d20 = (v2 * v0).sum(-1)
    d21 = (v2 * v1).sum(-1)
    den = np.where(np.abs(d00 * d11 - d01 ** 2) > 1e-300, d00 * d11 - d01 ** 2, 1e-300)
    w1 = (d11 * d20 - d01 * d21) / den
    w2 = (d00 * d21 - d01 * d20) / den
    w = np.stack([1.0 - w1 - w2, w1, w2], -1)  # (N,k,3)
    clamped = np.clip(w, 0.0, None)
    clamped /= clamped.sum(-1, keepdims=True)
    proj = np.einsum("nkm,nkmj->nkj", clamped, tri[cand])
    gap = np.linalg.norm(proj - points[:, None, :], axis=-1)  # 0 inside the triangle
    best = np.argmin(gap, axis=1)
    rows = np.arange(len(points))
    weights = clamped[rows, best]
    cols = faces[cand[rows, best]]
    return sp.csr_matrix((weights.ravel(), (np.repeat(rows, 3), cols.ravel())),
                         shape=(len(points), len(uv)))


class PairTie:
    """The subspace of displacements in which every pair's halves mirror each other."""

    def __init__(self, garment: Garment, pairs: Sequence[MirrorPair]) -> None:
        self.ties: list[_Tie] = []
        piece_of_face = garment.piece_of_face()
        for p in pairs:
            first = np.flatnonzero(garment.piece_of_vertex == p.first)
            second = np.flatnonzero(garment.piece_of_vertex == p.second)
            local = np.full(garment.n_vertices, -1)
            local[first] = np.arange(len(first))
            faces = local[garment.faces[piece_of_face == p.first]]
            back = (garment.uv[second] - p.translation) @ p.rotation @ FLIP  # M^-1 q
            interp = barycentric_matrix(back, garment.uv[first], faces)
            normal = (sp.identity(len(first)) + interp.T @ interp).tocsc()
            self.ties.append(_Tie(first, second, interp, p.rotation @ FLIP, splu(normal)))

    def project(self, field: np.ndarray) -> np.ndarray:
        """Orthogonal projection of a (V,2) displacement (or gradient) onto the subspace."""
        out = np.array(field, dtype=float, copy=True)
        for t in self.ties:
            rhs = out[t.first] + t.interp.T @ (out[t.second] @ t.mirror)
            d_i = t.solve.solve(np.ascontiguousarray(rhs))
            out[t.first] = d_i
            out[t.second] = (t.interp @ d_i) @ t.mirror.T
        return out

    def mirror_error(self, displacement: np.ndarray) -> float:
        """Largest distance (mm) between a second piece's displacement and its first
        piece's mirrored, interpolated displacement: 0 inside the subspace."""
        worst = 0.0
        for t in self.ties:
            want = (t.interp @ displacement[t.first]) @ t.mirror.T
            worst = max(worst, float(np.linalg.norm(displacement[t.second] - want,
                                                    axis=1).max(initial=0.0)))
        return worst
