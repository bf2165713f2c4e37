"""Bites (issue 35): a marker longer than the table cut in windows, no piece on a boundary."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from solver.nest import Layout, NestProblem, Piece, load_esicup, nest_plain, verify_layout
from solver.nest.bites import nest_in_bites, plan_bites
from solver.nest.lattice import nest_lattice
from solver.nest.layout import build_layout
from solver.wallpaper import Wallpaper

SHIRTS = Path(__file__).resolve().parents[1] / "data" / "nesting" / "shirts.json"


def _rectangles(*spans: tuple[float, ...], gap: float = 1.0, width: float = 100.0
                ) -> Layout:
    """Plain 20 mm high rectangles at the given x spans (a hand-made marker), from y = 5
    or the span's third number."""
    problem = NestProblem([Piece(f"r{i}", [[a, y], [b, y], [b, y + 20], [a, y + 20]])
                           for i, (a, b, y) in enumerate(s + (5.0,)[:3 - len(s)]
                                                         for s in spans)],
                          width=width, gap=gap)
    moves = [np.array([[1.0, 0, 0], [0, 1.0, 0]])] * len(spans)
    return build_layout(problem, problem.items(), moves)


def _assert_bites_are_sound(plan, window: float, ids: list[str]) -> None:
    """Every piece in exactly one bite, inside its window by the gap; bites in order."""
    cut = [pid for b in plan.bites for pid in b.pieces]
    assert sorted(cut) == sorted(ids) and len(cut) == len(set(cut))
    by_id = {p.id: p for p in plan.layout.pieces}
    gap = plan.layout.gap
    for bite in (b for b in plan.bites if b.pieces):
        xs = np.concatenate([by_id[pid].outline[:, 0] for pid in bite.pieces])
        assert xs.min() >= bite.start_mm + gap - 1e-9
        assert xs.max() <= bite.start_mm + window - gap + 1e-9
        assert xs.max() <= bite.end_mm - gap + 1e-9
    for bite, later in zip(plan.bites, plan.bites[1:]):  # no piece straddles a boundary
        xs = [by_id[pid].outline[:, 0].min() for pid in later.pieces]
        assert min(xs, default=np.inf) >= bite.end_mm + gap - 1e-9
    starts = np.array([b.start_mm for b in plan.bites])
    assert np.all(np.diff(starts) > 0)
    assert all(b.end_mm <= b.start_mm + window + 1e-9 for b in plan.bites)
    advances = [b.advance_commanded_mm for b in plan.bites]
    assert advances[0] == 0.0 and np.allclose(advances[1:], np.diff(starts))
    assert max(advances) <= window


def test_a_piece_on_the_boundary_moves_on_by_what_it_needs():
    # window 100, gap 1: r1 (62..122) straddles x = 100; it and everything after it move
    # on by 1 mm so that the boundary (after r0, at 62) has a gap on each side
    layout = _rectangles((1, 61), (62, 122), (130, 150))
    plan = plan_bites(layout, 100.0)
    assert [b.pieces for b in plan.bites] == [("r0#1",), ("r1#1", "r2#1")]
    assert plan.bites[1].start_mm == pytest.approx(62.0)
    assert plan.boundary_cost_mm == pytest.approx(1.0)
    assert plan.layout.length == pytest.approx(layout.length + 1.0)
    assert plan.layout.pieces[2].outline[:, 0].min() == pytest.approx(131.0)
    assert plan.layout.pieces[0] is layout.pieces[0]  # the first bite's pieces stay
    _assert_bites_are_sound(plan, 100.0, [p.id for p in layout.pieces])


def test_pulled_back_pieces_fill_the_hole_the_block_move_left():
    # the first bite keeps r0 and r3 (ends 61, 80); r1 straddles x = 100, so r1 and r2
    # move on by a whole repeat, 50 mm. Pulled back, r2 cannot go back along its row (r1
    # is there) but goes back by (-50, 50): beside r1, and the marker ends with r1
    layout = _rectangles((1, 61), (62, 122), (130, 150), (62, 80, 40.0))
    lattice = np.array([[50.0, 0.0], [0.0, 50.0]])
    moved = plan_bites(layout, 100.0, lattice=lattice)
    pulled = plan_bites(layout, 100.0, lattice=lattice, pull=True)
    assert [p.outline[:, 0].min() for p in moved.layout.pieces] == [1, 112, 180, 62]
    assert [p.outline[:, 0].min() for p in pulled.layout.pieces] == [1, 112, 130, 62]
    assert pulled.layout.pieces[2].outline[:, 1].min() == 55.0
    assert (moved.layout.length, pulled.layout.length) == (201.0, 173.0)
    assert verify_layout(pulled.layout) == []
    _assert_bites_are_sound(pulled, 100.0, [p.id for p in layout.pieces])


