"""Notches: in the seam allowance, perpendicular to the sew line, twins on the same point."""

from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest
import shapely

from solver.garment import load_garment
from solver.garment.allowance import AllowanceRules, cut_lines, dart_runs
from solver.garment.notches import dart_marks, seam_notches
from tests.solver.test_allowance import GARMENTS


@pytest.fixture(scope="module", params=GARMENTS, ids=[g[0] for g in GARMENTS])
def notched(request):
    from tests.conftest import DATA

    path, units = request.param
    g = load_garment(DATA / "garments" / path, units=units)
    rules = AllowanceRules(seam_mm=12, hem_mm=25, opening_mm=8)
    cuts = cut_lines(g, rules)
    return g, cuts, seam_notches(g, cuts, spacing_mm=100, depth_mm=4), rules


def test_every_notch_is_a_short_slit_inside_the_allowance(notched):
    g, cuts, notches, rules = notched
    assert sum(map(len, notches)) > 0
    for i, per_piece in enumerate(notches):
        sew = shapely.Polygon(cuts[i].sew, cuts[i].sew_holes)
        for q in per_piece:
            a, b = g.uv[q.edge[0]], g.uv[q.edge[1]]
            tangent = (b - a) / np.linalg.norm(b - a)
            assert abs(float(np.dot(q.direction, tangent))) < 1e-9  # perpendicular
            assert np.allclose(q.sew_point, a + q.t * (b - a))
            assert cuts[i].cut.boundary.distance(shapely.Point(q.at)) < 1e-6  # on the cut line
            inner = q.at + q.depth * q.direction
            slit = shapely.LineString([q.at, inner])
            assert 0 < q.depth <= rules.seam_mm / 2 + 1e-9 and q.depth <= 4.0
            assert slit.distance(sew) > 0  # never reaches the sew line
            assert cuts[i].cut.buffer(1e-6).contains(slit)
            # it runs towards the sew point it marks
            assert np.linalg.norm(inner - q.sew_point) < np.linalg.norm(q.at - q.sew_point)


def test_twin_notches_mark_the_same_point_of_the_seam(notched):
    g, _, notches, _ = notched
    by_station = defaultdict(list)
    for per_piece in notches:
        for q in per_piece:
            by_station[(q.seam_line, q.station)].append(q)
    for (line, _), pair in by_station.items():
        assert len(pair) == 2
        s = g.seam_lines[line]
        assert sorted(q.piece for q in pair) == sorted((s.piece_a, s.piece_b))
        assert _marked(g, pair[0]) == pytest.approx(_marked(g, pair[1]), abs=1e-12)
        if g.xyz is not None:
            x = [g.xyz[n.edge[0]] + n.t * (g.xyz[n.edge[1]] - g.xyz[n.edge[0]]) for n in pair]
            assert np.allclose(x[0], x[1], atol=1e-6)


def _marked(g, q) -> tuple:
    """The sewn point a notch marks: a 3D point id, or a 3D edge and the fraction along it."""
    pov = g.point_of_vertex
    a, b = (int(pov[v]) for v in q.edge)
    if q.t in (0.0, 1.0):
        return (b if q.t else a,)
    return (a, b, q.t) if a < b else (b, a, 1 - q.t)


def test_every_seam_line_is_notched_near_both_ends(notched):
    g, _, notches, _ = notched
    stations = defaultdict(set)
    for per_piece in notches:
        for q in per_piece:
            stations[q.seam_line].add(q.station)
    darts = {line for i in range(g.n_pieces) for line, _ in dart_runs(g, i)}
    for line in range(len(g.seam_lines)):
        if line in darts:  # one twin pair at the mouth: the legs are sewn shut
            assert stations[line] == {0}, g.seam_lines[line].name
            continue
        rows = g.seam_edges[g.seam_line_of_edge == line]
        length = float(np.hypot(*(g.uv[rows[:, 1]] - g.uv[rows[:, 0]]).T).sum())
        last = max(int(np.ceil((length - 2 * min(12.0, length / 4)) / 100)), 1)
        assert {0, last} <= stations[line], g.seam_lines[line].name


def test_a_dart_gets_a_drill_mark_before_its_point():
    from tests.conftest import DATA

    g = load_garment(DATA / "garments" / "garmentcode" / "pants_specification.json")
    cuts = cut_lines(g)
    for i in range(g.n_pieces):
        runs = dart_runs(g, i)
        marks = dart_marks(g, i)
        assert len(marks) == len(runs)
        for (_, run), m in zip(runs, marks):
            assert cuts[i].cut.contains(shapely.Point(m))  # in the cloth (the kept wedge)
            assert np.hypot(*(g.uv[run] - m).T).min() <= 10.0 + 1e-9


def test_on_a_print_balance_notches_sit_where_lattice_lines_cross_the_seam(data_dir):
    from solver.garment.notches import placement_lattice
    from solver.placement import Placement
    from solver.wallpaper import Wallpaper

    g = load_garment(data_dir / "garments" / "berkeley" / "tshirt-coarse.obj", units="m")
    fabric = Wallpaper("p4m", [60.0, 0.0], [0.0, 60.0], [7.0, 3.0])
    placement = Placement.identity(g.n_pieces, fabric)
    placement.angles[:] = np.radians([10, 40, 70, 100, 130, 160])
    rules = AllowanceRules()
    cuts = cut_lines(g, rules)
    lattice = placement_lattice(placement)
    notches = seam_notches(g, cuts, spacing_mm=100, depth_mm=3,
                           lattice_coords=lattice)
    first_side = set()  # stations are measured along each seam line's longer side
    for line in range(len(g.seam_lines)):
        rows = g.seam_edges[g.seam_line_of_edge == line]
        a, b = (np.hypot(*(g.uv[rows[:, k + 1]] - g.uv[rows[:, k]]).T).sum() for k in (0, 2))
        first_side |= {tuple(e) for e in rows[:, :2 if a >= b - 1e-6 else 4][:, -2:].tolist()}
    side_a = defaultdict(list)
    for per_piece in notches:
        for q in per_piece:
            if q.edge in first_side:
                side_a[q.seam_line].append(q)
    on_lines = interior = 0
    for qs in side_a.values():
        qs.sort(key=lambda q: q.station)
        for q in qs[1:-1]:
            f = lattice(q.piece, q.sew_point[None])[0]
            interior += 1
            on_lines += bool(np.abs(f - np.round(f)).min() < 1e-9)
        gaps = np.hypot(*np.diff([q.sew_point for q in qs], axis=0).T)
        assert gaps.max() <= 100.0 + 1e-6 and gaps.min() >= 45.0  # chords, a bit under arcs
    assert interior > 20 and on_lines >= 0.7 * interior  # the rest fill gaps over 100 mm
