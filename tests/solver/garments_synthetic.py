"""Synthetic garments for alignment tests: a printed sheet cut into pieces.

A rectangle of fabric is triangulated on a grid (cells split along one diagonal) and
cut along grid lines and diagonals, so every cut is straight and follows mesh edges.
Each piece is then moved and turned at random in the pattern plane. Sewing the pieces
back along the cuts rebuilds the sheet, so a perfect alignment exists: the placement
that puts every piece back where it was cut (``truth``).
"""

from __future__ import annotations

import numpy as np

from solver.garment.model import build_garment


def cut_sheet(width: float = 240.0, height: float = 180.0, *, nx: int = 24, ny: int = 18,
              cuts_x=(0.5,), cuts_y=(0.5,), cuts_diag=(), seed: int = 0,
              drape: bool = True, spread: float = 400.0):
    """Garment cut from one sheet, and the placement that reassembles it.

    cuts_x, cuts_y : fractions of the width/height where vertical/horizontal cuts run
    cuts_diag : fractions c of the width for diagonal cuts ``x/sx - y/sy = c * nx``
    drape : give the flat sheet as the 3D drape (else a 2D-only garment)
    Returns (garment, truth_angles (P,), truth_translations (P,2)); with the truth
    placement ``p2D = R p_wp + t`` maps each piece's sheet coordinates to its pattern.
    """
    rng = np.random.default_rng(seed)
    sx, sy = width / nx, height / ny
    i, j = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), indexing="ij")
    sheet = np.column_stack([i.ravel() * sx, j.ravel() * sy])
    vid = (i * (ny + 1) + j)
    a, b = vid[:-1, :-1].ravel(), vid[1:, :-1].ravel()
    c, d = vid[1:, 1:].ravel(), vid[:-1, 1:].ravel()
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    cen = sheet[faces].mean(axis=1) / [sx, sy]  # grid units
    region = np.zeros(len(faces), np.int64)
    for k, f in enumerate(cuts_x):
        region += (cen[:, 0] > f * nx) * 3 ** (3 * k)
    for k, f in enumerate(cuts_y):
        region += (cen[:, 1] > f * ny) * 3 ** (3 * k + 1)
    for k, f in enumerate(cuts_diag):
        region += (cen[:, 0] - cen[:, 1] > f * nx) * 3 ** (3 * k + 2)
    _, piece_of_face = np.unique(region, return_inverse=True)
    n_pieces = piece_of_face.max() + 1
    # one copy of each vertex per piece that uses it
    key = piece_of_face[:, None] * len(sheet) + faces
    uniq, inv = np.unique(key.ravel(), return_inverse=True)
    new_faces = inv.reshape(faces.shape)
    point = uniq % len(sheet)
    piece_v = uniq // len(sheet)
    angles = rng.uniform(0, 2 * np.pi, n_pieces)
    shifts = rng.uniform(-spread, spread, (n_pieces, 2))
    c_, s_ = np.cos(angles), np.sin(angles)
    rmat = np.stack([np.stack([c_, -s_], -1), np.stack([s_, c_], -1)], -2)
    uv = np.einsum("nij,nj->ni", rmat[piece_v], sheet[point]) + shifts[piece_v]
    xyz = np.column_stack([sheet[point], np.zeros(len(point))]) if drape else None
    g = build_garment(uv, new_faces, point, xyz=xyz, source="synthetic sheet",
                      kind="synthetic")
    # build_garment renumbers pieces by first appearance: map the truth to its order
    order = _piece_order(g, uv, piece_v)
    return g, angles[order], shifts[order]


def _piece_order(g, uv_before: np.ndarray, piece_before: np.ndarray) -> np.ndarray:
    """For each garment piece, the synthetic piece it came from (matched by position)."""
    out = np.empty(g.n_pieces, np.int64)
    for p in range(g.n_pieces):
        v = g.uv[np.flatnonzero(g.piece_of_vertex == p)[0]]
        k = np.argmin(np.sum((uv_before - v) ** 2, axis=1))
        out[p] = piece_before[k]
    return out
