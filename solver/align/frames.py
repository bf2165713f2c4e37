"""Per seam edge frames for the rotational alignment (paper Sec. 4.1 and appendix).

Every sewn pair of twin edges gives two *directed records*, one for each side: the
piece ``c`` that is updated, the piece ``o`` across the seam, and two 2x2 matrices that
express orientation vectors of both pieces in one common 2D frame of the seam edge:

    u = A_e r_c          (o_e of the paper, in the frame)
    v = C_e r_o          (o_e^rot: the neighbour's o'_e unfolded into f_e's plane)

With a drape (``xyz``), ``F_e`` is the appendix matrix; its first two columns are the
3x2 Jacobian ``J = [e1^3D e2^3D] [e1^2D e2^2D]^-1`` of the face ``f_e`` that holds the
edge. The common frame is ``B = [ê, -in]``: ``ê`` the 3D edge direction, ``in`` the unit
vector inside the face plane pointing into ``f_e``. The neighbour face is unfolded about
the shared edge (the rotation about ``n'_e x n_e`` of the paper, whose axis is ``ê``
because both normals are perpendicular to the shared edge), which maps its frame
``B' = [ê, in']`` onto ``B``. Hence ``A_e = B^T J`` and ``C_e = B'^T J'``; the paper's
``F_e^-1 o_e`` is ``A_e^-1 u``. Using the inward directions rather than the normals
makes the unfold independent of how each face is oriented in the file.

Without a drape (a flat pattern from CAD) ``J = I`` and the frames come from the twin
pattern edges themselves: ``A_e^-1 C_e`` is the orthogonal map that lays the twin edge
onto the edge with the two pieces on opposite sides, a rotation when both pieces are
drawn with the same handedness across the seam and a reflection otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solver.fit import seam_lengths
from solver.garment.mesh import edge_keys


@dataclass(frozen=True)
class SeamFrames:
    """Directed seam-edge records, two per twin pair (side a first, then side b).

    piece, other : (R,) int      the updated piece and the piece across the seam
    edge : (R,) int              index into ``garment.seam_edges``
    mid, mid_other : (R,2) float edge midpoints in the two pieces' pattern coordinates
    length : (R,) float          l_e (mean of the twins' 2D lengths, as in solver.fit)
    A, A_inv, C : (R,2,2) float  frame matrices (module docstring)
    drape : bool                 frames from the 3D drape (True) or from the pattern
    """

    piece: np.ndarray
    other: np.ndarray
    edge: np.ndarray
    mid: np.ndarray
    mid_other: np.ndarray
    length: np.ndarray
    A: np.ndarray
    A_inv: np.ndarray
    C: np.ndarray
    drape: bool

    @property
    def n_edges(self) -> int:
        return len(self.piece) // 2


def _edge_faces(faces: np.ndarray, n_vertices: int, a: np.ndarray, b: np.ndarray):
    """Face holding each boundary edge (a, b) and its third vertex."""
    he = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = edge_keys(he[:, 0], he[:, 1], n_vertices)
    order = np.argsort(key, kind="stable")
    want = edge_keys(a, b, n_vertices)
    pos = np.searchsorted(key[order], want)
    pos = np.minimum(pos, len(key) - 1)
    if np.any(key[order][pos] != want):
        raise ValueError("a seam edge is not an edge of any face of the pattern")
    face = order[pos] // 3
    third = faces[face].sum(axis=1) - a - b
    return face, third


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def _side_frames(pos: np.ndarray, a, b, c, jac, sign: float) -> np.ndarray:
    """(R,2,2) matrix B^T J with B = [ê, sign * in] built from positions ``pos``."""
    e = _unit(pos[b] - pos[a])
    w = pos[c] - pos[a]
    inward = _unit(w - np.sum(w * e, axis=-1, keepdims=True) * e)
    basis = np.stack([e, sign * inward], axis=1)  # (R, 2, d): rows are the frame axes
    return basis @ jac


def _jacobians(garment, face: np.ndarray) -> np.ndarray:
    """(R,3,2) pattern-to-drape Jacobian of each face (appendix F_e, first columns)."""
    f = garment.faces[face]
    uv, xyz = garment.uv, garment.xyz
    d2 = np.stack([uv[f[:, 1]] - uv[f[:, 0]], uv[f[:, 2]] - uv[f[:, 0]]], axis=-1)
    d3 = np.stack([xyz[f[:, 1]] - xyz[f[:, 0]], xyz[f[:, 2]] - xyz[f[:, 0]]], axis=-1)
    det = d2[:, 0, 0] * d2[:, 1, 1] - d2[:, 0, 1] * d2[:, 1, 0]
    safe = np.where(np.abs(det) > 0, det, 1.0)
    inv = np.stack([np.stack([d2[:, 1, 1], -d2[:, 0, 1]], -1),
                    np.stack([-d2[:, 1, 0], d2[:, 0, 0]], -1)], -2) / safe[:, None, None]
    return d3 @ inv


def seam_frames(garment, *, use_drape: bool = True) -> SeamFrames:
    """Directed records of every seam edge of ``garment`` (see :class:`SeamFrames`).

    ``use_drape=False`` ignores ``garment.xyz`` and takes the frames from the pattern.
    """
    se = np.asarray(garment.seam_edges, dtype=np.int64).reshape(-1, 4)
    pov = garment.piece_of_vertex
    uv = garment.uv
    # directed records: side a (edge a->b, twin a2->b2), then side b (the reverse view)
    own = np.concatenate([se[:, :2], se[:, 2:]])
    oth = np.concatenate([se[:, 2:], se[:, :2]])
    n_e = len(se)
    face, third = _edge_faces(garment.faces, len(uv), own[:, 0], own[:, 1])
    face_o, third_o = _edge_faces(garment.faces, len(uv), oth[:, 0], oth[:, 1])
    drape = use_drape and getattr(garment, "xyz", None) is not None
    if drape:
        xyz = garment.xyz
        # ê from the updated side's 3D edge for both sides: twins share their 3D points.
        e = _unit(xyz[own[:, 1]] - xyz[own[:, 0]])
        w = xyz[third] - xyz[own[:, 0]]
        w_o = xyz[third_o] - xyz[oth[:, 0]]
        inn = _unit(w - np.sum(w * e, -1, keepdims=True) * e)
        inn_o = _unit(w_o - np.sum(w_o * e, -1, keepdims=True) * e)
        A = np.stack([e, -inn], axis=1) @ _jacobians(garment, face)
        C = np.stack([e, inn_o], axis=1) @ _jacobians(garment, face_o)
    else:
        eye = np.broadcast_to(np.eye(2), (len(own), 2, 2))
        A = _side_frames(uv, own[:, 0], own[:, 1], third, eye, -1.0)
        C = _side_frames(uv, oth[:, 0], oth[:, 1], third_o, eye, 1.0)
    det = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0]
    bad = np.abs(det) < 1e-12
    if bad.any():  # degenerate drape triangles: fall back to the pattern frame there
        eye = np.broadcast_to(np.eye(2), (int(bad.sum()), 2, 2))
        A[bad] = _side_frames(uv, own[bad, 0], own[bad, 1], third[bad], eye, -1.0)
        C[bad] = _side_frames(uv, oth[bad, 0], oth[bad, 1], third_o[bad], eye, 1.0)
    length = seam_lengths(uv, se)
    return SeamFrames(
        piece=pov[own[:, 0]],
        other=pov[oth[:, 0]],
        edge=np.concatenate([np.arange(n_e), np.arange(n_e)]),
        mid=0.5 * (uv[own[:, 0]] + uv[own[:, 1]]),
        mid_other=0.5 * (uv[oth[:, 0]] + uv[oth[:, 1]]),
        length=np.concatenate([length, length]),
        A=A,
        A_inv=np.linalg.inv(A),
        C=C,
        drape=drape,
    )
