"""Nesting: every layout is checked by the independent verifier, on real instances."""

from __future__ import annotations

import json

import numpy as np
import pytest
import shapely

from solver.nest import Layout, NestProblem, Piece, load_esicup, nest_plain, verify_layout
from solver.nest.instance import affine, compose, invert
from solver.nest.lattice import nest_lattice
from solver.nest.naive import nest_naive
from solver.nest.solve import nest
from solver.wallpaper import Wallpaper, covering_radius


@pytest.fixture(scope="module")
def shirts(request):
    from pathlib import Path

    return Path(__file__).resolve().parents[1] / "data" / "nesting" / "shirts.json"


@pytest.fixture(scope="module")
def shirts_plain(shirts):
    problem = load_esicup(shirts)
    return problem, nest_plain(problem, time_limit=2, seed=3)


def l_piece(name="L", **kw) -> Piece:
    return Piece(name, [[0, 0], [30, 0], [30, 10], [10, 10], [10, 25], [0, 25]], **kw)


def test_esicup_instance_loads_with_demands_and_orientations(shirts):
    p = load_esicup(shirts)
    assert p.width == 40 and len(p.pieces) == 8
    assert len(p.items()) == 99
    assert all(pc.orientations == (0.0, 180.0) for pc in p.pieces)
    assert p.piece_area == pytest.approx(sum(pc.area * pc.quantity for pc in p.pieces))


def test_plain_shirts_with_sparrow_is_dense_and_valid(shirts_plain):
    problem, layout = shirts_plain
    assert verify_layout(layout, problem) == []
    assert len(layout.pieces) == 99
    assert layout.density > 0.78  # sparrow reaches ~86 % in 30 s; 2 s on a busy machine less
    assert layout.density == pytest.approx(problem.piece_area / (40 * layout.length))


def test_verifier_catches_overlap_edge_and_rotation(shirts_plain):
    problem, layout = shirts_plain
    d = layout.to_dict()
    bad = Layout.from_dict(json.loads(json.dumps(d)))
    assert verify_layout(bad, problem) == []  # the JSON round trip keeps it valid
    a, b = bad.pieces[0], bad.pieces[1]
    shift = b.outline.mean(0) - a.outline.mean(0)
    a.outline = a.outline + shift
    a.transform = a.transform + np.column_stack([np.zeros((2, 2)), shift])
    faults = verify_layout(bad, problem)
    assert any("overlaps" in f for f in faults)
    turned = Layout.from_dict(d)
    p = turned.pieces[5]
    c = p.outline.mean(0)
    r = np.array([[0.0, -1.0], [1.0, 0.0]])  # 90 degrees: not allowed for shirts
    p.outline = (p.outline - c) @ r.T + c
    p.transform = compose(np.column_stack([r, c - r @ c]), p.transform)
    assert any("rotation" in f for f in verify_layout(turned, problem))
    out = Layout.from_dict(d)
    out.pieces[0].outline = out.pieces[0].outline - [0, 1000]
    assert any("leaves the fabric" in f for f in verify_layout(out))


def test_layout_json_has_the_agreed_fields(shirts_plain, tmp_path):
    _, layout = shirts_plain
    layout.save(tmp_path / "LAYOUT.json")
    d = json.loads((tmp_path / "LAYOUT.json").read_text())
    assert {"version", "units", "width", "length", "gap", "origin", "density", "fabric",
            "pieces"} <= set(d)
    p = d["pieces"][0]
    assert set(p) == {"id", "name", "transform", "angle_deg", "mirrored", "outline", "holes",
                      "notches", "marks", "grainline"}
    ring = np.array(p["outline"])
    assert shapely.Polygon(ring).exterior.is_ccw and not np.allclose(ring[0], ring[-1])


def test_gap_mirrored_pairs_and_quantities():
    problem = NestProblem([l_piece(quantity=2, mirrored_pair=True),
                           Piece("sq", [[0, 0], [12, 0], [12, 12], [0, 12]], quantity=3)],
                          width=60.0, gap=2.0)
    layout = nest_plain(problem, time_limit=1, seed=0)
    assert verify_layout(layout, problem) == []
    ids = sorted(p.id for p in layout.pieces)
    assert ids == ["L#1", "L#1m", "L#2", "L#2m", "sq#1", "sq#2", "sq#3"]
    for p in layout.pieces:
        assert (np.linalg.det(p.transform[:, :2]) < 0) == p.id.endswith("m")
    polys = [p.polygon() for p in layout.pieces]
    dmin = min(a.distance(b) for i, a in enumerate(polys) for b in polys[i + 1:])
    assert dmin >= 2.0 - 1e-6
    allx = np.vstack([p.outline for p in layout.pieces])
    assert allx[:, 1].min() >= 2.0 - 1e-9 and allx[:, 1].max() <= 58.0 + 1e-9


