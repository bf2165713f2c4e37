"""Cut lines on a specification's own curves: within 0.1 mm of the Beziers and arcs.

The true curves are sampled here independently of the importer (de Casteljau for the
Beziers, the arc's centre found from its chord and radius), 1500 points per edge.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import shapely

from solver.garment.allowance import AllowanceRules, cut_lines
from solver.garment.curves import CHORD_TOL_MM, adaptive_parameters, fine_loop
from solver.garment.spec import load_spec

DATA = Path(__file__).resolve().parents[1] / "data" / "garments"
GC_TEE = DATA / "garmentcode" / "tshirt_specification.json"
GPG_TEE = DATA / "garment_pattern_generator" / "tee.json"
DENSE = np.linspace(0.0, 1.0, 1500)


def _casteljau(ctrl: np.ndarray, t: np.ndarray) -> np.ndarray:
    pts = np.repeat(ctrl[None], len(t), axis=0)
    while pts.shape[1] > 1:
        pts = (1 - t)[:, None, None] * pts[:, :-1] + t[:, None, None] * pts[:, 1:]
    return pts[:, 0]


def _true_edge(a: np.ndarray, b: np.ndarray, curvature) -> np.ndarray:
    """Dense samples of one file edge (pygarment conventions), independently of solver."""
    e = b - a
    perp = np.array([-e[1], e[0]])
    if curvature is None:
        return np.array([a, b])
    if isinstance(curvature, list):
        rel = [curvature]
    elif curvature["type"] in ("quadratic", "cubic"):
        rel = curvature["params"]
    else:  # circle [radius, large_arc, right]: the SVG arc, centre on the chord's bisector
        radius, large, right = curvature["params"]
        d = np.hypot(*e)
        r = max(radius, d / 2)
        h = np.sqrt(max(r * r - d * d / 4, 0.0))
        sign = 1.0 if bool(large) != bool(right) else -1.0
        c = (a + b) / 2 + sign * h * perp / d
        za, zb = complex(*(a - c)), complex(*(b - c))
        sweep = np.angle(zb / za)  # the short way round, counter-clockwise positive
        if bool(right) and sweep < 0 or not bool(right) and sweep > 0:
            sweep -= np.sign(sweep) * 2 * np.pi
        z = za * np.exp(1j * sweep * DENSE)
        return c + np.column_stack([z.real, z.imag])
    ctrl = np.array([a, *(a + p[0] * e + p[1] * perp for p in rel), b])
    return _casteljau(ctrl, DENSE)


def _true_panels(path: Path) -> dict[str, list[np.ndarray]]:
    """Per panel its edges, densely sampled, in mm (file coordinates)."""
    data = json.loads(path.read_text())
    k = 1000.0 / data.get("properties", {}).get("units_in_meter", 1000.0)
    out = {}
    for name, panel in data["pattern"]["panels"].items():
        v = np.asarray(panel["vertices"], float) * k
        out[name] = [_true_edge(v[e["endpoints"][0]], v[e["endpoints"][1]],
                                e.get("curvature")) for e in panel["edges"]]
    return out


def _shift(piece_uv: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """The translation that lays the file's panel on the garment's piece: panels are only
    moved sideways, and every corner of the file is a vertex of the piece."""
    for x in piece_uv[np.abs(piece_uv[:, 1] - corners[0, 1]) < 1e-6, 0]:
        shift = np.array([x - corners[0, 0], 0.0])
        d = np.linalg.norm((corners + shift)[:, None] - piece_uv[None], axis=2).min(axis=1)
        if d.max() < 1e-6:
            return shift
    raise AssertionError("panel not found in the garment")


@pytest.mark.parametrize("path", [GC_TEE, GPG_TEE], ids=["garmentcode", "gpg"])
def test_cut_line_follows_the_true_curves(path: Path) -> None:
    g = load_spec(path)
    assert g.edge_curves, "a specification with curved edges keeps its curves"
    true = _true_panels(path)
    bare = cut_lines(g, AllowanceRules(0.0, 0.0, 0.0))  # cut on the sew line itself
    for i, name in enumerate(g.piece_names):
        edges = true[name]
        shift = _shift(g.uv[g.piece_loops(i)[0]], np.array([e[0] for e in edges]))
        ring = shapely.LinearRing(np.concatenate([e[:-1] for e in edges]) + shift)
        cut = bare[i].outline
        # both ways (Hausdorff): the cut is on the curve, and the curve is on the cut
        assert shapely.distance(shapely.points(cut), ring).max() <= CHORD_TOL_MM
        dense_cut = shapely.segmentize(shapely.LinearRing(cut), 0.5)
        assert shapely.distance(shapely.points(np.asarray(dense_cut.coords)),
                                ring).max() <= CHORD_TOL_MM
        assert shapely.distance(shapely.points(np.asarray(ring.coords)),
                                dense_cut).max() <= CHORD_TOL_MM


def test_offset_neckline_stays_one_allowance_from_the_curve() -> None:
    """With a 10 mm allowance the cut runs 10 +- 0.1 mm from the true neckline (a circular
    arc), and follows it with far more points than the mesh's chords."""
    g = load_spec(GC_TEE)
    i = g.piece_names.index("right_ftorso")
    edges = _true_panels(GC_TEE)["right_ftorso"]
    shift = _shift(g.uv[g.piece_loops(i)[0]], np.array([e[0] for e in edges]))
    neck = edges[1] + shift  # the edge labelled right_collar
    middle = shapely.LineString(neck[150:-150])  # clear of the corners' mitres
    cut = cut_lines(g, AllowanceRules(10.0, 10.0, 10.0))[i]
    pts = np.asarray(shapely.segmentize(cut.cut.exterior, 0.5).coords)
    near = shapely.distance(shapely.points(pts), middle) < 12.0
    d = shapely.distance(shapely.points(pts[near]), shapely.LineString(neck))
    assert near.sum() > 100
    assert np.abs(d - 10.0).max() <= CHORD_TOL_MM
    # point counts along the neckline: the cut line's own vertices against the mesh's
    mesh_near = shapely.distance(shapely.points(cut.sew), middle) < 0.01
    cut_near = shapely.distance(shapely.points(cut.outline), middle) < 12.0
    assert cut_near.sum() >= 3 * mesh_near.sum() >= 3 * 5


