"""Reshaping that keeps left and right pieces mirrored: one displacement for a pair.

A pair's second piece j moves as the mirror image of its first piece i: its displacement
at each vertex q is the mirrored displacement of i at ``M^-1 q``, interpolated in i's
mesh (barycentric, so meshes that differ between the two halves still tie),

    D_j = B D_i L^T        L = R_m FLIP (the pair's linear mirror map)

with B a sparse (n_j, n_i) interpolation matrix. The optimiser keeps every step in that
subspace by projecting gradients and directions orthogonally onto it,

    (I + B^T B) D_i = A_i + B^T A_j L,       D_j = B D_i L^T,

one small sparse factorisation per pair. A symmetrised pair (j a mirrored copy of i's
mesh, `solver.garment.symmetrise`) has B the permutation that pairs each vertex with its
image, not an interpolation, so it stays exactly one pattern.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from solver.garment.barycentric import barycentric_matrix
from solver.garment.model import Garment
from solver.garment.symmetry import MirrorPair, mirror_correspondence
from solver.geometry import FLIP


@dataclass
class _Tie:
    first: np.ndarray  # (n_i,) vertex indices of the first piece
    second: np.ndarray  # (n_j,) vertex indices of the second piece
    interp: sp.csr_matrix  # B, (n_j, n_i)
    mirror: np.ndarray  # L, (2, 2)
    solve: object  # factorised I + B^T B


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
            copy = mirror_correspondence(garment, p)
            if copy is not None:  # a symmetrised pair: j's vertex k is the image of one of i's
                interp = sp.csr_matrix((np.ones(len(second)), (np.arange(len(second)),
                                        local[copy])), shape=(len(second), len(first)))
            else:
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
