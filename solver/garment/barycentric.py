"""Barycentric interpolation in a triangle mesh, as one sparse matrix.

Carrying a field (a displacement, a 3D position) from one mesh to points of another is a
matrix product with this matrix: mirror pairs tie their displacements through it, and
symmetrising a pair takes the second piece's drape through it.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

_CANDIDATES = 12  # nearest triangles (by centroid) tried for each interpolated point


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
