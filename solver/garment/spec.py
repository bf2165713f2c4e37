"""Sewing-pattern JSON specifications (GarmentCode and the older Garment-Pattern-Generator).

A specification gives panels as closed loops of straight, quadratic, cubic and circular-arc
edges plus stitches that sew one whole edge to another. To make it a :class:`Garment` each
panel's loop is sampled at the chosen resolution, with the two edges of a stitch sampled at
the same count so that their boundary segments pair one to one, then triangulated with
Shewchuk's Triangle (quality mesh, no Steiner points on the boundary, so the seam samples
stay exactly as chosen). Twin samples share a 3D point id, and the common topology pass in
:func:`solver.garment.model.build_garment` turns them into seam edges and seam lines.

Edge geometry (pygarment conventions): Bezier control points are relative to the edge,
``p = start + x*e + y*perp(e)`` with ``e = end - start`` and ``perp(e) = (-e_y, e_x)``;
circle params ``[radius, large_arc, right]`` describe an SVG arc whose sweep flag is
``right``. Stitch orientation: by default edge 1's end meets edge 2's start (right side to
right side); ``"right_wrong"`` sews them in the same direction.

Panels written by :func:`solver.garment.spec_save.save_spec` also carry their triangle
mesh (``"mesh"``: interior points and triangles over the panel's vertices). Such a panel
is read as written, one boundary segment per straight edge, instead of being re-sampled
and re-triangulated: a reshaped pattern's outline is a polyline whose segments need not
fit the sampling resolution, and it may even cross itself, which no triangulation of the
outline can reproduce; the mesh makes the JSON round trip exact, like the OBJ one.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import triangle
from scipy.spatial.transform import Rotation

from solver.garment.curves import CHORD_TOL_MM, Curve, adaptive_parameters, edge_curve, to_chord
from solver.garment.errors import GarmentError
from solver.garment.mesh import connected_components
from solver.garment.model import Garment, build_garment
from solver.garment.spec_checks import (
    check_simple,
    check_size,
    panel_geometry,
    panel_marks,
    panel_mesh,
    read_spec_json,
    read_stitches,
)
from solver.geometry import resample_polyline
from solver.units import mm_per_unit, units_from_meter_fraction

DEFAULT_RESOLUTION_MM = 20.0
#: gap left between panels when they are laid out side by side in the pattern plane
PANEL_GAP_MM = 100.0
_DENSE_T = np.linspace(0.0, 1.0, 257)  # parameters to measure and resample a curved edge


# ---------------------------------------------------------------------- edge geometry


def _length(poly: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(poly, axis=0), axis=1).sum())


# ---------------------------------------------------------------------- import


@dataclass
class _Panels:
    """Every panel sampled, triangulated and laid out: the mesh and where each edge's
    samples start (global vertex ids), with the marks the panels carry."""

    uv: np.ndarray
    faces: np.ndarray
    edge_start: list[list[int]]
    offsets_v: list[tuple[int, int]]  # per panel (first vertex, outline length)
    grainlines: dict[int, tuple[tuple[float, float], tuple[float, float]]]
    notches: dict[int, list[tuple[float, float]]]
    frames: dict[int, np.ndarray]


def load_spec(
    path: str | Path, *, units: str | None = None, resolution_mm: float | None = None
) -> Garment:
    """Triangulate a GarmentCode / Garment-Pattern-Generator specification (2D only)."""
    path = Path(path)
    data = read_spec_json(path)
    pattern = data["pattern"]
    panels = pattern.get("panels")
    if not isinstance(panels, dict) or not panels:
        raise GarmentError(path, "pattern has no panels")
    props = data.get("properties") or {}
    unit, k = _file_units(path, props, units)
    if props.get("curvature_coords", "relative") != "relative":
        raise GarmentError(path, "only relative curvature coordinates are supported")
    res = DEFAULT_RESOLUTION_MM if resolution_mm is None else float(resolution_mm)
    if not res > 0:
        raise ValueError(f"resolution_mm must be > 0, got {resolution_mm}")

    order = [n for n in pattern.get("panel_order", []) if n in panels]
    order += [n for n in panels if n not in order]
    dense, curves, meshes = _dense_edges(path, panels, order, k, res)
    # curves may bulge far beyond their vertices: size the sampled outlines, not the corners
    check_size(path, [np.concatenate(polys) for polys in dense], res)
    counts = [
        [1 if meshes[i] is not None else max(1, math.ceil(_length(p) / res)) for p in polys]
        for i, polys in enumerate(dense)
    ]
    index = {n: i for i, n in enumerate(order)}
    stitches = read_stitches(path, pattern.get("stitches", []), index, dense)
    _match_stitch_counts(path, order, stitches, meshes, counts)
    laid = _lay_out(path, panels, order, dense, meshes, counts, k, res,
                    absolute=props.get("pattern_layout") == "absolute")
    point, twins = _stitch_points(laid, stitches, counts)
    fine = _edge_curves(laid, dense, curves, counts)
    return build_garment(
        laid.uv,
        laid.faces,
        point,
        xyz=None,
        source=path,
        kind="spec",
        units_in_file=unit,
        piece_names=list(order),
        grainlines=laid.grainlines,
        notches=laid.notches,
        twins=twins,
        panel_frames=laid.frames,
        edge_curves=fine,
    )


def _file_units(path: Path, props: dict, units: str | None) -> tuple[str, float]:
    """The file's unit name and mm per unit: ``units`` if given, else the file's
    ``units_in_meter``, else mm."""
    if units is not None:
        return units, mm_per_unit(units)
    uim = props.get("units_in_meter")
    if uim is None:
        return "mm", 1.0
    try:
        named, k = units_from_meter_fraction(float(uim))
    except (TypeError, ValueError, ZeroDivisionError):
        raise GarmentError(path, f"bad units_in_meter {uim!r}") from None
    if not (np.isfinite(k) and k > 0):
        raise GarmentError(path, f"bad units_in_meter {uim!r}: must be > 0")
    return named or f"1/{uim} m", k


def _dense_edges(path: Path, panels: dict, order: list[str], k: float, res: float
                 ) -> tuple[list[list[np.ndarray]], list[list[Curve | None]],
                            list[tuple[np.ndarray, np.ndarray] | None]]:
    """Per panel the dense polyline and the curve (None: straight) of every edge in mm,
    and the panel's own mesh if any."""
    dense: list[list[np.ndarray]] = []
    curves: list[list[Curve | None]] = []
    meshes: list[tuple[np.ndarray, np.ndarray] | None] = []
    for name in order:
        verts, edges = panel_geometry(path, name, panels[name])
        meshes.append(panel_mesh(path, name, panels[name], verts, edges))
        verts = verts * k
        check_size(path, [verts], res)
        polys, fns = [], []
        for ei, e in enumerate(edges):
            i, j = (int(x) for x in e["endpoints"])
            try:
                fn = edge_curve(verts[i], verts[j], e.get("curvature"), where=f"{name}/{ei}")
            except ValueError as exc:
                raise GarmentError(path, f"panel {exc}") from None
            fns.append(fn)
            polys.append(np.array([verts[i], verts[j]]) if fn is None else fn(_DENSE_T))
        dense.append(polys)
        curves.append(fns)
    return dense, curves, meshes


