"""Write a garment as a GarmentCode-style JSON specification that reads back exactly.

One straight edge per outline segment, the triangle mesh kept as each panel's ``mesh``,
grain lines and notches as panel entries: :func:`solver.garment.spec.load_spec` reads the
same pattern back, whatever its outline (a reshaped one need not fit any resolution).
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import shapely

from solver.garment.model import Garment


def save_spec(g: Garment, path: str | Path) -> None:
    """Write a GarmentCode-style specification: one straight edge per outline segment.

    Panel vertices are the piece outlines (in cm, ``units_in_meter`` 100, as GarmentCode
    writes); each seam twin pair becomes one stitch, with ``right_wrong`` where the two
    edges run the same way round their panels. Grain lines and notches are kept as panel
    entries ``grainline`` and ``notches``, the triangle mesh as ``mesh`` so that
    :func:`~solver.garment.spec.load_spec` reads back exactly this pattern (any outline,
    any segment lengths).
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
        panels[names[i]] = _panel(g, i, loop, face_piece, local)
        if len(loop) >= 3 and not shapely.LinearRing(g.uv[loop]).is_simple:
            crossed.append(names[i])
        for k in range(len(loop)):
            a, b = int(loop[k]), int(loop[(k + 1) % len(loop)])
            edge_of[(a, b)] = (names[i], k, +1)
            edge_of[(b, a)] = (names[i], k, -1)
    stitches, lost = _stitches(g, edge_of)
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


def _panel(g: Garment, i: int, loop: np.ndarray, face_piece: np.ndarray,
           local: np.ndarray) -> dict:
    """Piece i as a panel (cm): its outline's straight edges, its mesh in panel-local
    numbering (the outline first, then the interior; ``local`` is filled in), its grain
    line and notches."""
    n = len(loop)
    mine = np.flatnonzero(g.piece_of_vertex == i)
    interior = mine[~np.isin(mine, loop)]
    local[loop] = np.arange(n)
    local[interior] = n + np.arange(len(interior))
    panel = {
        "translation": [0.0, 0.0, 0.0],
        "rotation": [0.0, 0.0, 0.0],
        "vertices": (g.uv[loop] / 10.0).tolist(),
        "edges": [{"endpoints": [k, (k + 1) % n]} for k in range(n)],
        "mesh": {
            "interior": (g.uv[interior] / 10.0).tolist(),
            "triangles": local[g.faces[face_piece == i]].tolist(),
        },
    }
    if i in g.grainlines:
        panel["grainline"] = (np.asarray(g.grainlines[i]) / 10.0).tolist()
    if g.notches.get(i):
        panel["notches"] = (np.asarray(g.notches[i]) / 10.0).tolist()
    return panel


def _stitches(g: Garment, edge_of: dict) -> tuple[list, int]:
    """One stitch per seam twin pair of outline edges; how many lie on holes (dropped)."""
    stitches, lost = [], 0
    for a, b, a2, b2 in g.seam_edges.tolist():
        e1, e2 = edge_of.get((a, b)), edge_of.get((a2, b2))
        if e1 is None or e2 is None:
            lost += 1
            continue
        st: list[Any] = [{"panel": e1[0], "edge": e1[1]}, {"panel": e2[0], "edge": e2[1]}]
        if e1[2] == e2[2]:
            st.append("right_wrong")
        stitches.append(st)
    return stitches, lost


def _unique_names(names: list[str]) -> list[str]:
    seen: dict[str, int] = {}
    out = []
    for n in names:
        k = seen.get(n, 0)
        seen[n] = k + 1
        out.append(n if k == 0 else f"{n}_{k}")
    return out
