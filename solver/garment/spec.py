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

Panels written by :func:`save_spec` also carry their triangle mesh (``"mesh"``: interior
points and triangles over the panel's vertices). Such a panel is read as written, one
boundary segment per straight edge, instead of being re-sampled and re-triangulated: a
reshaped pattern's outline is a polyline whose segments need not fit the sampling
resolution, and it may even cross itself, which no triangulation of the outline can
reproduce; the mesh makes the JSON round trip exact, like the OBJ one.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import shapely
import triangle
from scipy.spatial.transform import Rotation

import untrusted
from solver.garment.errors import GarmentError
from solver.garment.mesh import boundary_half_edges, connected_components
from solver.garment.model import Garment, build_garment
from solver.geometry import polygon_area, resample_polyline
from solver.units import mm_per_unit, units_from_meter_fraction

DEFAULT_RESOLUTION_MM = 20.0
#: gap left between panels when they are laid out side by side in the pattern plane
PANEL_GAP_MM = 100.0
_DENSE = 257  # samples used to measure and resample one curved edge


# ---------------------------------------------------------------------- edge geometry


def _rel_to_abs(start: np.ndarray, end: np.ndarray, rel: Any) -> np.ndarray:
    e = end - start
    perp = np.array([-e[1], e[0]])
    rel = np.asarray(rel, dtype=float)
    return start + rel[0] * e + rel[1] * perp


def _bezier(ctrl: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Points of a Bezier curve with control polygon ``ctrl`` (k,2) at parameters t."""
    n = len(ctrl) - 1
    coef = np.array([math.comb(n, i) for i in range(n + 1)], dtype=float)
    i = np.arange(n + 1)
    basis = coef * t[:, None] ** i * (1 - t[:, None]) ** (n - i)
    return basis @ ctrl


def _arc(start: np.ndarray, end: np.ndarray, params: Any, t: np.ndarray) -> np.ndarray:
    """SVG-style circular arc from start to end (radius, large_arc, sweep=right)."""
    radius, large_arc, right = float(params[0]), bool(params[1]), bool(params[2])
    chord = end - start
    d = float(np.hypot(*chord))
    if d == 0:
        return np.repeat(start[None], len(t), axis=0)
    r = max(abs(radius), d / 2)  # SVG scales a too-small radius up to fit
    h = math.sqrt(max(r * r - d * d / 4, 0.0))
    left = np.array([-chord[1], chord[0]]) / d
    side = 1.0 if large_arc != right else -1.0
    centre = (start + end) / 2 + side * h * left
    a0 = math.atan2(*(start - centre)[::-1])
    a1 = math.atan2(*(end - centre)[::-1])
    if right:  # sweep flag: angle increases
        while a1 <= a0:
            a1 += 2 * math.pi
    else:
        while a1 >= a0:
            a1 -= 2 * math.pi
    ang = a0 + (a1 - a0) * t
    return centre + r * np.column_stack([np.cos(ang), np.sin(ang)])


def edge_polyline(
    start: np.ndarray, end: np.ndarray, curvature: Any, *, where: str = ""
) -> np.ndarray:
    """Dense polyline (m,2) of one specification edge, start and end included."""
    if curvature is None:
        return np.array([start, end], dtype=float)
    t = np.linspace(0.0, 1.0, _DENSE)
    if isinstance(curvature, list):  # Garment-Pattern-Generator: one quadratic control point
        ctrl = np.array([start, _rel_to_abs(start, end, curvature), end])
        return _bezier(ctrl, t)
    if not isinstance(curvature, dict):
        raise ValueError(f"{where}: curvature must be a list or an object")
    kind = curvature.get("type")
    params = curvature.get("params")
    if kind in ("quadratic", "cubic"):
        need = 1 if kind == "quadratic" else 2
        if not isinstance(params, list) or len(params) != need:
            raise ValueError(f"{where}: {kind} curvature needs {need} control point(s)")
        ctrl = np.array([start, *(_rel_to_abs(start, end, p) for p in params), end])
        return _bezier(ctrl, t)
    if kind == "circle":
        if not isinstance(params, list) or len(params) != 3:
            raise ValueError(f"{where}: circle curvature needs [radius, large_arc, right]")
        return _arc(start, end, params, t)
    raise ValueError(f"{where}: unknown curvature type {kind!r}")


def _length(poly: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(poly, axis=0), axis=1).sum())


# ---------------------------------------------------------------------- import


def _read_json(path: Path) -> dict:
    try:
        data = untrusted.read_json(path, what="pattern specification")
    except untrusted.MissingInput:
        raise
    except untrusted.InputError as exc:
        raise GarmentError(path, exc.fault) from None
    if not isinstance(data, dict) or not isinstance(data.get("pattern"), dict):
        raise GarmentError(path, "no 'pattern' object: not a sewing-pattern specification")
    try:
        _check_structure(path, data)
    except untrusted.InputError as exc:
        raise GarmentError(path, exc.fault) from None
    return data


def _check_structure(path: Path, data: dict) -> None:
    """Types and sizes of everything the importer reads, before any geometry is built."""
    lim = untrusted.limits
    pattern = data["pattern"]
    if data.get("properties") is not None:
        untrusted.mapping(data["properties"], path, "properties")
    panels = pattern.get("panels")
    if isinstance(panels, dict):
        untrusted.count(panels, path, "pattern.panels", limit=lim.MAX_PIECES)
        for name, panel in panels.items():
            where = f"panel {name!r}"
            panel = untrusted.mapping(panel, path, where)
            untrusted.points(panel.get("vertices"), path, f"{where} vertices", min_len=3,
                             max_abs=math.inf)
            edges = untrusted.sequence(panel.get("edges"), path, f"{where} edges", min_len=2,
                                       max_len=lim.MAX_PANEL_POINTS)
            for k, e in enumerate(edges):
                e = untrusted.mapping(e, path, f"{where} edge {k}")
                ends = untrusted.sequence(e.get("endpoints"), path, f"{where} edge {k} "
                                          "endpoints", min_len=2, max_len=2)
                for v in ends:
                    untrusted.integer(v, path, f"{where} edge {k} endpoint", lo=0,
                                      hi=lim.MAX_PANEL_POINTS)
                curvature = e.get("curvature")
                if isinstance(curvature, list):
                    untrusted.vector(curvature, path, f"{where} edge {k} curvature",
                                     max_abs=1e6)
                elif isinstance(curvature, dict):
                    params = curvature.get("params")
                    if not isinstance(params, list) or len(params) > 3 or not all(
                            isinstance(x, (int, float, list)) for x in params):
                        raise untrusted.InputError(path, f"{where} edge {k} curvature params "
                                                   "must be a short list of numbers or points")
                    for x in params:
                        if isinstance(x, list):
                            untrusted.vector(x, path, f"{where} edge {k} curvature", max_abs=1e6)
                        else:
                            untrusted.number(x, path, f"{where} edge {k} curvature", lo=-1e9,
                                             hi=1e9)
    order = pattern.get("panel_order", [])
    if not isinstance(order, list) or not all(isinstance(n, str) for n in order):
        raise untrusted.InputError(path, "pattern.panel_order must be a list of panel names")
    stitches = untrusted.sequence(pattern.get("stitches", []), path, "pattern.stitches",
                                  max_len=lim.MAX_PANEL_POINTS)
    for s, st in enumerate(stitches):
        sides = st if isinstance(st, list) else []
        for side in sides[:2]:
            if isinstance(side, dict) and not isinstance(side.get("panel"), str):
                raise untrusted.InputError(path, f"stitch {s} panel must be a panel name")


def _check_size(path: Path, verts_mm: list[np.ndarray], res: float) -> None:
    """Err before meshing if the pattern is wider than a garment can be or its mesh would
    exceed the face limit (about 2.3 faces per res x res square of panel area)."""
    lim = untrusted.limits
    for v in verts_mm:
        span = float(np.ptp(v, axis=0).max())
        if not span <= lim.MAX_GARMENT_MM:
            raise GarmentError(path, f"a panel spans {span:.3g} mm; a garment is at most "
                               f"{lim.MAX_GARMENT_MM:g} mm across (wrong units_in_meter?)")
    area = sum(abs(polygon_area(v)) for v in verts_mm)
    faces = 2.3 * area / res**2
    if faces > lim.MAX_FACES:
        raise GarmentError(path, f"meshing at {res:g} mm would make about {faces:.3g} faces, "
                           f"beyond the limit of {lim.MAX_FACES:,}")


def _panel_geometry(path: Path, name: str, panel: Any) -> tuple[np.ndarray, list[dict]]:
    """Vertices (n,2) and edges of one panel, validated: finite, closed loop in order."""
    if not isinstance(panel, dict):
        raise GarmentError(path, f"panel {name!r} is not an object")
    try:
        verts = np.asarray(panel["vertices"], dtype=float)
        edges = list(panel["edges"])
    except (KeyError, TypeError, ValueError) as exc:
        raise GarmentError(path, f"panel {name!r} has no usable vertices/edges ({exc})") from None
    if verts.ndim != 2 or verts.shape[1] != 2 or len(verts) < 3 or len(edges) < 2:
        raise GarmentError(path, f"panel {name!r} needs >= 3 2D vertices and >= 2 edges")
    if not np.isfinite(verts).all():
        raise GarmentError(path, f"panel {name!r} has a non-finite vertex (NaN or inf)")
    ends = []
    for k, e in enumerate(edges):
        try:
            i, j = (int(x) for x in e["endpoints"])
        except (KeyError, TypeError, ValueError):
            raise GarmentError(path, f"panel {name!r} edge {k} has no endpoints") from None
        if not (0 <= i < len(verts) and 0 <= j < len(verts)):
            raise GarmentError(path, f"panel {name!r} edge {k} points at missing vertex ({i}, {j})")
        ends.append((i, j))
    for k in range(len(ends)):
        if ends[k][1] != ends[(k + 1) % len(ends)][0]:
            raise GarmentError(
                path, f"panel {name!r} edges {k} and {(k + 1) % len(ends)} do not form a loop"
            )
    return verts, edges


def _panel_mesh(
    path: Path, name: str, panel: dict, verts: np.ndarray, edges: list[dict]
) -> tuple[np.ndarray, np.ndarray] | None:
    """The panel's optional ``mesh`` {interior (m,2), triangles (t,3)}, validated.

    Triangle corners index the panel's vertices (0..n-1), then the interior points
    (n..n+m-1). The edges must be the straight loop 0->1->...->0 and every one of them a
    boundary edge of the mesh, so the outline read back is the one written.
    """
    raw = panel.get("mesh")
    if raw is None:
        return None
    n = len(verts)
    try:
        interior = np.asarray(raw["interior"], dtype=float).reshape(-1, 2)
        tri = np.asarray(raw["triangles"])
    except (KeyError, TypeError, ValueError) as exc:
        raise GarmentError(
            path, f"panel {name!r} mesh needs 'interior' 2D points and 'triangles' ({exc})"
        ) from None
    if not np.isfinite(interior).all():
        raise GarmentError(path, f"panel {name!r} mesh has a non-finite interior point")
    if tri.ndim != 2 or tri.shape[1] != 3 or len(tri) == 0 or tri.dtype.kind not in "iu":
        raise GarmentError(path, f"panel {name!r} mesh triangles are not rows of 3 integers")
    bad = tri[(tri < 0) | (tri >= n + len(interior))]
    if bad.size:
        raise GarmentError(
            path, f"panel {name!r} mesh triangle corner {int(bad[0])} is not a vertex "
            f"(it has {n} outline and {len(interior)} interior points)"
        )
    for k, e in enumerate(edges):
        if [int(x) for x in e["endpoints"]] != [k, (k + 1) % n] or e.get("curvature"):
            raise GarmentError(
                path, f"panel {name!r} has a mesh, so edge {k} must be the straight edge "
                f"[{k}, {(k + 1) % n}]"
            )
    tri = tri.astype(np.int64)
    total = n + len(interior)
    bhe = boundary_half_edges(tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), total)
    on_boundary = np.minimum(bhe[:, 0], bhe[:, 1]) * total + np.maximum(bhe[:, 0], bhe[:, 1])
    k = np.arange(n)
    loop_keys = np.minimum(k, (k + 1) % n) * total + np.maximum(k, (k + 1) % n)
    missing = np.flatnonzero(~np.isin(loop_keys, on_boundary))
    if missing.size:
        raise GarmentError(
            path, f"panel {name!r} edge {int(missing[0])} is not on the boundary of its mesh"
        )
    return interior, tri


def load_spec(
    path: str | Path, *, units: str | None = None, resolution_mm: float | None = None
) -> Garment:
    """Triangulate a GarmentCode / Garment-Pattern-Generator specification (2D only)."""
    path = Path(path)
    data = _read_json(path)
    pattern = data["pattern"]
    panels = pattern.get("panels")
    if not isinstance(panels, dict) or not panels:
        raise GarmentError(path, "pattern has no panels")
    props = data.get("properties") or {}
    if units is not None:
        unit, k = units, mm_per_unit(units)
    else:
        uim = props.get("units_in_meter")
        if uim is None:
            unit, k = "mm", 1.0
        else:
            try:
                named, k = units_from_meter_fraction(float(uim))
            except (TypeError, ValueError, ZeroDivisionError):
                raise GarmentError(path, f"bad units_in_meter {uim!r}") from None
            if not (np.isfinite(k) and k > 0):
                raise GarmentError(path, f"bad units_in_meter {uim!r}: must be > 0")
            unit = named or f"1/{uim} m"
    if props.get("curvature_coords", "relative") != "relative":
        raise GarmentError(path, "only relative curvature coordinates are supported")
    res = DEFAULT_RESOLUTION_MM if resolution_mm is None else float(resolution_mm)
    if not res > 0:
        raise ValueError(f"resolution_mm must be > 0, got {resolution_mm}")

    order = [n for n in pattern.get("panel_order", []) if n in panels]
    order += [n for n in panels if n not in order]
    index = {n: i for i, n in enumerate(order)}

    # dense geometry of every edge, in mm
    geom: list[tuple[np.ndarray, list[dict]]] = []
    dense: list[list[np.ndarray]] = []
    meshes: list[tuple[np.ndarray, np.ndarray] | None] = []
    for name in order:
        verts, edges = _panel_geometry(path, name, panels[name])
        meshes.append(_panel_mesh(path, name, panels[name], verts, edges))
        verts = verts * k
        _check_size(path, [verts], res)
        polys = []
        for ei, e in enumerate(edges):
            i, j = (int(x) for x in e["endpoints"])
            try:
                polys.append(
                    edge_polyline(verts[i], verts[j], e.get("curvature"), where=f"{name}/{ei}")
                )
            except ValueError as exc:
                raise GarmentError(path, f"panel {exc}") from None
        geom.append((verts, edges))
        dense.append(polys)

    # curves may bulge far beyond their vertices: size the sampled outlines, not the corners
    _check_size(path, [np.concatenate(polys) for polys in dense], res)

    # stitches: validate and give both edges the same sample count; a meshed panel's
    # edges are one segment each, and so are the edges sewn to them
    counts = [
        [1 if meshes[i] is not None else max(1, math.ceil(_length(p) / res)) for p in polys]
        for i, polys in enumerate(dense)
    ]
    stitches = _read_stitches(path, pattern.get("stitches", []), index, dense)
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

    # sample each panel loop, triangulate, lay panels out side by side
    uv_parts, face_parts, offsets_v = [], [], []
    edge_start: list[list[int]] = []
    base = 0
    grainlines: dict[int, tuple[tuple[float, float], tuple[float, float]]] = {}
    notches: dict[int, list[tuple[float, float]]] = {}
    boxes: list[np.ndarray] = []
    frames: dict[int, np.ndarray | None] = {}
    absolute = props.get("pattern_layout") == "absolute"
    zero_edges = 0
    for p, polys in enumerate(dense):
        pts, starts = [], []
        for e, poly in enumerate(polys):
            starts.append(len(pts))
            samples = resample_polyline(poly, counts[p][e])[:-1]
            pts.extend(samples)
            if _length(poly) == 0:
                zero_edges += 1
        loop = np.array(pts)
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
            # panels live in their own frames: lay them out left to right, as BoxMesh does
            shift = max(b[2] for b in boxes) + PANEL_GAP_MM - box[0]
            verts = verts + np.array([shift, 0.0])
            box = box + np.array([shift, 0.0, shift, 0.0])
        boxes.append(box)
        frames[p] = _panel_frame(panels[order[p]], k, shift)
        marks = _panel_marks(path, order[p], panels[order[p]], k, np.array([shift, 0.0]))
        if marks[0] is not None:
            grainlines[p] = marks[0]
        if marks[1]:
            notches[p] = marks[1]
        uv_parts.append(verts)
        face_parts.append(tri["triangles"] + base)
        offsets_v.append((base, len(loop)))
        edge_start.append([base + s for s in starts])
        base += len(verts)
    if zero_edges:
        warnings.warn(f"{path}: ignored {zero_edges} zero-length edges", stacklevel=2)
    uv = np.concatenate(uv_parts)
    faces = np.concatenate(face_parts)

    # twin samples share a 3D point id: union them with connected components
    # and each pair of consecutive twin samples is one seam edge
    pairs, twins = [], []
    for pa, ea, pb, eb, right_wrong in stitches:
        ia = _edge_vertices(edge_start, offsets_v, pa, ea, counts[pa][ea])
        ib = _edge_vertices(edge_start, offsets_v, pb, eb, counts[pb][eb])
        ib = ib if right_wrong else ib[::-1]
        pairs.append(np.column_stack([ia, ib]))
        twins.append(np.column_stack([ia[:-1], ia[1:], ib[:-1], ib[1:]]))
    all_pairs = np.concatenate(pairs) if pairs else np.zeros((0, 2), dtype=np.int64)
    _, point = connected_components(len(uv), all_pairs)
    all_twins = np.concatenate(twins) if twins else np.zeros((0, 4), dtype=np.int64)
    return build_garment(
        uv,
        faces,
        point,
        xyz=None,
        source=path,
        kind="spec",
        units_in_file=unit,
        piece_names=list(order),
        grainlines=grainlines,
        notches=notches,
        twins=all_twins,
        panel_frames={p: f for p, f in frames.items() if f is not None},
    )


def _panel_frame(panel: dict, k: float, shift: float) -> np.ndarray | None:
    """Where the specification places a panel around the body: ``F`` (3,3) with world =
    ``F @ (u, v, 1)`` mm for the pattern point (u, v) (``rotation``: intrinsic XYZ Euler
    degrees, as GarmentCode builds it; ``translation`` in file units). None when the panel
    is not placed (all zero is what :func:`save_spec` writes)."""
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


def _panel_marks(
    path: Path, name: str, panel: dict, k: float, shift: np.ndarray
) -> tuple[tuple[tuple[float, float], tuple[float, float]] | None, list[tuple[float, float]]]:
    """Optional ``grainline`` [[x0,y0],[x1,y1]] and ``notches`` [[x,y],...] of a panel.

    Not part of GarmentCode; :func:`save_spec` writes them so that grain lines and
    notches from other sources (e.g. DXF) survive a round trip through JSON.
    """
    grain = None
    if "grainline" in panel:
        try:
            g = np.asarray(panel["grainline"], dtype=float).reshape(2, 2)
        except (TypeError, ValueError):
            raise GarmentError(path, f"panel {name!r} grainline is not two 2D points") from None
        if not np.isfinite(g).all():
            raise GarmentError(path, f"panel {name!r} grainline is not finite")
        g = g * k + shift
        grain = ((float(g[0, 0]), float(g[0, 1])), (float(g[1, 0]), float(g[1, 1])))
    marks: list[tuple[float, float]] = []
    if panel.get("notches"):
        try:
            n = np.asarray(panel["notches"], dtype=float).reshape(-1, 2)
        except (TypeError, ValueError):
            raise GarmentError(path, f"panel {name!r} notches are not 2D points") from None
        if not np.isfinite(n).all():
            raise GarmentError(path, f"panel {name!r} has a non-finite notch")
        marks = [(float(x), float(y)) for x, y in (n * k + shift).tolist()]
    return grain, marks


def _read_stitches(
    path: Path, raw: Any, index: dict[str, int], dense: list[list[np.ndarray]]
) -> list[tuple[int, int, int, int, bool]]:
    """[(panel a, edge a, panel b, edge b, right_wrong)], every reference checked."""
    if not isinstance(raw, list):
        raise GarmentError(path, "'stitches' is not a list")
    out = []
    for s, st in enumerate(raw):
        if not isinstance(st, list) or len(st) < 2:
            raise GarmentError(path, f"stitch {s} is not a pair of {{panel, edge}}")
        ends = []
        for side in st[:2]:
            if not isinstance(side, dict) or "panel" not in side or "edge" not in side:
                raise GarmentError(path, f"stitch {s} side is not {{panel, edge}}")
            name = side["panel"]
            if name not in index:
                raise GarmentError(path, f"stitch {s} names missing panel {name!r}")
            p = index[name]
            # 1.5 or true once read as edge 1: an index is a whole number, nothing else
            e = untrusted.integer(side["edge"], path, f"stitch {s} edge", lo=0, hi=10**9)
            if not 0 <= e < len(dense[p]):
                raise GarmentError(
                    path,
                    f"stitch {s} names missing edge {e} of panel {name!r} (it has {len(dense[p])})",
                )
            ends += [p, e]
        right_wrong = any(x == "right_wrong" for x in st[2:])
        out.append((ends[0], ends[1], ends[2], ends[3], right_wrong))
    return out


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


def _check_simple(path: Path, name: str, loop: np.ndarray) -> None:
    """Err unless the sampled outline is a simple polygon of positive area: Triangle
    crashes the process (SIGSEGV) on some degenerate loops, e.g. collinear vertices."""
    if len(loop) < 3:
        why = "fewer than 3 distinct points"
    else:
        ring = shapely.Polygon(loop)
        why = shapely.is_valid_reason(ring).split("[")[0].lower() if not ring.is_valid \
            else "" if ring.area > 0 else "no area"
    if why:
        raise GarmentError(path, f"panel {name!r} outline is not a simple polygon ({why})")


def _triangulate(path: Path, name: str, loop: np.ndarray, res: float) -> dict:
    """Quality triangulation of one closed loop with Triangle; boundary kept as sampled."""
    _check_simple(path, name, loop)
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


# ---------------------------------------------------------------------- export


def save_spec(g: Garment, path: str | Path) -> None:
    """Write a GarmentCode-style specification: one straight edge per outline segment.

    Panel vertices are the piece outlines (in cm, ``units_in_meter`` 100, as GarmentCode
    writes); each seam twin pair becomes one stitch, with ``right_wrong`` where the two
    edges run the same way round their panels. Grain lines and notches are kept as panel
    entries ``grainline`` and ``notches``, the triangle mesh as ``mesh`` so that
    :func:`load_spec` reads back exactly this pattern (any outline, any segment lengths).
    Seams on holes cannot be expressed and are dropped with a warning. An outline that
    crosses itself (a reshaping artefact CAD cannot cut) is written as it is, with a warning.
    """
    path = Path(path)
    panels: dict[str, dict] = {}
    edge_of: dict[tuple[int, int], tuple[str, int, int]] = {}
    names = _unique_names(g.piece_names)
    face_piece = g.piece_of_face()
    local = np.full(g.n_vertices, -1, dtype=np.int64)
    crossed = []
    for i in range(g.n_pieces):
        loop = g.piece_loops(i)[0]
        n = len(loop)
        # panel-local numbering: outline first (the panel vertices), then the interior
        mine = np.flatnonzero(g.piece_of_vertex == i)
        interior = mine[~np.isin(mine, loop)]
        local[loop] = np.arange(n)
        local[interior] = n + np.arange(len(interior))
        panels[names[i]] = {
            "translation": [0.0, 0.0, 0.0],
            "rotation": [0.0, 0.0, 0.0],
            "vertices": (g.uv[loop] / 10.0).tolist(),
            "edges": [{"endpoints": [k, (k + 1) % n]} for k in range(n)],
            "mesh": {
                "interior": (g.uv[interior] / 10.0).tolist(),
                "triangles": local[g.faces[face_piece == i]].tolist(),
            },
        }
        if n >= 3 and not shapely.LinearRing(g.uv[loop]).is_simple:
            crossed.append(names[i])
        if i in g.grainlines:
            panels[names[i]]["grainline"] = (np.asarray(g.grainlines[i]) / 10.0).tolist()
        if g.notches.get(i):
            panels[names[i]]["notches"] = (np.asarray(g.notches[i]) / 10.0).tolist()
        for k in range(n):
            a, b = int(loop[k]), int(loop[(k + 1) % n])
            edge_of[(a, b)] = (names[i], k, +1)
            edge_of[(b, a)] = (names[i], k, -1)
    stitches = []
    lost = 0
    for a, b, a2, b2 in g.seam_edges.tolist():
        e1, e2 = edge_of.get((a, b)), edge_of.get((a2, b2))
        if e1 is None or e2 is None:
            lost += 1
            continue
        st: list[Any] = [{"panel": e1[0], "edge": e1[1]}, {"panel": e2[0], "edge": e2[1]}]
        if e1[2] == e2[2]:
            st.append("right_wrong")
        stitches.append(st)
    if lost:
        warnings.warn(f"{path}: dropped {lost} seam edges that lie on holes", stacklevel=2)
    if crossed:
        warnings.warn(
            f"{path}: the outline of {', '.join(crossed)} crosses itself; "
            "a CAD program may not cut it as meant",
            stacklevel=2,
        )
    spec = {
        "pattern": {"panels": panels, "stitches": stitches, "panel_order": names},
        "properties": {
            "curvature_coords": "relative",
            "normalize_panel_translation": False,
            "normalized_edge_loops": True,
            "units_in_meter": 100,
            # panel vertices are already where the pattern has them: no automatic layout
            "pattern_layout": "absolute",
            "written_by": "cutting station (solver.garment.save_spec)",
        },
    }
    path.write_text(json.dumps(spec, indent=1) + "\n", encoding="utf-8")


def _unique_names(names: list[str]) -> list[str]:
    seen: dict[str, int] = {}
    out = []
    for n in names:
        k = seen.get(n, 0)
        seen[n] = k + 1
        out.append(n if k == 0 else f"{n}_{k}")
    return out