def _edge_curves(laid: _Panels, dense: list, curves: list, counts: list[list[int]],
                 tol_mm: float = CHORD_TOL_MM / 2) -> dict[tuple[int, int], np.ndarray]:
    """Each curved edge's samples between its mesh vertices, in chord coordinates
    (:attr:`Garment.edge_curves`): the mesh vertices sit at equal arc length along the
    dense polyline, so their curve parameters are read off it, and the curve is sampled
    adaptively between them to ``tol_mm``. A panel read with its own mesh has none.

    Half the cut line's tolerance: offsetting a polyline by the allowance ``a`` adds up to
    ``a th^2 / 8`` at each joint (th the turn there), which the other half absorbs."""
    out: dict[tuple[int, int], np.ndarray] = {}
    for p, fns in enumerate(curves):
        for e, fn in enumerate(fns):
            n = counts[p][e]
            poly = dense[p][e]
            if fn is None or _length(poly) == 0 or len(laid.edge_start[p]) != len(fns):
                continue
            s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poly, axis=0).T))])
            t_mesh = np.interp(np.linspace(0.0, s[-1], n + 1), s, _DENSE_T)
            t = adaptive_parameters(fn, t_mesh, tol_mm)
            ends = resample_polyline(poly, n)  # the mesh vertices, as the loop has them
            seg = np.searchsorted(t_mesh, t, side="right") - 1
            ids = _edge_vertices(laid.edge_start, laid.offsets_v, p, e, n)
            inside = ~np.isin(t, t_mesh)
            groups = np.split(fn(t[inside]), np.searchsorted(seg[inside], np.arange(1, n)))
            for j, pts in enumerate(groups):
                out[(int(ids[j]), int(ids[j + 1]))] = to_chord(ends[j], ends[j + 1], pts)
    return out


