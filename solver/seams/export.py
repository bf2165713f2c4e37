"""CAD-like DXF-AAMA exports of garments whose seams are known: the seam inference's oracle.

A pattern CAD writes each piece's cut line (layer 1), its turn points (layer 2: corners and
the ends of every seam), balance notches on both sides of each seam (layer 4: at the same
share of the seam on both pieces; a double notch where the seam is on the back, a single one
elsewhere, as sewers expect), a grain line (layer 7) and the piece's name, and no seam data
at all. A dart is not cut out: the cut line runs across its mouth with the take-up's peak, a
notch marks each leg and a drill hole (layer 13) its tip (:mod:`solver.seams.darts`). Each
piece is turned by a random angle. The true seams come back as point correspondences in the
exported pieces' coordinates, so :mod:`solver.seams.score` can compare an inference made
from the file alone.
"""

from __future__ import annotations

from pathlib import Path

import ezdxf
import numpy as np
import shapely

from solver.garment.model import Garment
from solver.garment.notches import chain_seam_rows
from solver.seams.darts import DRILL_SETBACK_MM, dart_cap
from solver.seams.names import name_parts
from solver.seams.score import STEP_MM, Correspondence

__all__ = ["export_cad_dxf"]

DOUBLE_GAP_MM = 6.0  # between the two slits of a double notch
BACK_SIDE = 0.1  # an unnamed piece this share of the garment's depth behind its middle is
# a back


def _seam_rows(g: Garment, line: int) -> np.ndarray:
    """The twin rows (a0, a1, b0, b1) of one seam line, side A all on one side and running
    round its loop: a mesh may list a seam of a piece with itself (a dart, a tube's
    underarm) either side first and either way round, row by row (a CAD then got a turn
    point at every change, and a dart was not seen). Going round the loop from the widest
    stretch the seam leaves free, side A is the one met first (a dart's first leg)."""
    rows = g.seam_edges[g.seam_line_of_edge == line]
    piece = g.piece_of_vertex
    if len(rows) < 2 or piece[rows[0, 0]] != piece[rows[0, 2]]:
        return rows
    loop = g.piece_loops(int(piece[rows[0, 0]]))[0]
    at = np.full(len(g.uv), -1)
    at[loop] = np.arange(len(loop))
    n = len(loop)
    pos = np.stack([np.where((at[rows[:, k + 1]] - at[rows[:, k]]) % n == 1, at[rows[:, k]],
                             at[rows[:, k + 1]]) for k in (0, 2)], axis=1)  # (r,2) edges
    used = np.unique(pos)
    gaps = np.diff(np.append(used, used[0] + n))
    start = used[(np.argmax(gaps) + 1) % len(used)]
    ahead = (pos - start) % n
    rows = np.where((ahead[:, 1] < ahead[:, 0])[:, None], rows[:, [2, 3, 0, 1]], rows)
    forward = (at[rows[:, 1]] - at[rows[:, 0]]) % n == 1  # side A runs round the loop
    return np.where(forward[:, None], rows, rows[:, [1, 0, 3, 2]])


def _seam_sides(g: Garment, line: int) -> tuple[np.ndarray, np.ndarray]:
    """Twin vertex chains (side A, side B) of one seam line, A's k-th sewn to B's k-th."""
    rows = chain_seam_rows(_seam_rows(g, line))
    return (np.append(rows[:, 0], rows[-1, 1]), np.append(rows[:, 2], rows[-1, 3]))


def _dart_of(chain: np.ndarray, twin: np.ndarray) -> tuple[int, int, int] | None:
    """(one leg's mouth end, tip, the other's) when a seam's two sides meet at one end."""
    for i in (0, -1):
        for j in (0, -1):
            if chain[i] == twin[j]:
                return int(chain[-1 - i]), int(chain[i]), int(twin[-1 - j])
    return None


