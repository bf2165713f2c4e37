"""The print's mismatch across the seams as really cut on the simulated roll (issue 35).

Simulation side only (`station demo`): it reads the simulator's truth, which production
never has. For every seam edge of every garment of an order, the midpoint seen on both
sides (as E_fit takes them, `solver.fit.seam_midpoints`) is carried pattern -> window by
the map each piece was cut with (``bite-K-pieces.json``, written by the bite loop from
the markers it handed to the cut), window -> cloth by the simulated conveyor's real pose
at that bite, and cloth -> the print's design by `simulators.roll.RollPrint`; the two
sides' design points are compared by the print's own symmetry (`Wallpaper.mismatch`).

Per seam edge, the print's mismatch across the seam as cut on the cloth (under the
print's true symmetry), and as planned (the marker on the print as detected, under the
detected symmetry: the alignment's own residual, since a tee's seams cannot all match a
plaid whatever the cut). The figures are given over every seam edge and over the edges
the plan matched (within `MATCHED_MM`), where all that is left is what the cut did.

"Uncompensated" is the same cut as if each bite had been cut where it was planned: the
marker moved by the commanded advances only, no re-registration, no local maps, on the
same real poses of the roll; "without local maps" is each bite's measured track alone.
Where the GRBL emulator's trace is at hand, each piece's map is refitted to what the
machine really burnt (`traced_maps`), so the figures are about the real cut.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import shapely

from simulators.roll import Pose, RollPrint
from solver.fit import seam_midpoints
from solver.garment import Garment, load_garment
from solver.nest.instance import affine, compose, invert
from solver.nest.layout import Layout
from solver.placement import Placement
from solver.wallpaper import Wallpaper
from station.steps.cutbites import BITE_PIECES_FILE

#: a seam edge the plan matched: its print mismatch as planned is within this (mm)
MATCHED_MM = 1.0
#: a traced cut further than this from the pieces of its bite belongs to the next bite
TRACE_TOLERANCE_MM = 0.5


@dataclass(frozen=True)
class SeamSides:
    """Both sides of every seam edge of an order: pattern midpoints (E, 2) and the id of
    the marker piece each lies on (E,)."""

    points_a: np.ndarray
    pieces_a: np.ndarray
    points_b: np.ndarray
    pieces_b: np.ndarray


def garment_seams(garment: Garment, piece_ids: list[str]) -> SeamSides:
    """The seam edges of ``garment``, each side named by the marker piece ``piece_ids[i]``
    cut for the garment's piece ``i``."""
    edges = garment.seam_edges
    a, b = seam_midpoints(garment.uv, edges)
    ids = np.asarray(piece_ids, dtype=object)
    return SeamSides(a, ids[garment.piece_of_vertex[edges[:, 0]]],
                     b, ids[garment.piece_of_vertex[edges[:, 2]]])


def joined(parts: list[SeamSides]) -> SeamSides:
    """The seams of several garments as one set."""
    return SeamSides(*(np.concatenate([getattr(s, name) for s in parts])
                       for name in ("points_a", "pieces_a", "points_b", "pieces_b")))


def mapped(points: np.ndarray, pieces: np.ndarray, maps: dict[str, np.ndarray]) -> np.ndarray:
    """(E, 2) ``points`` carried each by the (2, 3) map of its piece."""
    m = np.stack([maps[p] for p in pieces])
    return np.einsum("nij,nj->ni", m[:, :, :2], points) + m[:, :, 2]


def on_cloth(window: np.ndarray, poses: list[Pose], pose_of) -> np.ndarray:
    """(E, 2) cloth points of (E, 2) window points, point ``i`` under ``poses[pose_of[i]]``
    (`simulators.roll.Pose.cloth_point`, vectorised over the points' poses)."""
    table = np.array([(math.radians(q.angle_deg), q.along, q.across, *q.pivot)
                      for q in poses]).reshape(-1, 5)[np.asarray(pose_of, int)]
    angle, shift, pivot = table[:, 0], table[:, 1:3], table[:, 3:5]
    c, s = np.cos(angle), np.sin(angle)
    d = window - pivot
    return np.column_stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]]) \
        + pivot + shift