def _match_stitch_counts(path: Path, order: list[str], stitches: list, meshes: list,
                         counts: list[list[int]]) -> None:
    """Give both edges of every stitch the same sample count (in place); a meshed
    panel's edges are one segment each, and so are the edges sewn to them. An edge
    sewn twice is an error."""
    used: dict[tuple[int, int], int] = {}
    for s, (pa, ea, pb, eb, _) in enumerate(stitches):
        for key in ((pa, ea), (pb, eb)):
            if key in used:
                raise GarmentError(
                    path,
                    f"edge {key[1]} of panel {order[key[0]]!r} is in stitches {used[key]} "
                    f"and {s}: an edge can be sewn only once",
                )
            used[key] = s
        fixed = meshes[pa] is not None or meshes[pb] is not None
        n = 1 if fixed else max(counts[pa][ea], counts[pb][eb])
        counts[pa][ea] = counts[pb][eb] = n


def _sampled_loop(polys: list[np.ndarray], counts: list[int]) -> tuple[np.ndarray, list[int], int]:
    """One panel's outline sampled edge by edge: the (n,2) loop, the index where each
    edge's samples start, and how many edges have zero length."""
    pts, starts, zero = [], [], 0
    for e, poly in enumerate(polys):
        starts.append(len(pts))
        pts.extend(resample_polyline(poly, counts[e])[:-1])
        if _length(poly) == 0:
            zero += 1
    return np.array(pts), starts, zero


def _lay_out(path: Path, panels: dict, order: list[str], dense: list, meshes: list,
             counts: list[list[int]], k: float, res: float, *, absolute: bool) -> _Panels:
    """Sample each panel loop, triangulate it (or take its own mesh), and lay the panels
    out side by side where their frames overlap, as BoxMesh does."""
    out = _Panels([], [], [], [], {}, {}, {})
    base, zero_edges = 0, 0
    boxes: list[np.ndarray] = []
    for p, polys in enumerate(dense):
        loop, starts, zero = _sampled_loop(polys, counts[p])
        zero_edges += zero
        if meshes[p] is None:
            loop, keep_map = _drop_duplicates(loop)
            starts = [int(keep_map[s]) for s in starts]
            tri = _triangulate(path, order[p], loop, res)
        else:  # the panel's own mesh: its vertices are the loop, then the interior points
            interior, triangles = meshes[p]
            tri = {"vertices": np.concatenate([loop, interior * k]), "triangles": triangles}
        verts = tri["vertices"]
        box = np.concatenate([verts.min(axis=0), verts.max(axis=0)])
        shift = 0.0
        if not absolute and any(_overlap(box, b) for b in boxes):
            shift = max(b[2] for b in boxes) + PANEL_GAP_MM - box[0]
            verts = verts + np.array([shift, 0.0])
            box = box + np.array([shift, 0.0, shift, 0.0])
        boxes.append(box)
        _add_marks(out, path, p, order[p], panels[order[p]], k, shift)
        out.uv.append(verts)
        out.faces.append(tri["triangles"] + base)
        out.offsets_v.append((base, len(loop)))
        out.edge_start.append([base + s for s in starts])
        base += len(verts)
    if zero_edges:
        warnings.warn(f"{path}: ignored {zero_edges} zero-length edges", stacklevel=3)
    out.uv, out.faces = np.concatenate(out.uv), np.concatenate(out.faces)
    return out


def _add_marks(out: _Panels, path: Path, p: int, name: str, panel: dict, k: float,
               shift: float) -> None:
    """Panel p's placement around the body, grain line and notches, shifted with it."""
    frame = _panel_frame(panel, k, shift)
    if frame is not None:
        out.frames[p] = frame
    grain, notches = panel_marks(path, name, panel, k, np.array([shift, 0.0]))
    if grain is not None:
        out.grainlines[p] = grain
    if notches:
        out.notches[p] = notches


