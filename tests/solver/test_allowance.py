"""Cut lines: the sew line offset outward edge by edge, on the bundled real garments."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import shapely

from solver.garment import load_garment
from solver.garment.allowance import (
    AllowanceRules,
    cut_lines,
    dart_fills,
    drape_up,
    edge_allowances,
    offset_outline,
    open_edges,
)

GARMENTS = [
    ("berkeley/pants-coarse.obj", "m"),
    ("berkeley/skirt-coarse.obj", "m"),
    ("berkeley/tshirt-coarse.obj", "m"),
    ("berkeley/shorts-iso.obj", "m"),
    ("garmentcode/pants_specification.json", None),  # darts
    ("garmentcode/skirt_many_panels_specification.json", None),  # darts
    ("garmentcode/tshirt_specification.json", None),
    ("garment_pattern_generator/tee.json", None),
    ("garment_pattern_generator/pants_straight_sides.json", None),
]


@pytest.fixture(scope="module", params=GARMENTS, ids=[g[0] for g in GARMENTS])
def garment(request):
    from tests.conftest import DATA

    path, units = request.param
    return load_garment(DATA / "garments" / path, units=units)


def _edge_strip_inside(cut: shapely.Polygon, ring: np.ndarray, a: np.ndarray) -> bool:
    """Points a - 0.5 mm out from every edge (at 1/4, 1/2, 3/4 of it) lie in the cut line."""
    d = np.roll(ring, -1, axis=0) - ring
    length = np.hypot(*d.T)
    keep = length > 1e-6
    t = d[keep] / length[keep, None]
    out = np.column_stack([t[:, 1], -t[:, 0]])
    pts = np.concatenate([ring[keep] + f * d[keep] + np.maximum(a[keep] - 0.5, 0)[:, None] * out
                          for f in (0.25, 0.5, 0.75)])
    return bool(shapely.contains_xy(cut.buffer(1e-6), pts[:, 0], pts[:, 1]).all())


def test_cut_line_holds_the_allowance_and_stays_within_twice_it(garment):
    rules = AllowanceRules(seam_mm=10, hem_mm=20, opening_mm=8)
    for c in cut_lines(garment, rules):
        sew = shapely.Polygon(c.sew_outline, c.sew_holes)  # on the file's curves
        allow = np.concatenate([c.allowance, *c.hole_allowance])
        assert c.cut.is_valid and c.cut.exterior.is_simple  # never crosses itself
        assert shapely.Polygon(c.outline).exterior.is_ccw
        # sew line buffered by the allowance less 0.5 mm lies inside (area slack: rounding)
        assert sew.buffer(allow.min() - 0.5).difference(c.cut).area < 1e-6
        # each edge its own allowance
        assert _edge_strip_inside(c.cut, c.sew_outline, c.sew_outline_allowance)
        assert sew.buffer(2 * allow.max() + 0.5).contains(c.cut)
        assert len(c.holes) == len(c.sew_holes)


def test_open_edges_split_into_hems_and_openings():
    """The skirt has a waist and a hem; the T-shirt a neckline, two sleeve ends and a hem."""
    from tests.conftest import DATA

    skirt = load_garment(DATA / "garments" / "berkeley" / "skirt-coarse.obj", units="m")
    edges, opening, is_hem = open_edges(skirt)
    assert len(is_hem) == 2 and is_hem.sum() == 1
    heights = [skirt.xyz[edges[opening == k]][..., 1].mean() for k in range(2)]
    assert heights[int(np.argmax(is_hem))] < heights[int(np.argmin(is_hem))]  # hem at bottom
    # Berkeley drapes are z-up, GarmentCode's y-up: the neckline / waist is the top opening
    for path, units, up in (("berkeley/tshirt-coarse.obj", "m", 2),
                            ("berkeley/pants-coarse.obj", "m", 2),
                            ("garmentcode/pants_boxmesh_res2.obj", None, 1)):
        g = load_garment(DATA / "garments" / path, units=units)
        edges, opening, is_hem = open_edges(g)
        assert is_hem.sum() == len(is_hem) - 1, path
        height = [g.xyz[edges[opening == k]][..., up].mean() for k in range(len(is_hem))]
        assert int(np.argmax(height)) == int(np.argmin(is_hem)), path
    # a flat GarmentCode specification places its panels around the body (y up)
    spec = load_garment(DATA / "garments" / "garmentcode" / "tshirt_specification.json")
    assert len(spec.panel_frames) == spec.n_pieces
    edges, opening, is_hem = open_edges(spec)
    assert len(is_hem) == 4 and is_hem.sum() == 3  # neckline; bottom and sleeve hems
    neck = int(np.argmin(is_hem))
    assert {spec.piece_names[p] for p in spec.piece_of_vertex[edges[opening == neck, 0]]} == {
        "left_ftorso", "left_btorso", "right_ftorso", "right_btorso"}
    # GPG's tee holds its sleeves out level: the cuffs reach the shoulder's height, yet
    # they are hems (upright loops alone on the sleeves); the neckline is not
    tee = load_garment(DATA / "garments" / "garment_pattern_generator" / "tee.json")
    edges, opening, is_hem = open_edges(tee)
    assert len(is_hem) == 4 and is_hem.sum() == 3
    neck = int(np.argmin(is_hem))
    assert {tee.piece_names[p] for p in tee.piece_of_vertex[edges[opening == neck, 0]]} == {
        "front", "back"}


def test_overrides_change_only_what_they_name(garment):
    # each piece on its own: with mirror pairs the mirrored edges follow (test_pair_cut.py)
    base = edge_allowances(garment, AllowanceRules(), ())
    name = garment.seam_lines[0].name
    changed = edge_allowances(garment, AllowanceRules().with_overrides({name: 17.0, "hem": 33}),
                              ())
    first = garment.seam_edges[garment.seam_line_of_edge == 0]
    named = set(map(tuple, np.sort(np.vstack([first[:, :2], first[:, 2:]]), axis=1).tolist()))
    for i in range(garment.n_pieces):
        loop = garment.piece_loops(i)[0]
        pairs = np.sort(np.column_stack([loop, np.roll(loop, -1)]), axis=1)
        is_named = np.array([tuple(p) in named for p in pairs.tolist()])
        before, after = base[i][0], changed[i][0]
        assert np.all(after[is_named] == 17.0)
        moved = ~is_named & (after != before)
        assert np.all((before[moved] == 20.0) & (after[moved] == 33.0))  # only hems moved
    with pytest.raises(ValueError, match="no seam line, opening or piece"):
        edge_allowances(garment, AllowanceRules(overrides={"no-such-seam": 5.0}))


def test_sharp_corner_is_capped_at_twice_the_allowance():
    spike = np.array([[0.0, 0.0], [300.0, 0.0], [0.0, 20.0]])  # 3.8 degree tip
    cut = offset_outline([spike], [np.full(3, 10.0)], cap=2.0)
    d = shapely.Polygon(spike).exterior.distance(shapely.points(np.asarray(
        cut.exterior.coords)))
    assert d.max() <= 20.0 + 1e-6
    assert cut.contains(shapely.Polygon(spike).buffer(9.5))
    square = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [0.0, 100.0]])
    mitred = offset_outline([square], [np.full(4, 10.0)])
    assert mitred.area == pytest.approx(120.0 ** 2)  # offset lines extended to meet


def test_holes_stay_holes_and_a_dart_leaves_a_simple_outline():
    outer = np.array([[0.0, 0.0], [200.0, 0.0], [200.0, 200.0], [110.0, 200.0], [100.0, 120.0],
                      [90.0, 200.0], [0.0, 200.0]])  # a dart from the top edge
    hole = np.array([[50.0, 50.0], [50.0, 80.0], [80.0, 80.0], [80.0, 50.0]])  # clockwise
    cut = offset_outline([outer, hole], [np.full(7, 10.0), np.full(4, 5.0)])
    assert cut.is_valid and cut.exterior.is_simple and len(cut.interiors) == 1
    assert shapely.Polygon(cut.interiors[0]).area == pytest.approx(20.0 ** 2)
    small = offset_outline([outer, hole], [np.full(7, 10.0), np.full(4, 20.0)])
    assert len(small.interiors) == 1  # too small for 20 mm: cut on its sew line
    assert shapely.Polygon(small.interiors[0]).area == pytest.approx(30.0 ** 2)


def test_the_cut_line_runs_across_a_dart_as_if_it_were_closed():
    """GarmentCode's trouser backs have two darts each (legs sewn to each other)."""
    from tests.conftest import DATA

    g = load_garment(DATA / "garments" / "garmentcode" / "pants_specification.json")
    rules = AllowanceRules()
    cuts = cut_lines(g, rules)
    per_edge = edge_allowances(g, rules)
    darted = [i for i in range(g.n_pieces) if any(
        s.piece_a == s.piece_b == i for s in g.seam_lines)]
    assert darted
    for i in darted:
        fills = dart_fills(g, i, per_edge[i][0], rules.cap)
        assert len(fills) == sum(s.piece_a == s.piece_b == i for s in g.seam_lines)
        for f in fills:
            assert cuts[i].cut.buffer(1e-6).contains(f)  # no slot left at the dart's mouth
        sew = shapely.Polygon(cuts[i].sew)
        assert sew.buffer(2 * cuts[i].allowance.max() + 0.5).contains(cuts[i].cut)
        assert cuts[i].cut.exterior.is_simple


