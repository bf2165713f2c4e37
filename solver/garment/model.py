"""The garment model: a sewing pattern (2D mesh, mm), its optional drape, and its seams.

A garment is one triangle mesh in pattern space whose connected components are the pieces.
Every pattern vertex also carries the id of the 3D point it is sewn to
(``point_of_vertex``): twin vertices on the two sides of a seam share it. A seam edge is one
3D edge used by two pattern boundary edges; seam edges between the same two pieces that
follow each other along the boundary form a seam line, which carries the weight the fit
measure uses. Deriving everything from (uv, faces, point_of_vertex) lets every importer
(OBJ, OBJ pairs, JSON specifications) share one vectorised topology pass.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix

import untrusted
from solver.garment.errors import GarmentError
from solver.garment.grain import PieceGrain, piece_grains
from solver.garment.mesh import boundary_half_edges, connected_components, edge_keys
from solver.geometry import polygon_area, signed_areas


@dataclass(frozen=True)
class SeamLine:
    """A maximal run of sewn twin edges between two pieces (or one piece and itself)."""

    piece_a: int
    piece_b: int
    weight: float = 1.0
    name: str = ""


@dataclass(eq=False)
class Garment:
    """Sewing pattern in millimetres with its seams and optional 3D drape.

    Attributes
    ----------
    uv : (V,2) float array
        Pattern coordinates in mm.
    faces : (F,3) int array
        Triangles, counter-clockwise in ``uv``.
    xyz : (V,3) float array or None
        Draped (or placed) 3D position of each pattern vertex in mm; None for 2D-only input.
    point_of_vertex : (V,) int array
        Id of the 3D point each pattern vertex is sewn to; twins share an id.
    piece_of_vertex : (V,) int array
        Piece (connected component of the pattern mesh) of each vertex.
    piece_names : list of str
        One name per piece (panel names from JSON, ``piece0``... otherwise).
    seam_edges : (E,4) int array
        ``[a, b, a2, b2]``: pattern edge a->b (oriented as in its face, the piece on its
        left) is sewn to a2->b2 with a~a2 and b~b2 the same 3D points; one row per twin pair.
    seam_line_of_edge : (E,) int array
        Index into ``seam_lines`` of each seam edge.
    seam_lines : list of SeamLine
        Maximal runs of twin pairs between the same two pieces, connected along the boundary.
    boundary_3d_edges : int
        Pattern boundary edges sewn to nothing (hems, necklines): boundary = 2 E + this.
    grainlines, notches : dict
        Per piece index, where the input has them (mm, pattern coordinates).
    grain : tuple of PieceGrain
        Each piece's grain direction and its source (`solver.garment.grain`); empty until
        :meth:`grains` infers it or :meth:`with_grain` sets it.
    panel_frames : dict
        Per piece a (3,3) float array ``F``: a specification places its panel around the
        body, and the pattern point (u, v) sits at ``F @ (u, v, 1)`` (mm, world, +y up).
    edge_curves : dict
        Per directed boundary edge (a, b) the pattern's own curve between its two ends, as
        (m,2) chord coordinates (:mod:`solver.garment.curves`): a specification's Beziers
        and arcs, for cutting; empty where the outline is the mesh itself.
    cut_outlines : dict
        Per piece the cut line its file draws, (k,2) CCW, pattern mm (a DXF's layer 1, as
        the pattern maker drew it): cut there rather than on an offset of the sew line;
        dropped when the sew line moves (:meth:`with_uv`), since the file's allowance no
        longer holds.
    units_in_file : str
        Units the file's coordinates were read in ("m", "cm", "mm", "in", or "1/N m").
    scale_recovered : float or None
        Factor applied to normalised [0,1] texture coordinates to bring them to the file's
        units (fitted to the 3D edge lengths); None when the file's vt were used as they are.
    source, kind : str
        The file read and its kind: "obj", "obj-pair" or "spec".
    """

    uv: np.ndarray
    faces: np.ndarray
    xyz: np.ndarray | None
    point_of_vertex: np.ndarray
    piece_of_vertex: np.ndarray
    piece_names: list[str]
    seam_edges: np.ndarray
    seam_line_of_edge: np.ndarray
    seam_lines: list[SeamLine]
    boundary_3d_edges: int = 0
    grainlines: dict[int, tuple[tuple[float, float], tuple[float, float]]] = field(
        default_factory=dict
    )
    notches: dict[int, list[tuple[float, float]]] = field(default_factory=dict)
    grain: tuple[PieceGrain, ...] = ()
    panel_frames: dict[int, np.ndarray] = field(default_factory=dict)
    edge_curves: dict[tuple[int, int], np.ndarray] = field(default_factory=dict)
    cut_outlines: dict[int, np.ndarray] = field(default_factory=dict)
    units_in_file: str = "mm"
    scale_recovered: float | None = None
    source: str = ""
    kind: str = "obj"
    _loops: list[list[np.ndarray]] | None = field(default=None, repr=False, compare=False)

    # ------------------------------------------------------------------ basic facts
    @property
    def n_pieces(self) -> int:
        return len(self.piece_names)

    @property
    def n_vertices(self) -> int:
        return int(self.uv.shape[0])

    def piece_of_face(self) -> np.ndarray:
        """(F,) int piece of each face."""
        return self.piece_of_vertex[self.faces[:, 0]]

    def grains(self) -> tuple[PieceGrain, ...]:
        """Each piece's grain: as set by :meth:`with_grain`, else from the file, the drape
        or (with a warning) the outline, inferred once and kept."""
        if len(self.grain) != self.n_pieces:
            self.grain = piece_grains(self)
        return self.grain

    def with_grain(self, *, lines: Mapping[int | str, float] | None = None,
                   bias=(), up: np.ndarray | str | None = None) -> Garment:
        """Copy whose grain takes the operator's ``lines`` (degrees by piece name or index),
        ``bias`` pieces and the drape's ``up`` axis into account."""
        out = self.copy()
        out.grain = piece_grains(self, lines=lines, bias=bias, up=up)
        return out

    def seam_weights(self) -> np.ndarray:
        """(E,) float weight of each seam edge, taken from its seam line."""
        w = np.array([s.weight for s in self.seam_lines], dtype=float)
        if w.size == 0:
            return np.zeros(0)
        return w[self.seam_line_of_edge]

    def with_seam_weights(self, mapping: Mapping[int | str, float]) -> Garment:
        """Copy with seam-line weights replaced; keys are seam-line indices or names."""
        names = {s.name: i for i, s in enumerate(self.seam_lines)}
        lines = list(self.seam_lines)
        for key, weight in mapping.items():
            idx = names.get(key) if isinstance(key, str) else int(key)
            if idx is None or not 0 <= idx < len(lines):
                raise ValueError(f"no seam line {key!r} (there are {len(lines)})")
            if not np.isfinite(weight) or weight < 0:
                raise ValueError(f"seam weight for {key!r} must be finite and >= 0")
            lines[idx] = dataclasses.replace(lines[idx], weight=float(weight))
        out = self.copy()
        out.seam_lines = lines
        return out

    def with_uv(self, new_uv: np.ndarray) -> Garment:
        """Copy with the pattern replaced (same topology), as reshaping produces."""
        new_uv = np.asarray(new_uv, dtype=float)
        if new_uv.shape != self.uv.shape:
            raise ValueError(f"new uv has shape {new_uv.shape}, expected {self.uv.shape}")
        out = self.copy()
        out.uv = new_uv.copy()
        out.cut_outlines = {}  # the file's cut lines carried the allowance of the old outline
        return out

    def copy(self) -> Garment:
        """Deep copy of arrays and per-piece dictionaries."""
        return dataclasses.replace(
            self,
            uv=self.uv.copy(),
            faces=self.faces.copy(),
            xyz=None if self.xyz is None else self.xyz.copy(),
            point_of_vertex=self.point_of_vertex.copy(),
            piece_of_vertex=self.piece_of_vertex.copy(),
            piece_names=list(self.piece_names),
            seam_edges=self.seam_edges.copy(),
            seam_line_of_edge=self.seam_line_of_edge.copy(),
            seam_lines=list(self.seam_lines),
            grainlines=dict(self.grainlines),
            notches={k: list(v) for k, v in self.notches.items()},
            panel_frames={k: v.copy() for k, v in self.panel_frames.items()},
            edge_curves=dict(self.edge_curves),  # arrays never changed in place
            cut_outlines=dict(self.cut_outlines),
            _loops=None,
        )

    # ------------------------------------------------------------------ outlines
    def boundary_half_edges(self) -> np.ndarray:
        """(B,2) int pattern boundary edges oriented as in their face (interior on the left)."""
        he = self.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        return boundary_half_edges(he, self.n_vertices)

    def piece_loops(self, i: int) -> list[np.ndarray]:
        """Vertex-index loops of piece ``i``: outer boundary first (CCW), then holes (CW)."""
        if self._loops is None:
            self._loops = _piece_loops(self)
        if not 0 <= i < self.n_pieces:
            raise IndexError(f"piece {i} out of range (garment has {self.n_pieces})")
        return self._loops[i]

    def piece_outline(self, i: int) -> np.ndarray:
        """(k,2) float outer boundary of piece ``i``, counter-clockwise, in mm."""
        return self.uv[self.piece_loops(i)[0]]

    def piece_holes(self, i: int) -> list[np.ndarray]:
        """Inner boundary loops of piece ``i`` as (k,2) arrays (clockwise), in mm."""
        return [self.uv[loop] for loop in self.piece_loops(i)[1:]]

    def piece_areas(self) -> np.ndarray:
        """(n_pieces,) float pattern area of each piece in mm^2."""
        area = signed_areas(self.uv, self.faces)
        return np.bincount(self.piece_of_face(), weights=area, minlength=self.n_pieces)

    def piece_bboxes(self) -> np.ndarray:
        """(n_pieces,4) float [xmin, ymin, xmax, ymax] of each piece in mm."""
        out = np.empty((self.n_pieces, 4))
        for k in range(2):
            out[:, k] = np.full(self.n_pieces, np.inf)
            np.minimum.at(out[:, k], self.piece_of_vertex, self.uv[:, k])
            out[:, k + 2] = np.full(self.n_pieces, -np.inf)
            np.maximum.at(out[:, k + 2], self.piece_of_vertex, self.uv[:, k])
        return out