def test_keepout_and_window_are_respected():
    flaw = np.array([[20, 10], [40, 10], [40, 40], [20, 40]], float)
    problem = NestProblem([l_piece(quantity=6)], width=60.0, length=150.0, gap=1.0,
                          keepouts=[flaw])
    layout = nest(problem, time_limit=2, seed=1)
    assert verify_layout(layout, problem) == []
    assert all(p.polygon().distance(shapely.Polygon(flaw)) >= 1.0 - 1e-6 for p in layout.pieces)
    assert layout.length <= 150.0
    with pytest.raises(ValueError, match="do not fit"):
        nest(NestProblem([l_piece(quantity=6)], width=60.0, length=40.0), time_limit=1)


def test_bad_pieces_are_refused_with_their_name(tmp_path):
    with pytest.raises(ValueError, match="'bow'.*crosses itself"):
        Piece("bow", [[0, 0], [10, 10], [10, 0], [0, 10]])
    with pytest.raises(ValueError, match="'dot'.*at least 3"):
        Piece("dot", [[0, 0], [1, 1]])
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"strip_height": 10, "items": [{"id": 0, "shape": {}}]}))
    with pytest.raises(ValueError, match="bad.json: item 0 lacks"):
        load_esicup(bad)


def test_covering_radius():
    assert covering_radius(np.eye(2) * 2) == pytest.approx(np.sqrt(2))
    hexa = np.array([[1.0, -0.5], [0.0, np.sqrt(3) / 2]])
    assert covering_radius(hexa) == pytest.approx(1 / np.sqrt(3))


def _assert_moves_are_symmetries(layout, problem):
    """The print under each placed piece is the print under its aligned position."""
    wp = problem.fabric
    by_name = {p.name: p for p in problem.pieces}
    rng = np.random.default_rng(1)
    for placed in layout.pieces:
        piece = by_name[placed.name]
        g = compose(placed.transform, invert(piece.base))
        pts = rng.uniform(-50, 50, (32, 2))
        assert wp.mismatch_distance(affine(g, pts), pts).max() < 1e-6


def test_printed_shirts_lattice_search_beats_the_naive_baseline(shirts):
    problem = load_esicup(shirts)
    problem.fabric = Wallpaper("p1", (1.0, 0.0), (0.0, 1.0))
    layout = nest_lattice(problem, time_limit=2.5, seed=0, strategies=("fill",))
    assert verify_layout(layout, problem) == []
    _assert_moves_are_symmetries(layout, problem)
    assert all(p.angle_deg == pytest.approx(0.0) for p in layout.pieces)  # p1: no turns
    # translations are whole lattice vectors from the aligned (input) position
    t = np.array([p.transform[:, 2] for p in layout.pieces])
    assert np.allclose(t, np.round(t), atol=1e-9)
    # the naive baseline gives 44 % here (47 % measured with sparrow 10 s)
    assert layout.density > 0.65


def test_naive_baseline_is_valid_and_snapped(shirts):
    problem = load_esicup(shirts)
    problem.fabric = Wallpaper("p2", (1.0, 0.0), (0.3, 0.9))
    layout = nest_naive(problem, time_limit=2, seed=0)
    assert verify_layout(layout, problem) == []
    _assert_moves_are_symmetries(layout, problem)


def test_mirrored_copy_on_a_print_uses_a_mirror_of_the_print():
    fabric = Wallpaper("pm", (8.0, 0.0), (0.0, 6.0), origin=(1.0, 2.0))
    problem = NestProblem([l_piece(mirrored_pair=True, quantity=2)], width=70.0, gap=0.5,
                          fabric=fabric)
    layout = nest(problem, time_limit=2, seed=0)
    assert verify_layout(layout, problem) == []
    _assert_moves_are_symmetries(layout, problem)
    assert sum(p.mirrored for p in layout.pieces) == 2
    # a flaw and a short table on the same print: still symmetries only, clear of the flaw
    flaw = np.array([[5, 5], [35, 5], [35, 30], [5, 30]], float)
    problem.keepouts, problem.length = [flaw], 120.0
    layout = nest(problem, time_limit=2, seed=0)
    assert verify_layout(layout, problem) == []
    _assert_moves_are_symmetries(layout, problem)
    with pytest.raises(ValueError, match="no operation"):
        NestProblem([l_piece(mirrored_pair=True)], width=70.0,
                    fabric=Wallpaper("p1", (8.0, 0.0), (0.0, 6.0))).items()


