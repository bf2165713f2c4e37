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
centroids c1, c*; S1 turned by theta/2 and S1* turned back by theta/2, both about
(c1 + c*)/2, meet in the middle pose, and S1_ideal is the mean of the two there.
S2_ideal is the image of S1_ideal under the inverse of the symmetry map that took S2 to
S1*, so the two ideal lines fit perfectly and are congruent (the paper's principles 1
and 2). Departure: the paper moves both lines by half the rigid motion; when the twins
differ in shape that leaves one side to take the whole shape difference (or the lines do
not fit), so the shapes are averaged too and each side moves half of everything. Where
one piece is fixed, the other side takes the whole displacement.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solver.geometry import rotation_matrices
from solver.placement import Placement

# seam length (mm) that carries one unit of proximity weight: E_prox integrates along the
# seams in these units, which sets its balance with the conformal, Dirichlet and bending
# terms (8 mm: every Berkeley garment reaches less than half its aligned E_fit)
UNIT_MM = 8.0


@dataclass(frozen=True)
class SeamTargets:
    """Proximity targets for E_prox: one row per (seam line, seam vertex).

    ``vertex`` (K,) pattern vertex, ``target`` (K,2) its ideal position in mm,
    ``weight`` (K,) w_S times the vertex's share of seam length over ``unit_mm`` (so
    E_prox integrates along the seam and keeps its balance with the conformal term when
    the mesh is refined), ``line`` (K,) its seam line.
    """

    vertex: np.ndarray
    target: np.ndarray
    weight: np.ndarray
    line: np.ndarray


@dataclass(frozen=True)
class IdealSeams(SeamTargets):
    """The paper's ideal seam lines, with per seam line (S,): ``op`` the chosen symmetry,
    ``theta`` the Procrustes angle of S1 onto S1* (radians) and ``shift`` the distance
    between the centroids of S1 and S1*."""

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