def _closed(g: Garment, i: int, darts: list[tuple[int, int, int]]) -> np.ndarray:
    """Piece ``i``'s sew line as a CAD draws its cut line's course: each dart's legs
    replaced by the take-up's peak across the mouth."""
    loop = g.piece_loops(i)[0]
    at = {int(v): k for k, v in enumerate(loop)}
    n = len(loop)
    drop, peak_after = np.zeros(n, bool), {}
    for m1, tip, m2 in darts:
        k1, kt, k2 = at[m1], at[tip], at[m2]
        if (kt - k1) % n > (k2 - k1) % n:
            k1, k2 = k2, k1  # walk forward from k1 through the tip to k2
        inner = (k1 + 1 + np.arange((k2 - k1 - 1) % n)) % n
        drop[inner] = True
        peak_after[k1] = dart_cap(g.uv[loop[k1]], g.uv[tip], g.uv[loop[k2]])
    out = []
    for k in range(n):
        if not drop[k]:
            out.append(g.uv[loop[k]])
        if k in peak_after:
            out.append(peak_after[k])
    return np.array(out)


def _backs(g: Garment) -> np.ndarray:
    """(n_pieces,) which pieces a pattern maker calls the back: by name; for a garment whose
    names say neither (a scanned or simulated mesh), the pieces that hang on one side of
    the body, along the garment's thinnest axis (a garment is wider and taller than deep),
    by more than :data:`BACK_SIDE` of its depth. Which side is the back cannot be told from
    the mesh, nor need it: the double notches only have to tell the two halves of a cap or
    a waist apart as consistently as a CAD's single front and double back notches do."""
    kinds = [name_parts(n)[0] for n in g.piece_names]
    if any(k & {"front", "back"} for k in kinds) or g.xyz is None:
        return np.array(["back" in k for k in kinds], dtype=bool)
    xyz = np.asarray(g.xyz, float)
    centred = xyz - xyz.mean(0)
    depth = np.linalg.svd(centred, full_matrices=False)[2][-1]  # least spread
    along = centred @ depth
    at = np.array([along[g.piece_of_vertex == i].mean() for i in range(g.n_pieces)])
    return at < -BACK_SIDE * float(np.ptp(along))


def _stretches(edges: np.ndarray) -> list[np.ndarray]:
    """Vertex chains of the (k,2) directed edges, one per contiguous stretch."""
    nxt = {int(a): int(b) for a, b in edges}
    out = []
    for a in sorted(set(nxt) - set(nxt.values())):
        chain = [a]
        while chain[-1] in nxt and len(chain) <= len(edges):
            chain.append(nxt[chain[-1]])
        out.append(np.array(chain))
    return out


def _one_chain(rows: np.ndarray) -> np.ndarray | None:
    """The twin rows ordered along a side that is one chain (the other side may jump a
    dart), that side first; None when neither is."""
    for r in (rows, rows[:, [2, 3, 0, 1]]):
        o = chain_seam_rows(r)
        if np.array_equal(o[1:, 0], o[:-1, 1]):
            return o
    return None


def _at_share(uv: np.ndarray, rows: np.ndarray, share: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """Points at ``share`` of side A's length and their sewn partners on side B, twin edge
    by twin edge (side B may jump a dart that side A runs past)."""
    a0, a1, b0, b1 = (uv[rows[:, k]] for k in range(4))
    cum = np.concatenate([[0], np.cumsum(np.linalg.norm(a1 - a0, axis=1))])
    s = np.clip(share, 0, 1) * cum[-1]
    k = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(rows) - 1)
    t = ((s - cum[k]) / np.maximum(cum[k + 1] - cum[k], 1e-300))[:, None]
    return a0[k] + t * (a1[k] - a0[k]), b0[k] + t * (b1[k] - b0[k])


def _face_down(g: Garment) -> np.ndarray:
    """(n_pieces,) whether each piece is drawn wrong side up. A CAD draws every piece right
    side up, so two pieces sewn right side to right side run opposite ways along their seam;
    GarmentCode draws back panels as seen from the front. Two-colour the seam graph so that
    every seam runs opposite ways (where it cannot, the first colour found stays)."""
    at = np.full(len(g.uv), -1)
    size = np.zeros(len(g.uv), int)
    for i in range(g.n_pieces):
        loop = g.piece_loops(i)[0]
        at[loop], size[loop] = np.arange(len(loop)), len(loop)
    sign = {}
    for line in range(len(g.seam_lines)):
        rows = g.seam_edges[g.seam_line_of_edge == line]
        ways = [(at[rows[:, k + 1]] - at[rows[:, k]]) % np.maximum(size[rows[:, k]], 1) == 1
                for k in (0, 2)]  # each twin edge as its loop runs, row by row (a mesh may
        # list a seam's rows either way round, or its side across a dart out of order)
        sign[line] = 1 if np.mean(ways[0] == ways[1]) > 0.5 else -1  # +1: both run the
        # same way (one piece face down)
    flip = np.full(g.n_pieces, -1)
    for start in range(g.n_pieces):
        if flip[start] >= 0:
            continue
        flip[start], todo = 0, [start]
        while todo:
            i = todo.pop()
            for line, sl in enumerate(g.seam_lines):
                if i not in (sl.piece_a, sl.piece_b) or sl.piece_a == sl.piece_b:
                    continue
                j = sl.piece_b if sl.piece_a == i else sl.piece_a
                if flip[j] < 0:
                    flip[j] = flip[i] ^ (sign[line] > 0)
                    todo.append(j)
    return flip.astype(bool)


