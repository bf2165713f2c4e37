"""Where a garment hangs: its up axis, where a specification places its flat panels, and
its openings (the open edges chained into necklines, hems and cuffs).

The grain (:mod:`solver.garment.grain`) needs the up axis and a sleeve's axis; the seam
allowance (:mod:`solver.garment.allowance`) needs to know which opening is a hem. Both
read them here, so neither imports the other. Functions take any garment-like object
(:class:`solver.garment.model.Garment`); of the garment modules this one imports only
the mesh helpers.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from solver.garment.mesh import connected_components, edge_keys

LIMB_ANGLE_DEG = 30.0  # a wrapped piece whose axis is this far from vertical is a limb
PANEL_UP = np.array([0.0, 1.0, 0.0])  # specifications place their panels y-up (GarmentCode)
TOP_FRACTION = 0.05  # an opening within this fraction of the height from the top is not a hem
LEVEL = 0.7  # |cos| between a loop's plane normal and up above which the loop is level
VOTE_LEVEL = 0.9  # level enough (within ~25 degrees) to vote on which end is up


def detect_up(xyz: np.ndarray) -> np.ndarray:
    """Unit (3,) up axis of a draped garment: the coordinate axis across which it is least
    mirror-symmetric (median distance from each reflected vertex to the garment)."""
    xyz = np.asarray(xyz, float)
    tree = cKDTree(xyz)
    err = np.empty(3)
    for a in range(3):  # three axes: a loop of three queries, each vectorised
        mirrored = xyz.copy()
        mirrored[:, a] = xyz[:, a].min() + xyz[:, a].max() - xyz[:, a]
        err[a] = np.median(tree.query(mirrored)[0])
    v = np.zeros(3)
    v[int(np.argmax(err))] = 1.0
    return v


def panel_positions(garment) -> np.ndarray | None:
    """(V,3) mm: where a specification places its flat panels around the body (``PANEL_UP``
    up), or None when not every piece is placed."""
    g = garment
    if len(g.panel_frames) != g.n_pieces or g.n_pieces == 0:
        return None
    frames = np.stack([g.panel_frames[i] for i in range(g.n_pieces)])[g.piece_of_vertex]
    return np.einsum("vij,vj->vi", frames, np.column_stack([g.uv, np.ones(g.n_vertices)]))


def open_edges(garment, up: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Open boundary edges (sewn to nothing), the opening each belongs to, and whether hem.

    Returns ``edges`` (k,2) vertex pairs as in their face, ``opening`` (k,) int and
    ``is_hem`` (n_openings,) bool. Openings are numbered by their first edge. ``up`` is
    the drape's up direction (default: :func:`drape_up`).
    """
    g, n = garment, garment.n_vertices
    bhe = g.boundary_half_edges()
    seam = np.concatenate([edge_keys(g.seam_edges[:, 0], g.seam_edges[:, 1], n),
                           edge_keys(g.seam_edges[:, 2], g.seam_edges[:, 3], n)])
    edges = bhe[~np.isin(edge_keys(bhe[:, 0], bhe[:, 1], n), seam)]
    if len(edges) == 0:
        return edges, np.zeros(0, np.int64), np.zeros(0, bool)
    pts = g.point_of_vertex[edges]
    _, label = connected_components(int(g.point_of_vertex.max()) + 1, pts)
    _, first, inv = np.unique(label[pts[:, 0]], return_index=True, return_inverse=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    opening = rank[inv.ravel()]
    flat = g.xyz is None or float(np.ptp(g.xyz, axis=0).min()) <= 1e-9 * max(
        float(np.ptp(g.xyz, axis=0).max()), 1e-9)  # a drape with no depth says nothing
    if not flat:
        pos = g.xyz
        up = drape_up(pos, edges, opening) if up is None else np.asarray(up, float)
    elif (placed := panel_positions(g)) is not None:  # a specification places its panels
        pos = placed
        up = PANEL_UP if up is None else np.asarray(up, float)
    else:  # flat pattern: heights relative to each piece's own box
        box = g.piece_bboxes()
        piece = g.piece_of_vertex
        rel = (g.uv[:, 1] - box[piece, 1]) / np.maximum(box[piece, 3] - box[piece, 1], 1e-9)
        reach = np.full(len(first), -np.inf)
        np.maximum.at(reach, opening, rel[edges].max(axis=1))
        return edges, opening, reach < 1.0 - TOP_FRACTION
    up = up / np.linalg.norm(up)
    h = pos @ up
    top, span = float(h.max()), float(np.ptp(h)) or 1.0
    reach = np.full(len(first), -np.inf)
    np.maximum.at(reach, opening, h[edges].max(axis=1))
    _, normal, _ = _opening_planes(pos, edges, opening)
    level = np.abs(normal @ up) > LEVEL
    # a limb's end: an upright loop (a T-pose sleeve's cuff reaches the shoulder's height)
    # on pieces that have no other opening; an armhole's pieces also carry the neckline
    alone = _alone(g, edges, opening).any(axis=1)
    return edges, opening, (reach < top - TOP_FRACTION * span) | (~level & alone)


def _alone(g, edges: np.ndarray, opening: np.ndarray) -> np.ndarray:
    """(k, P) bool: opening k touches piece p, and every piece it touches carries no other
    opening (a limb's end: a cuff, a leg's hem; a torso also has its neckline)."""
    k = int(opening.max()) + 1
    touches = np.zeros((k, g.n_pieces), bool)
    touches[opening, g.piece_of_vertex[edges[:, 0]]] = True
    others = touches.sum(0)[None, :] - touches  # other openings on each piece
    return touches & ~np.any(touches & (others > 0), axis=1)[:, None]


def limb_end_axes(garment, pos: np.ndarray, up: np.ndarray) -> np.ndarray:
    """(P,3) per piece the axis of the limb it belongs to, or NaN: the plane normal of an
    upright opening alone on its pieces (a sleeve's cuff), for patterns whose pieces lie
    flat in 3D (a specification's panels), where the drape's wrapping says nothing.
    It points towards the garment's middle (the sleeve's cap), as ``limb_axes`` does."""
    out = np.full((garment.n_pieces, 3), np.nan)
    edges, opening, _ = open_edges(garment, up)
    if len(edges) == 0:
        return out
    centre, normal, _ = _opening_planes(pos, edges, opening)
    upright = np.abs(normal @ up) < np.cos(np.radians(LIMB_ANGLE_DEG))
    towards = np.einsum("ki,ki->k", normal, pos.mean(0) - centre)
    normal = normal * np.where(towards < 0, -1.0, 1.0)[:, None]
    for k, piece in zip(*np.nonzero(_alone(garment, edges, opening) & upright[:, None])):
        out[piece] = normal[k]
    return out


def _opening_planes(pos: np.ndarray, edges: np.ndarray, opening: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per opening its centre (k,3), unit plane normal (k,3) and length (k,) in 3D."""
    k = int(opening.max()) + 1
    length = np.linalg.norm(pos[edges[:, 1]] - pos[edges[:, 0]], axis=1)
    total = np.bincount(opening, weights=length, minlength=k)
    mid = 0.5 * (pos[edges[:, 0]] + pos[edges[:, 1]])
    centre = np.stack([np.bincount(opening, weights=mid[:, j] * length, minlength=k)
                       for j in range(3)], 1) / np.maximum(total, 1e-12)[:, None]
    normal = np.zeros((k, 3))
    for o in range(k):  # one small SVD per opening (a handful per garment)
        p = mid[opening == o] - centre[o]
        if len(p) >= 3:
            normal[o] = np.linalg.svd(p, full_matrices=False)[2][-1]
    return centre, normal, total


def drape_up(xyz: np.ndarray, edges: np.ndarray, opening: np.ndarray) -> np.ndarray:
    """The drape's up direction (the files disagree: Berkeley is z-up, GarmentCode y-up).

    The axis is the one across which the garment is least mirror-symmetric
    (:func:`detect_up`, as the grain takes it): a garment mirrors
    left to right, and the openings' planes favour the wrong axis on an open front (a
    shirt's or jacket's hem, front edges and neckline are one loop, standing upright) or
    with T-pose sleeves. The sense: a garment hangs from its smaller end, the neckline
    or waist shorter than the hems below it, so up is the side of the mid-height with
    less length of level openings; only loops within ``VOTE_LEVEL`` of level vote (a
    sleeve's cuff at 45 degrees is neither hem nor neckline).
    """
    axis = int(np.argmax(detect_up(xyz)))
    centre, normal, total = _opening_planes(xyz, edges, opening)
    level = np.abs(normal[:, axis]) > VOTE_LEVEL
    h = centre[:, axis]
    middle = 0.5 * (xyz[:, axis].min() + xyz[:, axis].max())
    above = total[level & (h > middle)].sum()
    below = total[level & (h <= middle)].sum()
    up = np.zeros(3)
    up[axis] = 1.0 if above <= below else -1.0
    return up