# ---------------------------------------------------------------------- helpers


def unique_rows(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct rows of a finite (n,k) array (sorted) and the (n,) inverse index.

    A lexsort over the columns: several times faster than ``np.unique(axis=0)``, which
    sorts structured rows. Rows compare by exact value (so -0.0 equals 0.0).
    """
    a = np.asarray(a) + 0  # -0.0 -> 0.0
    if len(a) == 0:
        return a, np.zeros(0, dtype=np.int64)
    order = np.lexsort(a.T[::-1])
    srt = a[order]
    new = np.empty(len(a), dtype=bool)
    new[0] = True
    new[1:] = (srt[1:] != srt[:-1]).any(axis=1)
    inv = np.empty(len(a), dtype=np.int64)
    inv[order] = np.cumsum(new) - 1
    return srt[new], inv


def _piece_loops(g: Garment) -> list[list[np.ndarray]]:
    """Walk boundary half-edges into loops; the outer loop of a piece has the largest area."""
    bhe = g.boundary_half_edges()
    nxt: dict[int, list[int]] = {}
    for a, b in bhe.tolist():
        nxt.setdefault(a, []).append(b)
    loops_by_piece: list[list[np.ndarray]] = [[] for _ in range(g.n_pieces)]
    for start in list(nxt):
        while nxt.get(start):
            loop = [start]
            cur = nxt[start].pop()
            while cur != start and nxt.get(cur):
                loop.append(cur)
                cur = nxt[cur].pop()
            loops_by_piece[int(g.piece_of_vertex[start])].append(np.array(loop, dtype=np.int64))
    out: list[list[np.ndarray]] = []
    for loops in loops_by_piece:
        if not loops:
            out.append([np.zeros(0, dtype=np.int64)])
            continue
        areas = [polygon_area(g.uv[lp]) for lp in loops]
        order = np.argsort(-np.abs(areas), kind="stable")
        out.append([loops[k] for k in order])
    return out


def _check_extent(source: str | Path, points: np.ndarray, what: str) -> None:
    """A garment spans at most :data:`untrusted.limits.MAX_GARMENT_MM` in every axis: larger
    (or non-finite) coordinates mean wrong units or a corrupt file, and would overflow later."""
    limit = untrusted.limits.MAX_GARMENT_MM
    if len(points) == 0:
        return
    with np.errstate(over="ignore", invalid="ignore"):
        span = np.ptp(points, axis=0)
    if not np.all(np.isfinite(points)) or not bool(np.all(span <= limit)):
        raise GarmentError(source, f"the {what} spans {float(np.max(span)):.3g} mm (or holds a "
                           f"non-finite number); a garment is at most {limit:g} mm across "
                           "(wrong --units?)")


def _check_not_degenerate(source: str | Path, uv: np.ndarray) -> None:
    """A pattern narrower than :data:`untrusted.limits.MIN_PATTERN_MM` is no garment: texture
    coordinates scaled far down (1e-9) would make every later size and ratio zero."""
    least = untrusted.limits.MIN_PATTERN_MM
    span = float(np.ptp(uv, axis=0).max()) if len(uv) else 0.0
    if not span >= least:
        raise GarmentError(source, f"the sewing pattern spans only {span:.3g} mm; a pattern "
                           f"is at least {least:g} mm across (texture coordinates scaled "
                           "wrong, or wrong --units?)")


def build_garment(
    uv: np.ndarray,
    faces: np.ndarray,
    point_of_vertex: np.ndarray,
    *,
    xyz: np.ndarray | None,
    source: str | Path,
    kind: str,
    units_in_file: str = "mm",
    scale_recovered: float | None = None,
    piece_names: list[str] | None = None,
    grainlines: dict | None = None,
    notches: dict | None = None,
    twins: np.ndarray | None = None,
    panel_frames: dict | None = None,
    edge_curves: dict | None = None,
) -> Garment:
    """Derive pieces, orientation, seam edges and seam lines from a welded pattern mesh.

    ``piece_names`` are given per connected component in order of first appearance in
    ``faces`` (importers emit pieces in order). Degenerate faces are dropped and unused
    vertices removed, each with a warning that says how many. ``twins`` (E,4) gives the seam
    edges explicitly (in input vertex numbering) when the importer knows them (stitches);
    otherwise they are inferred from shared 3D points. ``edge_curves`` (input numbering)
    are the pattern's own curves between boundary vertices (:attr:`Garment.edge_curves`).
    """
    uv = np.asarray(uv, dtype=float)
    faces = np.asarray(faces, dtype=np.int64)
    point_of_vertex = np.asarray(point_of_vertex, dtype=np.int64)
    if faces.size == 0:
        raise GarmentError(source, "no faces")
    _check_extent(source, uv, "sewing pattern")
    _check_not_degenerate(source, uv)
    if xyz is not None:
        _check_extent(source, np.asarray(xyz, dtype=float), "3D garment")
    faces, area = _without_degenerate_faces(source, uv, faces)
    # orientation before renumbering, so that the numbering below is that of the faces
    # as they will be written out
    _orient_counter_clockwise(len(uv), faces, area)
    uv, faces, xyz, point_of_vertex, remap = _renumbered(source, uv, faces, xyz,
                                                         point_of_vertex)
    n = len(uv)
    # pieces: connected components of the pattern mesh (labels follow vertex order, which
    # is the order in which pieces first appear in the faces)
    he = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    n_pieces, piece_of_vertex = connected_components(n, he)
    seam_edges, boundary_3d = _seam_edges(source, _manifold_boundary(source, he, n),
                                          point_of_vertex, piece_of_vertex, twins, remap)
    names = _piece_names(source, piece_names, n_pieces)
    panels_are_pieces = piece_names is not None and len(piece_names) == n_pieces
    seam_line_of_edge, seam_lines = _seam_lines(seam_edges, piece_of_vertex, n, names)
    return Garment(
        uv=uv,
        faces=faces,
        xyz=xyz,
        point_of_vertex=point_of_vertex,
        piece_of_vertex=piece_of_vertex.astype(np.int64),
        piece_names=names,
        seam_edges=seam_edges,
        seam_line_of_edge=seam_line_of_edge,
        seam_lines=seam_lines,
        boundary_3d_edges=boundary_3d,
        grainlines=dict(grainlines or {}),
        notches=dict(notches or {}),
        # per-panel facts are kept only when the panels are the pieces
        panel_frames=dict(panel_frames or {}) if panels_are_pieces else {},
        edge_curves=_renumbered_curves(edge_curves or {}, remap),
        units_in_file=units_in_file,
        scale_recovered=scale_recovered,
        source=str(source),
        kind=kind,
    )


def _renumbered_curves(curves: dict, remap: np.ndarray) -> dict:
    """Edge curves keyed by the renumbered vertices; those of dropped vertices go."""
    out = {}
    for (a, b), rel in curves.items():
        a2, b2 = int(remap[a]), int(remap[b])
        if a2 >= 0 and b2 >= 0:
            out[(a2, b2)] = rel
    return out


def _seam_edges(source: str | Path, bhe: np.ndarray, point_of_vertex: np.ndarray,
                piece_of_vertex: np.ndarray, twins: np.ndarray | None, remap: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """Seam edges (E,4) from the importer's ``twins`` (input numbering) or inferred from
    shared 3D points, in a stable, readable order (by piece, then by vertex), and the
    boundary edges of the 3D garment."""
    if twins is None:
        seam_edges, boundary_3d = _infer_twins(bhe, point_of_vertex, piece_of_vertex, source)
    else:
        seam_edges, boundary_3d = _explicit_twins(bhe, remap[np.asarray(twins)], source)
    so = np.lexsort((seam_edges[:, 0], piece_of_vertex[seam_edges[:, 0]]))
    return seam_edges[so], boundary_3d


def _piece_names(source: str | Path, piece_names: list[str] | None, n_pieces: int
                 ) -> list[str]:
    """The importer's names when there is one per piece, else generic ones (with a
    warning when names were given)."""
    names = list(piece_names) if piece_names is not None else []
    if len(names) != n_pieces:
        if piece_names is not None:
            warnings.warn(
                f"{source}: {len(names)} pieces named but the pattern has {n_pieces} "
                "connected pieces; using generic names",
                stacklevel=4,
            )
        names = [f"piece{i}" for i in range(n_pieces)]
    return names


def _without_degenerate_faces(source: str | Path, uv: np.ndarray, faces: np.ndarray
                              ) -> tuple[np.ndarray, np.ndarray]:
    """Faces without slivers (a repeated corner or numerically zero pattern area), with
    a warning that says how many, and their (F,) signed areas."""
    area = signed_areas(uv, faces)
    scale2 = float(np.ptp(uv, axis=0).max()) ** 2 if len(uv) else 0.0
    repeated = (
        (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 0] == faces[:, 2])
    )
    degenerate = repeated | (np.abs(area) <= 1e-14 * max(scale2, 1e-300))
    if degenerate.any():
        warnings.warn(
            f"{source}: removed {int(degenerate.sum())} degenerate (zero-area) faces",
            stacklevel=4,
        )
        faces, area = faces[~degenerate], area[~degenerate]
        if faces.size == 0:
            raise GarmentError(source, "all faces are degenerate")
    return faces, area


def _orient_counter_clockwise(n: int, faces: np.ndarray, area: np.ndarray) -> None:
    """Turn (in place) the faces of every piece whose pattern area is negative."""
    _, comp = connected_components(n, faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2))
    comp_of_face = comp[faces[:, 0]]
    comp_area = np.bincount(comp_of_face, weights=area, minlength=int(comp.max()) + 1)
    flip = comp_area[comp_of_face] < 0
    if flip.any():
        faces[flip] = faces[flip][:, [0, 2, 1]]


def _renumbered(source: str | Path, uv: np.ndarray, faces: np.ndarray,
                xyz: np.ndarray | None, point_of_vertex: np.ndarray) -> tuple:
    """Vertices renumbered by first appearance in the faces, so that exports re-import in
    the same order (unused ones dropped, with a warning), 3D point ids compacted the
    same way: ``(uv, faces, xyz, point_of_vertex, remap)``, ``remap`` old -> new id."""
    n = len(uv)
    used, first = np.unique(faces.ravel(), return_index=True)
    order = used[np.argsort(first, kind="stable")]
    if len(order) < n:
        warnings.warn(f"{source}: removed {n - len(order)} unused vertices", stacklevel=4)
    remap = np.full(n, -1, dtype=np.int64)
    remap[order] = np.arange(len(order))
    xyz = None if xyz is None else np.asarray(xyz, dtype=float)[order]
    pts = point_of_vertex[order]
    _, pfirst, pinv = np.unique(pts, return_index=True, return_inverse=True)
    prank = np.empty(len(pfirst), dtype=np.int64)
    prank[np.argsort(pfirst, kind="stable")] = np.arange(len(pfirst))
    return uv[order], remap[faces], xyz, prank[pinv.ravel()], remap


def _manifold_boundary(source: str | Path, he: np.ndarray, n: int) -> np.ndarray:
    """The boundary half-edges of ``he``; a pattern edge used by more than two faces
    makes no sense in a sewing pattern and is an error."""
    _, inv, counts = np.unique(edge_keys(he[:, 0], he[:, 1], n), return_inverse=True,
                               return_counts=True)
    if counts.max() > 2:
        bad = he[np.argmax(counts[inv])]
        raise GarmentError(
            source,
            f"pattern edge {int(bad[0]) + 1}-{int(bad[1]) + 1} is used by "
            f"{int(counts.max())} faces (non-manifold pattern)",
        )
    return he[counts[inv] == 1]


def _seam_lines(
    seam_edges: np.ndarray, piece_of_vertex: np.ndarray, n: int, names: list[str]
) -> tuple[np.ndarray, list[SeamLine]]:
    """Group twin pairs into seam lines: same two pieces, connected along the boundary."""
    e = len(seam_edges)
    if e == 0:
        return np.zeros(0, dtype=np.int64), []
    pa = piece_of_vertex[seam_edges[:, 0]]
    pb = piece_of_vertex[seam_edges[:, 2]]
    lo, hi = np.minimum(pa, pb), np.maximum(pa, pb)
    pair_key = lo * (int(piece_of_vertex.max()) + 1) + hi
    # seam edge <-> pattern vertex incidence; edges sharing a vertex and a piece pair connect
    rows = np.repeat(np.arange(e), 4)
    inc = coo_matrix((np.ones(4 * e, dtype=np.int32), (rows, seam_edges.ravel())), shape=(e, n))
    inc = inc.tocsr()
    inc.data[:] = 1
    adj = (inc @ inc.T).tocoo()
    keep = pair_key[adj.row] == pair_key[adj.col]
    _, label = connected_components(e, np.column_stack([adj.row[keep], adj.col[keep]]))
    # number seam lines by their first seam edge
    _, first, inv = np.unique(label, return_index=True, return_inverse=True)
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    line_of_edge = rank[inv.ravel()]
    firsts = np.sort(first)
    pairs = [(int(lo[f]), int(hi[f])) for f in firsts.tolist()]
    total = {p: pairs.count(p) for p in set(pairs)}
    seen: dict[tuple[int, int], int] = {}
    lines: list[SeamLine] = []
    for a, b in pairs:
        k = seen.get((a, b), 0)
        seen[(a, b)] = k + 1
        suffix = f"#{k + 1}" if total[(a, b)] > 1 else ""
        lines.append(SeamLine(a, b, 1.0, f"{names[a]}~{names[b]}{suffix}"))
    return line_of_edge, lines


def _infer_twins(
    bhe: np.ndarray, point_of_vertex: np.ndarray, piece_of_vertex: np.ndarray, source: str | Path
) -> tuple[np.ndarray, int]:
    """Seam edges = 3D edges used by exactly two pattern boundary edges (vectorised)."""
    # seam edges: one 3D edge used by two pattern boundary edges
    pa, pb = point_of_vertex[bhe[:, 0]], point_of_vertex[bhe[:, 1]]
    collapsed = pa == pb
    if collapsed.any():
        warnings.warn(
            f"{source}: ignored {int(collapsed.sum())} boundary edges whose two ends are "
            "sewn to the same point",
            stacklevel=4,
        )
        bhe, pa, pb = bhe[~collapsed], pa[~collapsed], pb[~collapsed]
    n_points = int(point_of_vertex.max()) + 1
    key3 = edge_keys(pa, pb, n_points)
    # sort by 3D key, then piece, then vertex so the first twin is deterministic
    order = np.lexsort((bhe[:, 0], piece_of_vertex[bhe[:, 0]], key3))
    bhe, key3 = bhe[order], key3[order]
    uniq, start, counts3 = np.unique(key3, return_index=True, return_counts=True)
    if counts3.size and counts3.max() > 2:
        k = int(np.argmax(counts3))
        users = bhe[start[k] : start[k] + counts3[k]]
        pieces = sorted({int(p) for p in piece_of_vertex[users[:, 0]]})
        raise GarmentError(
            source,
            f"3D edge between points {int(uniq[k] // n_points) + 1} and "
            f"{int(uniq[k] % n_points) + 1} is used by {int(counts3[k])} pattern edges "
            f"(pieces {', '.join(map(str, pieces))}): an edge can join only two pieces",
        )
    twin = start[counts3 == 2]
    first_e, second_e = bhe[twin], bhe[twin + 1]
    same = point_of_vertex[second_e[:, 0]] == point_of_vertex[first_e[:, 0]]
    a2 = np.where(same, second_e[:, 0], second_e[:, 1])
    b2 = np.where(same, second_e[:, 1], second_e[:, 0])
    seam_edges = np.column_stack([first_e, a2, b2]).astype(np.int64)
    boundary_3d = int((counts3 == 1).sum())
    return seam_edges, boundary_3d


def _explicit_twins(
    bhe: np.ndarray, twins: np.ndarray, source: str | Path
) -> tuple[np.ndarray, int]:
    """Twin pairs given by the importer (stitches), oriented like their first edge's face."""
    if twins.size == 0:
        return np.zeros((0, 4), dtype=np.int64), len(bhe)
    if (twins < 0).any():
        raise GarmentError(source, "a seam edge uses a vertex that is in no face")
    n = int(max(bhe.max(initial=0), twins.max())) + 1
    fwd = bhe[:, 0].astype(np.int64) * n + bhe[:, 1]
    rev = bhe[:, 1].astype(np.int64) * n + bhe[:, 0]
    k1 = twins[:, 0] * n + twins[:, 1]
    k2 = twins[:, 2] * n + twins[:, 3]
    ok1_f, ok1_r = np.isin(k1, fwd), np.isin(k1, rev)
    ok2 = np.isin(k2, fwd) | np.isin(k2, rev)
    if not ((ok1_f | ok1_r) & ok2).all():
        raise GarmentError(source, "a stitched edge is not on a panel boundary")
    out = np.where(ok1_f[:, None], twins, twins[:, [1, 0, 3, 2]]).astype(np.int64)
    used = np.unique(np.concatenate([edge_keys(out[:, 0], out[:, 1], n),
                                     edge_keys(out[:, 2], out[:, 3], n)]))
    if len(used) < 2 * len(out):
        raise GarmentError(source, "a pattern edge is sewn more than once")
    return out, len(bhe) - 2 * len(out)