def seam_vertex_pairs(garment) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Unique twin vertex pairs (v1 on the first twin's piece, v2, seam line) of all seams
    and each pair's share of seam length (half of every seam edge it ends, in mm)."""
    e = garment.seam_edges
    line = np.asarray(garment.seam_line_of_edge, dtype=np.int64)
    uv = garment.uv
    half = 0.25 * (np.linalg.norm(uv[e[:, 1]] - uv[e[:, 0]], axis=1)
                   + np.linalg.norm(uv[e[:, 3]] - uv[e[:, 2]], axis=1))
    pairs = np.concatenate([
        np.column_stack([e[:, 0], e[:, 2], line]),
        np.column_stack([e[:, 1], e[:, 3], line]),
    ])
    pairs, inverse = np.unique(pairs, axis=0, return_inverse=True)
    length = np.bincount(inverse.ravel(), weights=np.concatenate([half, half]),
                         minlength=len(pairs))
    return pairs[:, 0], pairs[:, 1], pairs[:, 2], length


def _weighted_pairs(garment, unit_mm: float):
    """Seam vertex pairs of the weighted seam lines with their E_prox weights."""
    v1, v2, line, length = seam_vertex_pairs(garment)
    n_lines = len(garment.seam_lines)
    line_w = np.array([s.weight for s in garment.seam_lines], float).reshape(n_lines)
    keep = line_w[line] > 0
    return v1[keep], v2[keep], line[keep], (line_w[line] * length / unit_mm)[keep]


def _shares(garment, fixed, pi, pj) -> tuple[np.ndarray, np.ndarray]:
    """Fraction of a pair's displacement each side takes: half each, all of it for the
    side whose twin is on a fixed piece, none on a fixed piece."""
    fixed = (np.zeros(garment.n_pieces, bool) if fixed is None
             else np.asarray(fixed, bool).reshape(garment.n_pieces))
    fi, fj = fixed[pi], fixed[pj]
    si = np.where(fi, 0.0, np.where(fj, 1.0, 0.5))
    sj = np.where(fj, 0.0, np.where(fi, 1.0, 0.5))
    return si, sj


def matched_seams(garment, placement: Placement, *, uv: np.ndarray | None = None,
                  fixed: np.ndarray | None = None, unit_mm: float = UNIT_MM) -> SeamTargets:
    """Targets from each twin edge pair's own closest symmetry (what E_fit measures),
    split between the two sides like the ideal lines.

    The paper's ideal lines choose one symmetry per whole seam line; where twin lines
    differ in shape that can ask for moves of many lattice cells, and a pattern that only
    gets part of the way can fit worse than before. Here every seam edge takes the
    symmetry that maps its twin's midpoint closest to its own (E_fit's measure) and both
    its ends are pulled halfway onto the twin's image under it, so no vertex moves by more
    than half of the print's covering radius plus about one seam edge, and alternating
    these targets with the solve (as in ICP) keeps lowering E_fit. A vertex between two
    edges that chose different symmetries gets both targets (their mean), which keeps the
    fit at the midpoints rather than at isolated vertices.
    """
    uv = garment.uv if uv is None else np.asarray(uv, float)
    e = garment.seam_edges
    line = np.asarray(garment.seam_line_of_edge, dtype=np.int64)
    line_w = np.array([s.weight for s in garment.seam_lines], float).reshape(-1)
    keep = line_w[line] > 0 if len(e) else np.zeros(0, bool)
    e, line = e[keep], line[keep]
    piece = garment.piece_of_vertex
    pi, pj = piece[e[:, 0]], piece[e[:, 2]]
    mid_p = placement.to_wallpaper(0.5 * (uv[e[:, 0]] + uv[e[:, 1]]), pi)
    mid_q = placement.to_wallpaper(0.5 * (uv[e[:, 2]] + uv[e[:, 3]]), pj)
    op, lattice = placement.fabric.closest_symmetry(mid_p, mid_q)
    g = placement.fabric.cartesian_ops()[op]
    g[:, :2, 2] += lattice
    a_i = _homogeneous(rotation_matrices(placement.angles[pi]), placement.translations[pi])
    a_j = _homogeneous(rotation_matrices(placement.angles[pj]), placement.translations[pj])
    m = a_i @ g @ np.linalg.inv(a_j)  # per edge: pattern of piece j -> pattern of piece i
    m_inv = np.linalg.inv(m)
    si, sj = _shares(garment, fixed, pi, pj)
    uv0 = garment.uv  # weights from the input pattern, as the ideal lines': E_prox's
    length = 0.5 * (np.linalg.norm(uv0[e[:, 1]] - uv0[e[:, 0]], axis=1)  # Hessian stays put
                    + np.linalg.norm(uv0[e[:, 3]] - uv0[e[:, 2]], axis=1))
    targets, vertices = [], []
    for a, b in ((0, 2), (1, 3)):  # the two ends of the edge and their twins
        p, q = uv[e[:, a]], uv[e[:, b]]
        targets += [p + si[:, None] * (_apply(m, q) - p), q + sj[:, None] * (_apply(m_inv, p) - q)]
        vertices += [e[:, a], e[:, b]]
    return SeamTargets(vertex=np.concatenate(vertices), target=np.concatenate(targets),
                       weight=np.tile(line_w[line] * 0.5 * length / unit_mm, 4),
                       line=np.tile(line, 4))


def ideal_seams(garment, placement: Placement, *, uv: np.ndarray | None = None,
                fixed: np.ndarray | None = None, unit_mm: float = UNIT_MM,
                blend_shapes: bool = True) -> IdealSeams:
    """Ideal seam lines of every weighted seam line of ``garment`` under ``placement``.

    ``uv`` (V,2) overrides the garment's pattern; ``fixed`` (n_pieces,) bool marks pieces
    that must not move (their twins take the whole displacement); ``unit_mm`` the seam
    length that carries one unit of proximity weight. ``blend_shapes=False`` is the
    paper as written: both lines move by half the rigid motion, and S1's ideal line has
    S2's shape.
    """
    uv = garment.uv if uv is None else np.asarray(uv, float)
    v1, v2, line, weight = _weighted_pairs(garment, unit_mm)
    n_lines = len(garment.seam_lines)
    if len(v1) == 0:
        empty = np.zeros(0, np.int64)
        return IdealSeams(empty, np.zeros((0, 2)), np.zeros(0), empty,
                          np.zeros(n_lines, np.int64), np.zeros(n_lines), np.zeros(n_lines))
    piece = garment.piece_of_vertex
    pi, pj = piece[v1], piece[v2]
    m, best = _twin_maps(placement, uv, v1, v2, pi, pj, line, n_lines)
    s1 = uv[v1]
    s1_star = _apply(m, uv[v2])
    # Procrustes (rotation only) of S1 onto S1*, per line, uniform vertex weights
    count = np.bincount(line, minlength=n_lines).astype(float)

    def centroid(x: np.ndarray) -> np.ndarray:
        return np.stack([np.bincount(line, weights=x[:, c], minlength=n_lines)
                         for c in range(2)], -1) / np.maximum(count, 1.0)[:, None]

    c1, cs = centroid(s1), centroid(s1_star)
    x, y = s1 - c1[line], s1_star - cs[line]
    dot = np.bincount(line, weights=np.einsum("pi,pi->p", x, y), minlength=n_lines)
    crs = np.bincount(line, weights=x[:, 0] * y[:, 1] - x[:, 1] * y[:, 0], minlength=n_lines)
    theta = np.arctan2(crs, dot)  # S1 rotated by theta best matches S1*
    share, share_j = _shares(garment, fixed, pi, pj)
    s1_ideal = _meeting_line(share if blend_shapes else (share > 0).astype(float), share,
                             theta[line], c1[line], (cs - c1)[line], x, y)
    s2_ideal = _apply(np.linalg.inv(m), s1_ideal)
    stuck = (share == 0) & (share_j == 0)  # both pieces fixed: targets where they are
    s1_ideal[stuck] = s1[stuck]
    s2_ideal[stuck] = uv[v2][stuck]
    return IdealSeams(
        vertex=np.concatenate([v1, v2]),
        target=np.concatenate([s1_ideal, s2_ideal]),
        weight=np.concatenate([weight, weight]),
        line=np.concatenate([line, line]),
        op=best,
        theta=theta,
        shift=np.hypot(*(cs - c1).T),
    )


def _twin_maps(placement: Placement, uv: np.ndarray, v1: np.ndarray, v2: np.ndarray,
               pi: np.ndarray, pj: np.ndarray, line: np.ndarray, n_lines: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """Per twin vertex pair the map M (K,3,3) from piece j's pattern to piece i's taking
    S2 onto S1*, and per seam line the symmetry operation chosen (S,)."""
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
    shift_h = np.tile(np.eye(3), (n_lines, 1, 1))
    shift_h[:, :2, 2] = lat_best
    g = shift_h @ ops[best]  # (S,3,3) in wallpaper space
    return a_i @ g[line] @ np.linalg.inv(a_j), best


def _meeting_line(shape: np.ndarray, share: np.ndarray, theta: np.ndarray, c1: np.ndarray,
                  shift: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """S1's ideal line. S1's ``share`` of the displacement is half, all (twin fixed) or
    none (own piece fixed). Both lines meet in the middle pose: S1 (``x`` about its
    centroid ``c1``) turned forward by share*theta, S1* (``y``) turned back by the rest,
    both about the interpolated centroid (``shift``: S1*'s centroid from S1's); the ideal
    line blends their shapes by S1*'s ``shape`` share, so each side also takes its share
    of the shape difference (S1 no longer has to take S2's whole shape, e.g. a straight
    edge sewn to a curved one)."""
    centre = c1 + share[:, None] * shift
    fwd = np.einsum("pij,pj->pi", rotation_matrices(share * theta), x)
    bwd = np.einsum("pij,pj->pi", rotation_matrices((share - 1.0) * theta), y)
    return (1.0 - shape)[:, None] * fwd + shape[:, None] * bwd + centre


def ideal_move_rms(garment, ideal: IdealSeams) -> np.ndarray:
    """(S,) mm: per seam line, how far its ideal lines lie from where the pattern is
    (root mean square over the line's vertices, both sides)."""
    n_lines = len(garment.seam_lines)
    d2 = np.sum((ideal.target - garment.uv[ideal.vertex]) ** 2, axis=1)
    count = np.maximum(np.bincount(ideal.line, minlength=n_lines), 1)
    return np.sqrt(np.bincount(ideal.line, weights=d2, minlength=n_lines) / count)


def reach_mm(placement: Placement, reach: float, max_move_mm: float) -> float:
    """How far (RMS, mm) an ideal line may lie and still be pulled to: ``reach`` times
    the print's covering radius, and no farther than the move bound lets a vertex go."""
    return min(reach * placement.fabric.covering_radius, max_move_mm)


def initial_targets(garment, placement: Placement, ideal: IdealSeams, *,
                    fixed: np.ndarray | None = None, unit_mm: float = UNIT_MM,
                    reach: float = 1.0, max_move_mm: float = np.inf) -> SeamTargets:
    """The ideal lines where they are within reach, matched targets elsewhere.

    One symmetry for a whole seam line gives a perfect fit where the twin lines have
    nearly the same shape. Where the ideal line lies farther from the current line than
    the print's covering radius (RMS over its vertices), which no mismatch can exceed,
    the twins differ in shape beyond what one symmetry can absorb (the paper's Fig. 15):
    pulling them there would distort the piece and, short of arriving, fit worse than
    before. Likewise beyond ``max_move_mm``, the bound no vertex may cross: a t-shirt's
    sleeve cap runs some 55 degrees off its armhole's direction under every symmetry of
    a plaid, its ideal lines lie 37 mm (RMS) away, and pulling the pattern 10 mm towards
    them only bent it (0.8 % of a front's area) for no gain in fit. Those lines start
    from their per-edge matched targets instead (`reach_mm`).
    """
    far = ideal_move_rms(garment, ideal) > reach_mm(placement, reach, max_move_mm)
    if not far.any():
        return ideal
    matched = matched_seams(garment, placement, fixed=fixed, unit_mm=unit_mm)
    a, b = ~far[ideal.line], far[matched.line]
    return SeamTargets(vertex=np.concatenate([ideal.vertex[a], matched.vertex[b]]),
                       target=np.concatenate([ideal.target[a], matched.target[b]]),
                       weight=np.concatenate([ideal.weight[a], matched.weight[b]]),
                       line=np.concatenate([ideal.line[a], matched.line[b]]))