def _sampled_twins(uv: np.ndarray, rows: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points every :data:`STEP_MM` along each twin edge pair (a->b sewn to a2->b2), the
    sewn partner of each, and the length each stands for: exact whatever the chaining."""
    a, b = uv[rows[:, 0]], uv[rows[:, 1]]
    a2, b2 = uv[rows[:, 2]], uv[rows[:, 3]]
    length = np.linalg.norm(b - a, axis=1)
    n = np.maximum(np.ceil(length / STEP_MM).astype(int), 1)
    edge = np.repeat(np.arange(len(rows)), n)
    start = np.repeat(np.cumsum(n) - n, n)
    t = ((np.arange(n.sum()) - start + 0.5) / n[edge])[:, None]
    return (a[edge] + t * (b - a)[edge], a2[edge] + t * (b2 - a2)[edge],
            (length / n)[edge])


def _frames(g: Garment, rng: np.random.Generator) -> list[np.ndarray]:
    """Each piece right side up, turned by a random angle, the pieces laid in a row:
    (2,3) affine maps."""
    out, x = [], 0.0
    down = _face_down(g)
    for i in range(g.n_pieces):
        c = g.piece_outline(i).mean(0)
        th = rng.uniform(0, 2 * np.pi)
        r = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
        if down[i]:
            r = r @ np.diag([-1.0, 1.0])
        turned = (g.piece_outline(i) - c) @ r.T
        shift = np.array([x - turned[:, 0].min(), -turned[:, 1].min()])
        out.append(np.column_stack([r, shift - r @ c]))
        x += float(np.ptp(turned[:, 0])) + 100.0
    return out


def _apply(m: np.ndarray, p: np.ndarray) -> np.ndarray:
    return np.asarray(p, float).reshape(-1, 2) @ m[:, :2].T + m[:, 2]


def export_cad_dxf(g: Garment, path: str | Path, *, allowance_mm: float = 10.0,
                   seed: int = 0) -> Correspondence:
    """Write ``g`` as a CAD would (see the module) and return its true seams, sampled."""
    rng = np.random.default_rng(seed)
    frames = _frames(g, rng)
    piece = g.piece_of_vertex
    turns: list[list[np.ndarray]] = [[] for _ in range(g.n_pieces)]
    notches: list[list[np.ndarray]] = [[] for _ in range(g.n_pieces)]
    truth = []
    darts: list[list[tuple[int, int, int]]] = [[] for _ in range(g.n_pieces)]
    backs = _backs(g)
    drills: list[list[np.ndarray]] = [[] for _ in range(g.n_pieces)]
    for line in range(len(g.seam_lines)):
        chain, twin = _seam_sides(g, line)
        pa, pb = int(piece[chain[0]]), int(piece[twin[0]])
        dart = _dart_of(chain, twin) if pa == pb else None
        if dart is not None:  # notches at the legs' ends, a drill hole short of the tip
            darts[pa].append(dart)
            m1, tip, m2 = g.uv[list(dart)]
            axis = 0.5 * (m1 + m2) - tip
            drills[pa].append(tip + axis / np.linalg.norm(axis) * DRILL_SETBACK_MM)
            notches[pa] += [m1, m2]
        rows = _seam_rows(g, line)
        a, b, w = _sampled_twins(g.uv, rows)
        truth.append(Correspondence(np.tile([pa, pb], (len(w), 1)), _apply(frames[pa], a),
                                    _apply(frames[pb], b), w))
        if dart is not None:
            continue
        for side in (0, 2):  # the ends of every stretch of each side (it may jump a dart)
            for v in _stretches(rows[:, side:side + 2]):
                turns[int(piece[v[0]])] += [g.uv[v[0]], g.uv[v[-1]]]
        ordered = _one_chain(rows)
        if ordered is None:
            continue  # a branching seam line, or both sides jump darts: no notches
        a_len = float(np.linalg.norm(g.uv[ordered[:, 1]] - g.uv[ordered[:, 0]], axis=1).sum())
        if a_len < 80.0:
            continue
        back = backs[pa] or backs[pb]
        share = 0.25 + 0.5 * ((line * 0.618034) % 1.0)
        shares = [share] + ([share + DOUBLE_GAP_MM / a_len] if back else [])
        na, nb = _at_share(g.uv, ordered, np.array(shares))
        notches[int(piece[ordered[0, 0]])] += list(na)
        notches[int(piece[ordered[0, 2]])] += list(nb)
    outlines = [_closed(g, i, darts[i]) for i in range(g.n_pieces)]
    _write(g, path, frames, outlines, (turns, notches, drills), allowance_mm)
    return Correspondence.join(truth)


def _write(g: Garment, path, frames, outlines, marks, allowance_mm: float) -> None:
    """The DXF: per piece a block with its cut line (``outlines`` buffered by the
    allowance), and its ``marks`` (turn points, notches, drill holes: lists per piece)."""
    turns, notches, drills = marks
    doc = ezdxf.new("R12")
    msp = doc.modelspace()
    grains = g.grains()  # the file's, the drape's or the panel's placement on the body
    msp.add_text("Units: METRIC", dxfattribs={"layer": "1", "height": 5.0})
    for i, name in enumerate(g.piece_names):
        sew = outlines[i]
        cut_poly = shapely.Polygon(sew).buffer(allowance_mm, join_style="mitre",
                                               mitre_limit=2.0)
        ring = shapely.LinearRing(cut_poly.exterior.coords)
        corners = [sew[k] for k in _corner_indices(sew)]
        on_cut = [np.asarray(ring.interpolate(ring.project(shapely.Point(p))).coords[0])
                  for p in corners + turns[i] + notches[i]]
        m = frames[i]
        blk = doc.blocks.new(name=f"P{i}")
        blk.add_polyline2d([tuple(q) for q in _apply(m, np.asarray(ring.coords)[:-1])],
                           close=True, dxfattribs={"layer": "1"})
        for q in _apply(m, np.array(on_cut[:len(corners) + len(turns[i])])):
            blk.add_point(tuple(q), dxfattribs={"layer": "2"})
        for q in _apply(m, np.array(on_cut[len(corners) + len(turns[i]):]).reshape(-1, 2)):
            blk.add_point(tuple(q), dxfattribs={"layer": "4"})
        for q in _apply(m, np.array(drills[i]).reshape(-1, 2)):
            blk.add_point(tuple(q), dxfattribs={"layer": "13"})
        c = sew.mean(0)
        th = np.radians(grains[i].deg)
        h = 0.3 * float(np.ptp(sew, axis=0).max()) * np.array([np.cos(th), np.sin(th)])
        grain = _apply(m, np.array([c - h, c + h]))
        blk.add_line(tuple(grain[0]), tuple(grain[1]), dxfattribs={"layer": "7"})
        for k, text in enumerate([f"Piece Name: {name}", "Quantity: 1"]):
            blk.add_text(text, dxfattribs={"layer": "1", "height": 3.0,
                                           "insert": tuple(grain[0] + [0, -5.0 * (k + 1)])})
        msp.add_blockref(f"P{i}", (0, 0), dxfattribs={"layer": "1"})
    doc.saveas(Path(path))


def _corner_indices(loop: np.ndarray, deg: float = 30.0) -> np.ndarray:
    d_in = loop - np.roll(loop, 1, axis=0)
    d_out = np.roll(loop, -1, axis=0) - loop
    cross = d_in[:, 0] * d_out[:, 1] - d_in[:, 1] * d_out[:, 0]
    return np.flatnonzero(np.degrees(np.abs(np.arctan2(cross, (d_in * d_out).sum(1)))) > deg)
