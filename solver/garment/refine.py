"""Midpoint subdivision of a garment: the same pattern and drape on a finer mesh.

A seam can only take a new shape at its vertices. Where seam edges are about as long as
the print's repeat (the Berkeley library's coarse meshes: 35-70 mm edges against a 50 mm
repeat), reshaping has nothing to bend, and E_fit measured at edge midpoints hides what
the eye sees between them. Splitting every triangle into four keeps the outline, the 3D
surface and every seam exactly (new vertices lie on the old edges) and halves the edge
length.
"""

from __future__ import annotations

import numpy as np

from solver.garment.model import Garment, SeamLine, build_garment


def subdivided(garment: Garment) -> Garment:
    """Every triangle split into four at its edge midpoints; seams, seam weights and names,
    pieces, grain lines and notches carried over (a midpoint of a sewn edge is sewn to the
    midpoint of its twin through the pair of 3D points it lies between)."""
    g = garment
    f = g.faces
    n = g.n_vertices
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    key, inv = np.unique(np.minimum(e[:, 0], e[:, 1]) * n + np.maximum(e[:, 0], e[:, 1]),
                         return_inverse=True)
    a, b = key // n, key % n
    mid = n + inv.reshape(3, -1).T  # (F,3): midpoints of edges 01, 12, 20
    pa, pb = g.point_of_vertex[a], g.point_of_vertex[b]
    n_pts = int(g.point_of_vertex.max()) + 1
    _, pnew = np.unique(np.minimum(pa, pb) * n_pts + np.maximum(pa, pb), return_inverse=True)
    faces = np.concatenate([
        np.column_stack([f[:, 0], mid[:, 0], mid[:, 2]]),
        np.column_stack([f[:, 1], mid[:, 1], mid[:, 0]]),
        np.column_stack([f[:, 2], mid[:, 2], mid[:, 1]]),
        mid,
    ])
    uv = np.concatenate([g.uv, 0.5 * (g.uv[a] + g.uv[b])])
    point = np.concatenate([g.point_of_vertex, n_pts + pnew.ravel()])
    xyz = None if g.xyz is None else np.concatenate([g.xyz, 0.5 * (g.xyz[a] + g.xyz[b])])
    # number vertices by first appearance, as build_garment would, so that ``origin``
    # (new vertex -> index above) stays valid
    used, first = np.unique(faces.ravel(), return_index=True)
    origin = used[np.argsort(first, kind="stable")]
    remap = np.empty(len(uv), np.int64)
    remap[origin] = np.arange(len(origin))
    out = build_garment(
        uv[origin], remap[faces], point[origin],
        xyz=None if xyz is None else xyz[origin],
        source=g.source, kind=g.kind, units_in_file=g.units_in_file,
        scale_recovered=g.scale_recovered, piece_names=list(g.piece_names),
        grainlines=dict(g.grainlines), notches={k: list(v) for k, v in g.notches.items()})
    out.seam_lines = _carried_seam_lines(g, out, key, origin)
    out.grain = g.grain
    return out


def _carried_seam_lines(old: Garment, new: Garment, edge_key: np.ndarray,
                        origin: np.ndarray) -> list[SeamLine]:
    """Each new seam line takes the weight and name of the old line its midpoint vertices
    were cut from (``edge_key``: the sorted vertex pair key of each midpoint's old edge;
    ``origin``: each new vertex's index among old vertices followed by midpoints)."""
    n = old.n_vertices
    e = old.seam_edges
    sides = np.concatenate([e[:, :2], e[:, 2:]])
    keys = np.minimum(sides[:, 0], sides[:, 1]) * n + np.maximum(sides[:, 0], sides[:, 1])
    order = np.argsort(keys)
    line_of_key = np.tile(old.seam_line_of_edge, 2)[order]
    lines = []
    for i, line in enumerate(new.seam_lines):
        verts = origin[new.seam_edges[new.seam_line_of_edge == i, :2].ravel()]
        mids = edge_key[verts[verts >= n] - n]
        pos = np.clip(np.searchsorted(keys[order], mids), 0, len(keys) - 1)
        votes = line_of_key[pos[keys[order][pos] == mids]]
        if votes.size:
            src = old.seam_lines[int(np.bincount(votes).argmax())]
            line = SeamLine(line.piece_a, line.piece_b, src.weight, src.name)
        lines.append(line)
    return lines


def refined(garment: Garment, max_seam_edge_mm: float, *, max_levels: int = 3
            ) -> tuple[Garment, int]:
    """``garment`` subdivided until its mean seam edge is at most ``max_seam_edge_mm``
    (at most ``max_levels`` times), and the number of subdivisions made."""
    g = garment
    for level in range(max_levels):
        e = g.seam_edges
        if not len(e) or np.linalg.norm(g.uv[e[:, 1]] - g.uv[e[:, 0]], axis=1).mean() \
                <= max_seam_edge_mm:
            return g, level
        g = subdivided(g)
    return g, max_levels
