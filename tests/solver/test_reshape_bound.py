"""Reshaping's bounds: no vertex moves more than ``max_move_mm``, no piece's area changes by
1 %, as constraints the line search never crosses (analytic cases and a real garment)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from solver.garment import load_garment
from solver.garment.refine import refined
from solver.placement import Placement
from solver.reshape import ReshapeOptions, reshape
from solver.reshape.energy import (
    MOVE_ONSET,
    area_barrier,
    max_area_step,
    max_bounded_step,
    move_barrier,
)
from solver.wallpaper import Wallpaper

BERKELEY = Path(__file__).resolve().parents[1] / "data" / "garments" / "berkeley"


def test_bounded_step_is_where_a_vertex_reaches_the_bound():
    rest = np.zeros((2, 2))
    uv = np.array([[3.0, 0.0], [0.0, 0.0]])
    assert max_bounded_step(uv, rest, np.array([[1.0, 0.0], [0.0, 0.0]]), 5.0) == 2.0
    assert max_bounded_step(uv, rest, np.array([[0.0, 1.0], [0.0, 0.0]]), 5.0) == 4.0
    # the second vertex, at rest, reaches the bound first when it moves fast
    both = np.array([[1.0, 0.0], [0.0, 10.0]])
    assert max_bounded_step(uv, rest, both, 5.0) == pytest.approx(0.5)
    assert max_bounded_step(uv, rest, np.zeros((2, 2)), 5.0) == np.inf


def test_move_barrier_is_zero_inside_infinite_at_the_bound_and_has_its_gradient():
    rest = np.zeros((1, 2))
    inside = np.array([[0.8 * 10.0, 0.0]])
    assert move_barrier(inside, rest, 10.0, 1.0)[0] == 0.0
    assert move_barrier(np.array([[6.0, 8.0]]), rest, 10.0, 1.0)[0] == np.inf
    uv = np.array([[7.0, 6.5]])  # |p| = 9.55: beyond the onset (9 mm)
    assert np.sum(uv**2) / 100.0 > MOVE_ONSET
    e, g = move_barrier(uv, rest, 10.0, 2.0)
    assert e > 0
    h = 1e-6
    for k in range(2):
        d = np.zeros_like(uv)
        d[0, k] = h
        num = (move_barrier(uv + d, rest, 10.0, 2.0)[0]
               - move_barrier(uv - d, rest, 10.0, 2.0)[0]) / (2 * h)
        assert g[0, k] == pytest.approx(num, rel=1e-5)


def test_area_step_stops_a_growing_piece_at_one_percent():
    uv = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 3.0]])
    faces = np.array([[0, 1, 2]])
    piece, area0 = np.zeros(1, np.int64), np.array([3.0])
    # scaling about the origin: A(t) = A0 (1 + t)^2 reaches 1.01 A0 at t = sqrt(1.01) - 1
    t = max_area_step(uv, faces, piece, area0, 0.01, uv.copy())
    assert t == pytest.approx(np.sqrt(1.01) - 1.0, rel=1e-12)
    assert area_barrier(uv * 1.004, faces, piece, area0, 0.01, 1.0)[0] == 0.0
    assert area_barrier(uv * 1.0049, faces, piece, area0, 0.01, 1.0)[0] > 0.0
    assert area_barrier(uv * 1.006, faces, piece, area0, 0.01, 1.0)[0] == np.inf


@pytest.mark.parametrize("bound", [3.0, 10.0])
def test_reshaping_never_moves_a_vertex_beyond_the_bound(bound):
    from solver.align import align

    g = load_garment(BERKELEY / "tshirt-coarse.obj", units="m")
    plaid = Wallpaper("pmm", (60.0, 0.0), (0.0, 80.0))
    placement = align(g, plaid, restarts=3, seed=0)
    new, report = reshape(g, placement, options=ReshapeOptions(max_move_mm=bound))
    base, _ = refined(g, plaid.covering_radius)  # the mesh reshaping started from
    move = np.hypot(*(new.uv - base.uv).T)
    assert move.max() <= bound
    assert move.max() > 0.5 * bound  # the bound is what stopped it, not a lack of need
    assert report.max_move_bound_mm == bound
    areas = new.piece_areas() / base.piece_areas()
    assert np.all(np.abs(areas - 1.0) <= 0.01)
    assert report.e_fit_after_mm2 < report.e_fit_before_mm2
    # every seam still sews: its two sides keep their length difference within 1 mm
    assert report.ease_change_max_mm <= 1.0
    assert report.roughness_max_mm <= 1.0  # the outlines stay fair
    assert [p["piece"] for p in report.pieces] == list(g.piece_names)
    # a set-in sleeve's cap runs tens of degrees off its armhole's direction under every
    # symmetry of a plaid: no reshape within the bound fits it, and the report says so
    sleeves = {s.piece_a for s in g.seam_lines if s.piece_a == s.piece_b}
    armholes = [s for s, line in zip(report.seams, g.seam_lines)
                if (line.piece_a in sleeves) != (line.piece_b in sleeves)]
    assert len(sleeves) == 2 and len(armholes) == 4
    for seam in armholes:
        assert seam["ideal_turn_deg"] > 30.0 and not seam["within_reach"]
        assert seam["seam"] in report.seams_out_of_reach
    body = [s for s, line in zip(report.seams, g.seam_lines)
            if line.piece_a not in sleeves and line.piece_b not in sleeves]
    assert all(s["ideal_turn_deg"] < 5.0 for s in body)


def test_a_bound_of_zero_is_refused():
    g = load_garment(BERKELEY / "pants-coarse.obj", units="m")
    p = Placement.identity(g.n_pieces, Wallpaper("p4m", (50.0, 0.0), (0.0, 50.0)))
    with pytest.raises(ValueError, match="largest move"):
        reshape(g, p, options=ReshapeOptions(max_move_mm=0.0))
