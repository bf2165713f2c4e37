"""The checks of a sewing-pattern specification that run before any geometry is built.

A specification is untrusted input: every type, count and reference the importer
(:mod:`solver.garment.spec`) reads is checked here first, and each fault is one
:class:`~solver.garment.errors.GarmentError` line naming the file and the panel, edge or
stitch at fault. The size checks err before meshing, where a wrong ``units_in_meter``
would otherwise ask Triangle for millions of faces.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import shapely

import untrusted
from solver.garment.errors import GarmentError
from solver.garment.mesh import boundary_half_edges, edge_keys
from solver.geometry import polygon_area


def read_spec_json(path: Path) -> dict:
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
            _check_panel_structure(path, f"panel {name!r}", panel)
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


def _check_panel_structure(path: Path, where: str, panel: Any) -> None:
    """One panel's vertices, edges, endpoints and curvatures: types and sizes."""
    lim = untrusted.limits
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
        _check_curvature(path, f"{where} edge {k}", e.get("curvature"))


def _check_curvature(path: Path, where: str, curvature: Any) -> None:
    """A curvature is a GPG control point or an object whose params are a few numbers or
    points; its type and counts are checked later, by :func:`solver.garment.curves.edge_curve`."""
    if isinstance(curvature, list):
        untrusted.vector(curvature, path, f"{where} curvature", max_abs=1e6)
    elif isinstance(curvature, dict):
        params = curvature.get("params")
        if not isinstance(params, list) or len(params) > 3 or not all(
                isinstance(x, (int, float, list)) for x in params):
            raise untrusted.InputError(path, f"{where} curvature params "
                                       "must be a short list of numbers or points")
        for x in params:
            if isinstance(x, list):
                untrusted.vector(x, path, f"{where} curvature", max_abs=1e6)
            else:
                untrusted.number(x, path, f"{where} curvature", lo=-1e9, hi=1e9)


def check_size(path: Path, verts_mm: list[np.ndarray], res: float) -> None:
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


def panel_geometry(path: Path, name: str, panel: Any) -> tuple[np.ndarray, list[dict]]:
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


def panel_mesh(
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
    on_boundary = edge_keys(bhe[:, 0], bhe[:, 1], total)
    k = np.arange(n)
    loop_keys = edge_keys(k, (k + 1) % n, total)
    missing = np.flatnonzero(~np.isin(loop_keys, on_boundary))
    if missing.size:
        raise GarmentError(
            path, f"panel {name!r} edge {int(missing[0])} is not on the boundary of its mesh"
        )
    return interior, tri


def panel_marks(
    path: Path, name: str, panel: dict, k: float, shift: np.ndarray
) -> tuple[tuple[tuple[float, float], tuple[float, float]] | None, list[tuple[float, float]]]:
    """Optional ``grainline`` [[x0,y0],[x1,y1]] and ``notches`` [[x,y],...] of a panel.

    Not part of GarmentCode; :func:`~solver.garment.spec_save.save_spec` writes them so
    that grain lines and notches from other sources (e.g. DXF) survive a round trip
    through JSON.
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


def read_stitches(
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


def check_simple(path: Path, name: str, loop: np.ndarray) -> None:
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
