"""Nesting on cut lines: the gap really kept, the sew line checked, the transform shared."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from solver.garment import load_garment
from solver.nest import NestProblem, build_layout, verify_layout
from solver.nest.instance import load_esicup
from solver.nest.plain import inflate
from solver.nest.sources import garment_pieces


def _instances(data_dir, shared):
    files = [data_dir / "nesting" / "jakobs1.json", data_dir / "nesting" / "shirts.json"]
    if shared is not None:
        files += [shared / "nesting" / "fu.json", shared / "nesting" / "albano.json"]
    return files


@pytest.mark.parametrize("with_shared", [False, True])
def test_inflated_shapes_hold_the_whole_gap(data_dir, request, with_shared):
    """`nest fu.json --gap 1` failed its own verification: inflate simplified away the
    square cut of a sharp mitre, and two such corners came closer than the gap."""
    shared = request.getfixturevalue("shared_data") if with_shared else None
    for path in _instances(data_dir, shared):
        for piece in load_esicup(path).pieces:
            for d in (0.5, 1.5):
                grown = shapely.Polygon(inflate(piece.outline, d))
                exact = shapely.Polygon(piece.outline).buffer(d, quad_segs=32)
                assert exact.difference(grown).area < 1e-6 * exact.area, (path.name, piece.name)


def test_layout_moves_sew_line_with_the_cut_line_and_checks_it(data_dir):
    g = load_garment(data_dir / "garments" / "berkeley" / "skirt-coarse.obj", units="m")
    pieces = garment_pieces(g)
    problem = NestProblem(pieces, 3000.0, gap=2.0)
    items = problem.items()
    moves, x = [], 0.0
    for it in items:  # a simple row, each piece turned by 180 degrees
        ref = it.ref
        m = np.array([[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
        lo = (ref @ m[:, :2].T).min(0)
        m[:, 2] = [x + 2.0 - lo[0], 2.0 - lo[1]]
        x = float((ref @ m[:, :2].T + m[:, 2])[:, 0].max())
        moves.append(m)
    layout = build_layout(problem, items, moves)
    assert verify_layout(layout, problem) == []
    for placed, piece in zip(layout.pieces, pieces):
        t = placed.transform
        np.testing.assert_allclose(placed.sew_line, piece.sew_line @ t[:, :2].T + t[:, 2])
        assert shapely.Polygon(placed.outline).contains(shapely.Polygon(placed.sew_line))
    back = type(layout).from_dict(layout.to_dict())
    np.testing.assert_allclose(back.pieces[0].allowance, pieces[0].allowance)
    back.pieces[0].sew_line = back.pieces[0].sew_line + [5000.0, 0.0]
    assert any("sew line leaves the cut line" in f for f in verify_layout(back))