def seam_mismatch(wallpaper: Wallpaper, side_a: np.ndarray, side_b: np.ndarray
                  ) -> np.ndarray:
    """(E,) mm: the print's mismatch across each seam edge whose sides show the print's
    points ``side_a`` and ``side_b`` (E, 2): `Wallpaper.mismatch`, as E_fit takes it."""
    return np.hypot(*wallpaper.mismatch(side_a, side_b).T)


def percentiles(d: np.ndarray) -> dict[str, float | int | None]:
    """p50, p90 and max of the distances ``d`` (mm), and how many."""
    d = np.asarray(d, float).ravel()
    if not len(d):
        return {"p50": None, "p90": None, "max": None, "seams": 0}
    p50, p90 = np.percentile(d, [50, 90])
    return {"p50": round(float(p50), 3), "p90": round(float(p90), 3),
            "max": round(float(d.max()), 3), "seams": int(len(d))}


def order_seams(workdir: Path, layout: Layout) -> SeamSides:
    """Every seam edge of the order planned in ``workdir`` (its placement.json names each
    garment's pattern and placement), on the pieces of ``layout``."""
    data = json.loads((workdir / "placement.json").read_text())
    by_name = {p.name: p.id for p in layout.pieces}
    parts = []
    for g in data["garments"]:
        placement = Placement.from_dict(g["placement"])
        garment = load_garment(placement.garment, units=placement.garment_units)
        names = placement.piece_names or list(garment.piece_names)
        parts.append(garment_seams(garment, [by_name[f"{g['garment']}.{n}"] for n in names]))
    return joined(parts)