def test_mesh_vertices_stay_on_the_fine_outline_in_order() -> None:
    """The fine outline holds every mesh boundary vertex, in loop order, so seams, notches
    and allowances keep their correspondences; it survives a rigid move of the pattern."""
    g = load_spec(GPG_TEE)
    loop = g.piece_loops(g.piece_names.index("front"))[0]
    pts, edge = fine_loop(g.uv, loop, g.edge_curves)
    first = np.flatnonzero(np.r_[True, np.diff(edge) != 0])
    assert np.array_equal(edge[first], np.arange(len(loop)))
    assert np.array_equal(pts[first], g.uv[loop])
    assert len(pts) - len(loop) >= 40  # the neckline and armholes gained points
    turn = np.array([[0.6, -0.8], [0.8, 0.6]])
    moved, _ = fine_loop(g.uv @ turn.T + [300.0, -40.0], loop, g.edge_curves)
    assert np.allclose(moved, pts @ turn.T + [300.0, -40.0], atol=1e-9)


def test_adaptive_sampling_meets_its_tolerance() -> None:
    """A quarter circle of radius 100 mm: chords within tol, about as few as tol allows
    (sagitta l^2/8R: l = 8.9 mm for 0.1 mm, i.e. about 18 chords)."""
    def arc(t):
        return 100.0 * np.column_stack([np.cos(t * np.pi / 2), np.sin(t * np.pi / 2)])

    t = adaptive_parameters(arc, np.array([0.0, 0.3, 1.0]), 0.1)
    assert 0.3 in t and t[0] == 0.0 and t[-1] == 1.0
    mid = arc((t[:-1] + t[1:]) / 2)
    sag = 100.0 - np.hypot(*((arc(t[:-1]) + arc(t[1:])) / 2).T)
    assert sag.max() <= 0.1 and np.hypot(*mid.T).min() > 99.9
    assert 18 <= len(t) - 1 <= 40
    with pytest.raises(ValueError, match="tolerance"):
        adaptive_parameters(arc, np.array([0.0, 1.0]), 0.0)
