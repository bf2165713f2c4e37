"""``--time T`` is one deadline that every nesting stage reads (issue 18 part 3).

Timing asserts would be flaky on a loaded machine, so these tests drive the stages with
an injected clock and check the mechanism: shares come from what is left, a fill that
must give a result finishes, later ones stop, sparrow is cut at the deadline. The
wall-time ratios themselves are measured in ``bench/nest.py`` (BENCHMARKS.md).
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from solver.nest import NestProblem, Piece, load_esicup, verify_layout
from solver.nest.budget import Deadline, deadline_of, finish_reserve
from solver.nest.engine import fill_search
from solver.nest.plain import Late, spyrrow_pack
from solver.nest.solve import nest
from solver.wallpaper import Wallpaper

DATA = Path(__file__).resolve().parents[1] / "data"


class Clock:
    """A monotonic clock that jumps: ``now`` is set by the test."""

    def __init__(self, now: float = 0.0) -> None:
        self.now = now

    def __call__(self) -> float:
        return self.now


class ExpiresAfter:
    """A clock at 0 for its first ``n`` readings, far past any deadline afterwards."""

    def __init__(self, n: int) -> None:
        self.n = n

    def __call__(self) -> float:
        self.n -= 1
        return 0.0 if self.n >= 0 else 1e6


def test_deadline_shares_come_from_what_is_left():
    clock = Clock(10.0)
    d = Deadline(8.0, clock=clock)
    assert d.left() == 8.0 and not d.expired()
    clock.now = 14.0  # a stage overran: the next share shrinks, the end does not move
    half = d.share(0.5)
    assert half.end == 16.0 and d.end == 18.0
    assert d.before(1.0).end == 17.0 and d.within(1.0).end == 15.0 and d.within(99).end == 18.0
    clock.now = 18.5
    assert d.expired() and d.left() == 0.0 and d.share(0.5).left() == 0.0
    assert deadline_of(d) is d and deadline_of(3).left() == pytest.approx(3, abs=0.5)
    assert finish_reserve(100) > finish_reserve(1) > 0


@pytest.fixture(scope="module")
def printed_tshirt():
    from solver.garment import load_garment

    g = load_garment(DATA / "garments" / "berkeley" / "tshirt-coarse.obj", units="m")
    pieces = [Piece(f"p{i}", g.piece_outline(i)) for i in range(g.n_pieces)]
    return NestProblem(pieces, 1500.0, gap=2.0, fabric=Wallpaper("p2", (50.0, 0.0), (0.0, 50.0)))


def test_the_first_fill_finishes_past_the_deadline_and_no_other_starts(printed_tshirt):
    problem, items = printed_tshirt, printed_tshirt.items()
    said: list[str] = []
    r = fill_search(problem, items, time_limit=Deadline(0.0), seed=0, progress=said.append)
    assert r is not None and len(r[0]) == len(items)
    assert [m for m in said if "run" in m] and all("run 1 " in m for m in said)
    # a caller that holds another result gets nothing rather than a late fill
    assert fill_search(problem, items, time_limit=Deadline(0.0), seed=0,
                       interruptible=True) is None


def test_an_expired_budget_still_gives_a_verified_printed_marker(printed_tshirt):
    """Every stage reads the one deadline: no time for a fill that must finish, so the
    naive marker (sparrow's first feasible one, snapped) comes first; the searches that
    would improve on it are cut at the deadline, and what is left is verified."""
    said: list[str] = []
    layout = nest(printed_tshirt, time_limit=Deadline(0.0, clock=ExpiresAfter(0)), seed=0,
                  progress=said.append)
    assert verify_layout(layout, printed_tshirt) == []
    assert len(layout.pieces) == len(printed_tshirt.items())
    strategies = [m.split(":")[0] for m in said if "density" in m and "run" not in m
                  and not m.startswith("spyrrow")]
    assert strategies == ["naive"]


def test_with_time_for_a_fill_the_searches_give_the_marker(printed_tshirt):
    said: list[str] = []
    layout = nest(printed_tshirt, time_limit=2.0, seed=0, progress=said.append)
    assert verify_layout(layout, printed_tshirt) == []
    strategies = [m.split(":")[0] for m in said if "density" in m and "run" not in m
                  and not m.startswith("spyrrow")]
    # the fill after it may be cut on a loaded machine; the naive fallback is not needed
    assert strategies[0] == "resnap-margin" and "naive" not in strategies


def test_sparrow_is_cut_at_the_deadline_with_its_best_feasible_marker():
    problem = load_esicup(DATA / "nesting" / "shirts.json")
    shapes = {i: (p.outline, p.quantity, p.orientations) for i, p in enumerate(problem.pieces)}
    said: list[str] = []
    # the clock reads 0 while sparrow is given 3 s of search, then jumps past the deadline
    t0 = time.monotonic()
    placed, length = spyrrow_pack(shapes, problem.width, seed=0, progress=said.append,
                                  time_limit=Deadline(3.0, clock=ExpiresAfter(2)))
    took = time.monotonic() - t0
    assert any("deadline" in m for m in said)
    assert sum(len(v) for v in placed.values()) == len(problem.items())
    assert length >= problem.piece_area / problem.width
    assert took < 2.5, f"sparrow ran its own {took:.1f} s instead of stopping at the deadline"


def test_a_search_that_may_be_cut_does_not_wait_for_sparrow_past_its_deadline():
    """With another marker in hand, a late sparrow run is given up (its constructive start
    alone takes over 0.1 s on the 99 shirts), not waited for."""
    problem = load_esicup(DATA / "nesting" / "shirts.json")
    shapes = {i: (p.outline, p.quantity, p.orientations) for i, p in enumerate(problem.pieces)}
    with pytest.raises(Late):
        spyrrow_pack(shapes, problem.width, seed=0, interruptible=True,
                     time_limit=Deadline(0.0, clock=ExpiresAfter(0)))