def test_shared_garments_keep_the_cut_line_bounds(shared_data):
    """Held-out shapes: GarmentCode dresses (side and waist darts), GPG, ARCSim meshes."""
    root = shared_data / "garments"
    files = (sorted((root / "garmentcode" / "generated").glob("*/*_specification.json"))
             + sorted((root / "garment_pattern_generator").glob("*.json"))
             + sorted((root / "arcsim_meshes").glob("*.obj")))
    assert files
    for path in files:
        g = load_garment(path, units="m" if path.suffix == ".obj" else None)
        for c in cut_lines(g):
            sew = shapely.Polygon(c.sew_outline, c.sew_holes)  # on the file's curves
            allow = np.concatenate([c.allowance, *c.hole_allowance])
            assert c.cut.is_valid and c.cut.exterior.is_simple, path.name
            assert sew.buffer(allow.min() - 0.5).difference(c.cut).area < 1e-6, path.name
            assert sew.buffer(2 * allow.max() + 0.5).contains(c.cut), path.name


def _rings(specs: list[tuple[np.ndarray, np.ndarray, float]], n: int = 64
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points, edges and opening labels of circular openings (centre, normal, radius)."""
    pts, edges, label = [], [], []
    for k, (c, nrm, r) in enumerate(specs):
        nrm = np.asarray(nrm, float) / np.linalg.norm(nrm)
        u = np.cross(nrm, [0.0, 0.0, 1.0] if abs(nrm[2]) < 0.9 else [1.0, 0.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(nrm, u)
        t = np.linspace(0, 2 * np.pi, n, endpoint=False)
        start = sum(len(p) for p in pts)
        pts.append(np.asarray(c, float) + r * (np.outer(np.cos(t), u) + np.outer(np.sin(t), v)))
        edges.append(start + np.column_stack([np.arange(n), (np.arange(n) + 1) % n]))
        label.append(np.full(n, k))
    return np.vstack(pts), np.vstack(edges), np.concatenate(label)


def test_up_is_the_least_mirrored_axis_and_cuffs_at_45_degrees_do_not_vote():
    """A t-shirt y-up (as GarmentCode places its panels) with its sleeves raised 45
    degrees: hem 300 mm across at the bottom, neckline 150 mm at the top, cuffs 200 mm.
    The cuffs counted as level openings above the middle and turned the garment upside
    down (its neckline then took the hem allowance); and open fronts made the openings'
    planes pick the axis. Up is the axis across which the garment is least mirrored."""
    xyz, edges, opening = _rings([([0, 0, 0], [0, 1, 0], 300.0),
                                  ([0, 500, 0], [0, 1, 0], 150.0),
                                  ([-400, 400, 0], [0.7, 0.71, 0], 200.0),
                                  ([400, 400, 0], [-0.7, 0.71, 0], 200.0)])
    assert np.allclose(drape_up(xyz, edges, opening), [0, 1, 0])
    turned = xyz[:, [2, 0, 1]]  # the same garment z-up (as the Berkeley files are)
    assert np.allclose(drape_up(turned, edges, opening), [0, 0, 1])
    assert np.allclose(drape_up(-turned, edges, opening), [0, 0, -1])


def test_shared_drapes_stand_up(shared_data):
    """GarmentCode's box meshes are y-up and stand on their hems; the Berkeley and ARCSim
    drapes are z-up. Before, the box meshes (sleeves at 45 degrees) stood on their
    necklines, the neckline cut with the hem's allowance and the hem with an opening's,
    and open fronts (Berkeley shirt and vest, ARCSim jacket) had up across the body."""
    garments = shared_data / "garments"
    boxes = sorted((garments / "garmentcode").glob("**/*boxmesh*.obj"))
    drapes = sorted(garments.glob("berkeley_garment_library/**/*-iso*.obj")) + sorted(
        (garments / "arcsim_meshes").glob("*.obj"))
    assert len(boxes) >= 4 and len(drapes) >= 10
    for path, expected in [(p, [0, 1, 0]) for p in boxes] + [(p, [0, 0, 1]) for p in drapes]:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            g = load_garment(path, units="m" if "berkeley" in str(path) else None)
        edges, opening, is_hem = open_edges(g)
        assert np.allclose(drape_up(g.xyz, edges, opening), expected), path
        if path in boxes:  # the lowest opening is the hem
            low = [g.xyz[edges[opening == k][:, 0], 1].mean()
                   for k in range(int(opening.max()) + 1)]
            assert is_hem[int(np.argmin(low))], path