def test_placement_input_keeps_every_piece_on_its_print_position(data_dir, tmp_path, capsys):
    """PLACEMENT.json (Berkeley t-shirt, p4m print): nested pieces see the same print."""
    from solver.garment import load_garment
    from solver.nest.sources import load_problem
    from solver.placement import Placement
    from station.cli import main

    garment = data_dir / "garments" / "berkeley" / "tshirt-coarse.obj"
    fabric = Wallpaper("p4m", (60.0, 0.0), (0.0, 60.0), origin=(7.0, 3.0))
    n = load_garment(garment, units="m").n_pieces
    rng = np.random.default_rng(0)
    placement = Placement(np.radians(rng.choice([0.0, 90.0, 180.0], n)),
                          rng.uniform(-100, 100, (n, 2)), fabric, garment=str(garment))
    path = tmp_path / "PLACEMENT.json"
    placement.save(path)
    out = tmp_path / "LAYOUT.json"
    rc = main(["nest", str(path), "-o", str(out), "--width", "1500", "--gap", "3",
               "--units", "m", "--time", "2", "--json"])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["pieces"] == n and summary["printed"]
    layout = Layout.load(out)
    problem = load_problem([path], width=1500.0, gap=3.0, units="m")
    assert verify_layout(layout, problem) == []
    _assert_moves_are_symmetries(layout, problem)
    # the print seen at a point of a placed piece is the print at the same pattern point
    names = [p.name for p in problem.pieces]
    for placed in layout.pieces:
        i = names.index(placed.name)
        pattern = problem.pieces[i].outline
        wp_pts = placement.to_wallpaper(pattern, np.full(len(pattern), i))
        fabric_pts = affine(placed.transform, pattern)
        assert fabric.mismatch_distance(fabric_pts, wp_pts).max() < 1e-6


def test_lattice_basis_is_reduced_for_the_covering_radius():
    """A skewed description of the square lattice gives the square's covering radius."""
    skew = NestProblem([l_piece()], width=80.0,
                       fabric=Wallpaper("p1", (10.0, 0.0), (30.0, 10.0)))
    assert covering_radius(skew.lattice) == pytest.approx(10 / np.sqrt(2))
    assert abs(np.linalg.det(skew.lattice)) == pytest.approx(100.0)


def test_quarter_turns_on_a_p4_print(data_dir):
    """jakobs1 allows 0/90/180/270: on a p4 print all four are print symmetries."""
    problem = load_esicup(data_dir / "nesting" / "jakobs1.json")
    problem.fabric = Wallpaper("p4", (2.0, 0.0), (0.0, 2.0), origin=(0.5, 0.25))
    items = problem.items()
    assert all(len(it.candidates) == 4 for it in items)
    layout = nest(problem, time_limit=2, seed=0, method="fill")
    assert verify_layout(layout, problem) == []
    _assert_moves_are_symmetries(layout, problem)
    assert {round(p.angle_deg) % 360 for p in layout.pieces} <= {0, 90, 180, 270}
    # on p1 the same pieces may not turn at all
    problem.fabric = Wallpaper("p1", (2.0, 0.0), (0.0, 2.0))
    assert all(len(it.candidates) == 1 for it in problem.items())


def test_console_on_an_instance_under_a_print_draws_the_print(data_dir, tmp_path, capsys):
    from station.cli import main

    fabric = tmp_path / "FABRIC.json"
    fabric.write_text(json.dumps({"group": "p4m", "w1": [2, 0], "w2": [0, 2], "units": "mm"}))
    out, png = tmp_path / "LAYOUT.json", tmp_path / "marker.png"
    rc = main(["nest", str(data_dir / "nesting" / "jakobs1.json"), "-o", str(out), "--fabric",
               str(fabric), "--time", "1", "--json", "--png", str(png)])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["printed"] and summary["pieces"] == 25
    layout = Layout.load(out)
    assert layout.fabric["group"] == "p4m"
    import cv2

    img = cv2.imread(str(png))
    assert img is not None and img.std() > 10  # a print, not a blank sheet
    assert main(["nest", str(data_dir / "nesting" / "jakobs1.json"), "-o", str(out),
                 "--length", "5", "--time", "1"]) == 2
    assert "do not fit" in capsys.readouterr().err