def _stitch_points(laid: _Panels, stitches: list, counts: list[list[int]]
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Twin samples share a 3D point id (connected components of the stitched pairs),
    and each pair of consecutive twin samples is one seam edge: (V,) point ids, (E,4)."""
    pairs, twins = [], []
    for pa, ea, pb, eb, right_wrong in stitches:
        ia = _edge_vertices(laid.edge_start, laid.offsets_v, pa, ea, counts[pa][ea])
        ib = _edge_vertices(laid.edge_start, laid.offsets_v, pb, eb, counts[pb][eb])
        ib = ib if right_wrong else ib[::-1]
        pairs.append(np.column_stack([ia, ib]))
        twins.append(np.column_stack([ia[:-1], ia[1:], ib[:-1], ib[1:]]))
    all_pairs = np.concatenate(pairs) if pairs else np.zeros((0, 2), dtype=np.int64)
    _, point = connected_components(len(laid.uv), all_pairs)
    all_twins = np.concatenate(twins) if twins else np.zeros((0, 4), dtype=np.int64)
    return point, all_twins


def _panel_frame(panel: dict, k: float, shift: float) -> np.ndarray | None:
    """Where the specification places a panel around the body: ``F`` (3,3) with world =
    ``F @ (u, v, 1)`` mm for the pattern point (u, v) (``rotation``: intrinsic XYZ Euler
    degrees, as GarmentCode builds it; ``translation`` in file units). None when the panel
    is not placed (all zero is what `solver.garment.spec_save.save_spec` writes)."""
    rot, trans = panel.get("rotation"), panel.get("translation")
    try:
        rot = np.asarray(rot, float).reshape(3)
        trans = np.asarray(trans, float).reshape(3)
    except (TypeError, ValueError):
        return None
    if not (np.isfinite(rot).all() and np.isfinite(trans).all()) or not (
            rot.any() or trans.any()):
        return None
    r = Rotation.from_euler("XYZ", rot, degrees=True).as_matrix()
    return np.column_stack([r[:, 0], r[:, 1], trans * k - r[:, 0] * shift])


def _overlap(a: np.ndarray, b: np.ndarray) -> bool:
    """Do two [xmin, ymin, xmax, ymax] boxes overlap (or nearly touch)?"""
    m = PANEL_GAP_MM / 10  # panels that merely touch also count: keep a visible gap
    return bool(a[0] < b[2] + m and b[0] < a[2] + m and a[1] < b[3] + m and b[1] < a[3] + m)


def _edge_vertices(
    edge_start: list[list[int]], offsets_v: list[tuple[int, int]], p: int, e: int, n: int
) -> np.ndarray:
    """Global vertex ids of the n+1 samples of edge e of panel p, start to end."""
    base, loop_len = offsets_v[p]
    first = edge_start[p][e] - base
    return base + (first + np.arange(n + 1)) % loop_len


def _drop_duplicates(loop: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Remove consecutive coincident samples (zero-length edges); map old -> new index."""
    nxt = np.roll(loop, -1, axis=0)
    dup = np.all(np.abs(loop - nxt) <= 1e-9, axis=1)
    keep = ~dup
    new_index = np.cumsum(keep) - 1
    # a dropped sample maps to the next kept one (it coincides with it)
    mapping = np.where(keep, new_index, (new_index + 1) % max(int(keep.sum()), 1))
    return loop[keep], mapping


def _triangulate(path: Path, name: str, loop: np.ndarray, res: float) -> dict:
    """Quality triangulation of one closed loop with Triangle; boundary kept as sampled."""
    check_simple(path, name, loop)
    n = len(loop)
    segs = np.column_stack([np.arange(n), (np.arange(n) + 1) % n])
    max_area = math.sqrt(3) / 4 * res * res
    try:
        out = triangle.triangulate({"vertices": loop, "segments": segs}, f"pq28Ya{max_area:.6f}")
    except Exception as exc:  # Triangle reports failures as generic errors
        raise GarmentError(path, f"panel {name!r} cannot be triangulated ({exc})") from None
    if "triangles" not in out or len(out["triangles"]) == 0:
        raise GarmentError(path, f"panel {name!r} cannot be triangulated (no triangles)")
    if len(out["vertices"]) < n or not np.allclose(out["vertices"][:n], loop):
        raise GarmentError(path, f"panel {name!r}: triangulation changed its outline")
    return out