def cut_maps(workdir: Path, layout: Layout, n_bites: int
             ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Each piece's pattern -> window map as its bite was cut (``bite-K-pieces.json``),
    and the same without its local map (the bite's track alone)."""
    cut: dict[str, np.ndarray] = {}
    tracked: dict[str, np.ndarray] = {}
    placed = {p.id: p.transform for p in layout.pieces}
    for k in range(n_bites):
        path = workdir / BITE_PIECES_FILE.format(index=k)
        if path.is_file():
            data = json.loads(path.read_text())
            track = np.asarray(data["track"], float).reshape(2, 3)
            for i, m in data["pieces"].items():
                cut[i] = np.asarray(m, float).reshape(2, 3)
                tracked[i] = compose(track, placed[i])
    return cut, tracked


def cut_outlines(workdir: Path, layout: Layout, n_bites: int) -> list[dict[str, np.ndarray]]:
    """Each bite's pieces as cut, in window mm: ``{piece id: (k, 2) cut line}``, the
    pattern's cut lines carried by the maps of ``bite-K-pieces.json``."""
    pattern = {p.id: affine(invert(p.transform), p.outline) for p in layout.pieces}
    bites = []
    for k in range(n_bites):
        path = workdir / BITE_PIECES_FILE.format(index=k)
        pieces = json.loads(path.read_text())["pieces"] if path.is_file() else {}
        bites.append({i: affine(np.asarray(m, float).reshape(2, 3), pattern[i])
                      for i, m in pieces.items()})
    return bites


def traced_points(trace: np.ndarray, origin: tuple[float, float],
                  bites: list[dict[str, np.ndarray]]
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points (n, 2) window mm, bite (n,), distance (n,) mm) of the ends of what the
    emulator burnt (``trace``: `simulators.grbl.trace.trace_rows`, work mm; the fabric at
    ``origin``). The trace is in cutting order, so each point belongs to the bite being
    cut, or to the next one once it leaves this one's pieces; a notch or mark lies inside
    its piece (distance 0)."""
    burning = trace[(trace[:, 5] > 0) & (trace[:, 6] == 0)]
    xy = burning[:, 2:4] - np.asarray(origin, float)
    shapes = [shapely.MultiPolygon([shapely.Polygon(o) for o in b.values()]) for b in bites]
    off = np.array([shapely.distance(shape, shapely.points(xy)) for shape in shapes]
                   ).reshape(len(shapes), -1)
    bite = np.zeros(len(xy), int)
    k = 0
    for i in range(len(xy)):  # in cutting order: the bite moves on, never back
        while off[k, i] > TRACE_TOLERANCE_MM and k + 1 < len(shapes) \
                and off[k + 1, i] <= TRACE_TOLERANCE_MM:
            k += 1
        bite[i] = k
    return xy, bite, off[bite, np.arange(len(xy))]


def fit_to_trace(outline: np.ndarray, points: np.ndarray, *, rounds: int = 3) -> np.ndarray:
    """(2, 3) the small rigid motion carrying the closed ``outline`` (k, 2) onto the traced
    ``points`` (n, 2) that lie along it: Gauss-Newton on the points' distances to the
    nearest side (point-to-line, so a side may slide along itself)."""
    ring = np.vstack([outline, outline[:1]])
    centre = outline.mean(axis=0)
    motion = np.zeros(3)  # tx, ty, theta about the centre
    for _ in range(rounds):
        moved = _rigid(motion, centre)
        a, b = affine(moved, ring[:-1]), affine(moved, ring[1:])
        ab = b - a
        t = np.clip(np.einsum("nmj,mj->nm", points[:, None] - a[None], ab)
                    / np.maximum(np.einsum("mj,mj->m", ab, ab), 1e-12), 0.0, 1.0)
        near = a[None] + t[..., None] * ab[None]
        side = np.argmin(np.hypot(*(points[:, None] - near).transpose(2, 0, 1)), axis=1)
        n = np.column_stack([-ab[side, 1], ab[side, 0]])
        n /= np.maximum(np.hypot(*n.T), 1e-12)[:, None]
        q = near[np.arange(len(points)), side]
        arm = q - centre - motion[:2]
        rows = np.column_stack([n, n[:, 1] * arm[:, 0] - n[:, 0] * arm[:, 1]])
        step, *_ = np.linalg.lstsq(rows, np.einsum("nj,nj->n", n, points - q), rcond=None)
        motion += step
    return _rigid(motion, centre)


def _rigid(motion: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """(2, 3): turn by ``motion[2]`` about ``centre``, then shift by ``motion[:2]``."""
    c, s = math.cos(motion[2]), math.sin(motion[2])
    rot = np.array([[c, -s], [s, c]])
    return np.column_stack([rot, centre - rot @ centre + motion[:2]])


def traced_maps(cut: dict[str, np.ndarray], bites: list[dict[str, np.ndarray]],
                xy: np.ndarray, bite: np.ndarray) -> tuple[dict[str, np.ndarray], float]:
    """Each piece's pattern -> window map as the emulator really cut it: its recorded map
    corrected by `fit_to_trace` on the burnt points of its bite nearest its cut line; and
    the largest move that correction made to any cut line (mm)."""
    out, largest = dict(cut), 0.0
    for k, pieces in enumerate(bites):
        ids = list(pieces)
        pts = xy[bite == k]
        if not ids or not len(pts):
            continue
        rings = [shapely.LinearRing(pieces[i]) for i in ids]
        near = np.array([shapely.distance(r, shapely.points(pts)) for r in rings])
        owner = near.argmin(axis=0)
        for j, i in enumerate(ids):
            mine = pts[(owner == j) & (near[j] <= TRACE_TOLERANCE_MM)]
            if len(mine) < 6:
                continue  # too little of it traced to fit: the recorded map stands
            fix = fit_to_trace(pieces[i], mine)
            out[i] = compose(fix, cut[i])
            largest = max(largest, float(np.abs(affine(fix, pieces[i]) - pieces[i]).max()))
    return out, largest


def planned_maps(layout: Layout, bites: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """Each piece's pattern -> window map had its bite been cut where it was planned: the
    marker moved back by the commanded advances so far, nothing measured."""
    maps, moved = {}, 0.0
    placed = {p.id: p for p in layout.pieces}
    for bite in bites:
        moved += float(bite.get("advance_commanded_mm") or 0.0)
        back = np.array([[1.0, 0.0, -moved], [0.0, 1.0, 0.0]])
        maps.update({i: compose(back, placed[i].transform) for i in bite["pieces"]})
    return maps


def measure_seams(workdir: Path, roll_print: RollPrint, poses: list[Pose], *,
                  trace: np.ndarray | None = None, origin: tuple[float, float] = (0.0, 0.0)
                  ) -> dict[str, Any]:
    """The report's seam figures of an order cut in bites on the simulated roll:
    ``seam_mismatch_mm`` (as cut), ``seam_mismatch_uncompensated_mm`` and
    ``seam_mismatch_planned_mm`` over every seam edge (and
    ``seam_mismatch_without_local_maps_mm``: the bites re-registered, the pieces not
    placed on the print under them), and ``seam_matched`` the same over the edges the
    plan matched (see the module's docstring). ``seam_cut`` says where the cut was taken
    from: the emulator's ``trace`` when given (`traced_maps`: how far it lay from the
    markers, and how far fitting moved them), else the markers handed to the cut. ``{}``
    when the job was not cut in bites."""
    report = json.loads((workdir / "report.json").read_text())
    bites = report.get("bites") or []
    if not bites or not (workdir / "placement.json").is_file():
        return {}
    layout = Layout.load(workdir / "layout.json")
    seams = order_seams(workdir, layout)
    bite_of = {i: b["index"] for b in bites for i in b["pieces"]}
    cut, tracked = cut_maps(workdir, layout, len(bites))
    uncut = sorted(set(bite_of) - set(cut))
    if uncut:  # a job stopped early: no seam of the order is whole on the cloth
        return {"seam_mismatch_mm": None, "seam_mismatch_note": f"{len(uncut)} pieces not "
                f"cut ({', '.join(uncut[:3])}...): nothing measured"}
    traced = None
    if trace is not None:  # the cut as the emulator really traced it
        outlines = cut_outlines(workdir, layout, len(bites))
        xy, bite, off = traced_points(trace, origin, outlines)
        cut, moved = traced_maps(cut, outlines, xy, bite)
        traced = {"source": "emulator trace", "points": int(len(xy)),
                  "per_bite": np.bincount(bite, minlength=len(bites)).tolist(),
                  "off_max_mm": round(float(off.max()), 4) if len(off) else None,
                  "fit_moved_max_mm": round(moved, 4)}
    placed = {p.id: p.transform for p in layout.pieces}
    planned = seam_mismatch(Wallpaper.from_dict(layout.fabric),
                            mapped(seams.points_a, seams.pieces_a, placed),
                            mapped(seams.points_b, seams.pieces_b, placed))
    matched = planned <= MATCHED_MM
    out: dict[str, Any] = {"seam_mismatch_planned_mm": percentiles(planned)}
    figures = {}
    for label, maps in (("", cut), ("_without_local_maps", tracked),
                        ("_uncompensated", planned_maps(layout, bites))):
        design = []
        for pts, ids in ((seams.points_a, seams.pieces_a), (seams.points_b, seams.pieces_b)):
            cloth = on_cloth(mapped(pts, ids, maps), poses, [bite_of[i] for i in ids])
            design.append(np.column_stack(roll_print.design_point(*cloth.T)))
        figures[label] = seam_mismatch(roll_print.design.wallpaper, *design)
        out[f"seam_mismatch{label}_mm"] = percentiles(figures[label])
    out["seam_matched"] = {
        "planned_within_mm": MATCHED_MM,
        **{f"seam_mismatch{label}_mm": percentiles(d[matched]) for label, d in figures.items()}}
    out["seam_cut"] = traced or {"source": "markers handed to the cut"}
    return out


__all__ = ["SeamSides", "cut_maps", "cut_outlines", "fit_to_trace", "garment_seams",
           "measure_seams", "order_seams", "percentiles", "planned_maps", "seam_mismatch",
           "traced_maps", "traced_points"]