def test_on_a_print_the_rest_moves_by_a_whole_repeat():
    layout = _rectangles((1, 61), (62, 122), (130, 150))
    plan = plan_bites(layout, 100.0, lattice=np.array([[10.0, 3.0], [0.0, 10.0]]))
    # the shortest lattice move at least 1 mm along the roll that keeps the block on the
    # fabric (the block's y, 5..25, may move by -4..74): 7 w2 - 2 w1 = (1, 70) beats
    # 4 w2 - w1 = (2, 40) and w2 = (3, 10)
    assert np.allclose(plan.shifts[0], [1.0, 70.0]) and plan.boundary_cost_mm == 1.0
    moved = plan.layout.pieces[1]
    assert np.allclose(moved.transform[:, 2] - layout.pieces[1].transform[:, 2], [1.0, 70.0])
    narrow = plan_bites(_rectangles((1, 61), (62, 122), (130, 150), width=60.0), 100.0,
                        lattice=np.array([[10.0, 3.0], [0.0, 10.0]]))
    assert np.allclose(narrow.shifts[0], [3.0, 10.0])  # a 60 mm roll: only -4..34 across


def test_a_marker_that_fits_is_one_bite_and_costs_nothing():
    layout = _rectangles((1, 61), (62, 98))
    plan = plan_bites(layout, 100.0)
    assert len(plan.bites) == 1 and plan.boundary_cost_mm == 0.0
    assert plan.layout.length == layout.length


def test_a_capped_advance_keeps_cloth_in_view_and_may_roll_on_without_cutting():
    # after the first boundary r1 lies at 63..153; advances of at most 50 mm bring the
    # window to 50..150 first, where it does not fit: that bite cuts nothing, the next
    # advance (12 mm) brings r1 into view, and r2 comes after the last 50 mm
    layout = _rectangles((1, 61), (62, 152), (155, 175))
    plan = plan_bites(layout, 100.0, max_advance_mm=50.0)
    assert [len(b.pieces) for b in plan.bites] == [1, 0, 1, 1]
    assert [b.advance_commanded_mm for b in plan.bites] == pytest.approx([0, 50, 12, 50])
    assert plan.boundary_cost_mm == pytest.approx(1.0)
    _assert_bites_are_sound(plan, 100.0, [p.id for p in layout.pieces])
    with pytest.raises(ValueError, match="within the 100 mm window"):
        plan_bites(layout, 100.0, max_advance_mm=120.0)


def test_a_piece_longer_than_the_window_is_named():
    with pytest.raises(ValueError, match=r"piece 'r1#1' is 120.0 mm along the roll; a bite "
                       r"of the table's 100 mm window holds 98 mm"):
        plan_bites(_rectangles((1, 61), (62, 182)), 100.0)


@pytest.fixture(scope="module")
def shirts_plain():
    problem = load_esicup(SHIRTS)  # 99 pieces on a roll 40 wide, ~68 long
    return problem, nest_plain(problem, time_limit=2, seed=3)


@pytest.mark.parametrize("window", [20.0, 30.0])
def test_a_real_marker_in_bites_is_valid_and_reports_its_cost(shirts_plain, window):
    problem, layout = shirts_plain
    plan = plan_bites(layout, window)
    assert verify_layout(plan.layout, problem) == []
    _assert_bites_are_sound(plan, window, [p.id for p in layout.pieces])
    assert len(plan.bites) >= np.ceil(layout.length / window)
    assert plan.boundary_cost_mm == pytest.approx(sum(s[0] for s in plan.shifts))
    assert 0.0 < plan.boundary_cost_mm < layout.length  # boundaries cost, not double
    summary = plan.summary()
    assert summary["length_unbounded_mm"] == pytest.approx(layout.length, abs=1e-3)
    assert summary["bites"] == len(plan.bites)


def test_a_printed_marker_keeps_every_piece_on_its_print():
    problem = load_esicup(SHIRTS)
    problem.fabric = Wallpaper("p2", (1.0, 0.0), (0.3, 0.9))
    layout = nest_lattice(problem, time_limit=1.5, seed=0, strategies=("fill",))
    for pull in (False, True):
        plan = plan_bites(layout, 20.0, lattice=problem.lattice, pull=pull)
        assert verify_layout(plan.layout, problem) == []  # each piece against the print
        _assert_bites_are_sound(plan, 20.0, [p.id for p in layout.pieces])
    frac = np.linalg.solve(problem.lattice, np.array(plan.shifts).T)
    assert np.allclose(frac, np.round(frac), atol=1e-9)


def test_the_nest_in_bites_reports_against_the_free_nest_and_drops_its_fences():
    problem = load_esicup(SHIRTS)
    plan = nest_in_bites(problem, 30.0, time_limit=2.0, seed=0)
    assert verify_layout(plan.layout, problem) == [] and not plan.layout.keepouts
    _assert_bites_are_sound(plan, 30.0, [i.id for i in problem.items()])
    assert plan.length_unbounded_mm <= plan.layout.length  # the free nest, no boundaries
    with pytest.raises(ValueError, match="no length limit"):
        nest_in_bites(NestProblem(problem.pieces, 40.0, length=60.0), 30.0)
