"""The dotted-board model (CP-SAT on every allowed position): valid, exact, on time.

Real pieces (the bundled Berkeley shorts' cut lines) on 50 mm p1 and p2 prints; a tiny
instance on an oblique lattice against brute-force enumeration.
"""

from __future__ import annotations

import itertools
import math
import time

import numpy as np
import pytest
import shapely

from solver.garment import load_garment
from solver.nest import NestProblem, Piece, verify_layout
from solver.nest.dotted import dotted_nest, narrow_bound
from solver.nest.instance import affine
from solver.nest.lattice import nest_lattice
from solver.nest.layout import build_layout
from solver.nest.sources import garment_pieces
from solver.wallpaper import Wallpaper
from tests.conftest import DATA
from tests.solver.test_nest_dense import _assert_on_print


@pytest.fixture(scope="module")
def shorts() -> list[Piece]:
    g = load_garment(DATA / "garments" / "berkeley" / "shorts-iso.obj", units="m")
    return garment_pieces(g)


def _columns(problem: NestProblem, items) -> list[np.ndarray]:
    """A valid, loose marker: the pieces in columns across the roll on allowed positions,
    more than a lattice step apart (the hint a caller would have from a weak strategy)."""
    basis, moves = problem.lattice, []
    x, y, right = problem.gap, problem.gap, problem.gap
    for it in items:
        c = it.candidates[0]
        lo, hi = affine(c, it.ref).min(0), affine(c, it.ref).max(0)
        if y + hi[1] - lo[1] + 55.0 > problem.width - problem.gap:  # a new column
            x, y = right + 55.0, problem.gap
        m = c.copy()
        m[:, 2] += basis @ np.ceil(np.linalg.solve(basis, np.array([x, y]) - lo))
        moves.append(m)
        ring = affine(m, it.ref)
        y, right = ring[:, 1].max() + 55.0, max(right, ring[:, 0].max())
    return moves


@pytest.mark.parametrize("group", ["p1", "p2"])
def test_dotted_shortens_a_loose_marker_and_keeps_the_print(shorts, group):
    problem = NestProblem(shorts, 1500.0, gap=2.0,
                          fabric=Wallpaper(group, (50.0, 0.0), (0.0, 50.0), origin=(7.0, 3.0)))
    items = problem.items()
    hint = _columns(problem, items)
    loose = build_layout(problem, items, hint)
    assert verify_layout(loose, problem) == []
    # proven optimal after 1.4 s (p1) and 3.0 s (p2) on an idle machine: room for load
    r = dotted_nest(problem, items, time_limit=8.0, hint=hint)
    assert r is not None and r.moves is not None
    layout = build_layout(problem, items, r.moves)
    assert verify_layout(layout, problem) == []
    _assert_on_print(layout, problem)
    assert layout.length == pytest.approx(r.length)
    # the hint is where CP-SAT starts: never longer; a row of four leaves much to gain
    assert r.length <= 0.85 * loose.length
    area_bound = problem.gap + problem.piece_area / (problem.width - 2 * problem.gap)
    assert area_bound - 0.02 <= r.bound <= r.length + 1e-9
    if r.optimal:
        assert r.bound == pytest.approx(r.length, abs=0.011)


def _tiny(w2: tuple, origin: tuple) -> NestProblem:
    """Three small pieces (an L twice, a triangle) on a 45 mm roll (two fit across), a p2 print."""
    ell = Piece("ell", [(0, 0), (24, 0), (24, 9), (9, 9), (9, 20), (0, 20)], quantity=2)
    tri = Piece("tri", [(0, 0), (26, 0), (5, 17)])
    return NestProblem([ell, tri], 45.0, gap=1.0,
                       fabric=Wallpaper("p2", (11.0, 0.0), w2, origin=origin))


def _brute_force(problem: NestProblem, items, limit: float, period: float = 0.0) -> float:
    """The shortest marker up to ``limit``, by enumerating every combination of positions
    (each made here from the lattice and the print's operations, independently); with a
    ``period`` along the roll, the marker may start at any phase (span plus the gaps)."""
    g, basis = problem.gap, problem.lattice
    polys, lefts, rights = [], [], []
    k = np.stack(np.meshgrid(np.arange(-30, 31), np.arange(-30, 31)), -1).reshape(-1, 2)
    inner = shapely.box(g - 1e-9, g - 1e-9, limit + period - g + 1e-9,
                        problem.width - g + 1e-9)
    for it in items:
        p = np.concatenate([shapely.polygons(affine(c, it.ref)[None] + (k @ basis.T)[:, None])
                            for c in it.candidates])
        p = p[shapely.contains(inner, p)]
        polys.append(p)
        lefts.append(shapely.bounds(p)[:, 0])
        rights.append(shapely.bounds(p)[:, 2])
    pairs = {}
    for a, b in itertools.combinations(range(len(items)), 2):
        pa, pb = polys[a][:, None], polys[b][None, :]
        overlap = shapely.area(shapely.intersection(pa, pb)) > 1e-9
        pairs[a, b] = overlap | (shapely.distance(pa, pb) < g - 1e-9)
    assert len(items) == 3
    ok = ~(pairs[0, 1][:, :, None] | pairs[0, 2][:, None, :] | pairs[1, 2][None, :, :])
    ends = np.maximum(np.maximum(rights[0][:, None, None], rights[1][None, :, None]),
                      rights[2][None, None, :])
    if period:
        ends = ends - np.minimum(np.minimum(lefts[0][:, None, None], lefts[1][None, :, None]),
                                 lefts[2][None, None, :]) + g
    return float(ends[ok].min()) + g if ok.any() else math.inf


@pytest.mark.parametrize("w2, origin", [((4.0, 9.0), (3.0, 1.0)),  # oblique
                                        ((0.0, 9.0), (0.0, 0.0))])  # across: one piece low
def test_dotted_optimum_equals_brute_force(w2, origin):
    problem = _tiny(w2, origin)
    items = problem.items()
    limit = 90.0
    best = _brute_force(problem, items, limit)
    assert np.isfinite(best) and best < limit - 5  # a real, constrained choice
    assert best > 2 * 24 + 3 * problem.gap  # two pieces across at most, the lattice costs more
    r = dotted_nest(problem, items, time_limit=10.0, limit=limit)
    assert r is not None and r.optimal and r.moves is not None
    assert r.length == pytest.approx(best, abs=1e-6)
    assert r.bound == pytest.approx(best, abs=0.011)
    layout = build_layout(problem, items, r.moves)
    assert verify_layout(layout, problem) == []
    _assert_on_print(layout, problem)
    # just below the optimum: proven empty
    none = dotted_nest(problem, items, time_limit=10.0, limit=best - 0.05)
    assert none is not None and none.moves is None and none.optimal
    # bisection from a loose marker lands on the optimum too
    start = dotted_nest(problem, items, time_limit=10.0, hint=_columns(problem, items))
    start.bound = 0.0
    narrowed = narrow_bound(problem, items, start, time_limit=10.0, probe=5.0)
    assert narrowed.length == pytest.approx(best, abs=1e-6)
    assert best - 0.5 <= narrowed.bound <= best


def test_dotted_respects_its_deadline(shorts):
    import ortools.sat.python.cp_model  # noqa: F401  (a process pays its import once)

    problem = NestProblem(shorts, 1500.0, gap=2.0,
                          fabric=Wallpaper("p2", (50.0, 0.0), (0.0, 50.0)))
    items = problem.items()
    # 1 s three times: built fast, the model left the solver 0.2 s, which it overran by
    # 0.6 s in its first presolve pass (one run in three; SOLVE_MIN)
    for limit in (0.0, 0.3, 1.0, 1.0, 1.0):
        t0 = time.monotonic()
        r = dotted_nest(problem, items, time_limit=limit, limit=2000.0)
        assert time.monotonic() - t0 <= 1.1 * limit + 0.25  # the nest's promise: 10 %
        if r is not None and r.moves is not None:
            assert verify_layout(build_layout(problem, items, r.moves), problem) == []


def test_nest_lattice_runs_the_model_on_few_pieces_and_keeps_the_budget(shorts):
    problem = NestProblem(shorts, 1500.0, gap=2.0,
                          fabric=Wallpaper("p2", (50.0, 0.0), (0.0, 50.0)))
    said: list[str] = []
    t0 = time.monotonic()
    layout = nest_lattice(problem, time_limit=4.0, seed=0, progress=said.append)
    assert time.monotonic() - t0 <= 4.4
    assert verify_layout(layout, problem) == []
    assert any("allowed positions, model built" in s for s in said)  # it ran, on time


@pytest.mark.parametrize("origin", [(0.0, 0.0), (3.0, 1.0)])
def test_dotted_any_phase_equals_brute_force(origin):
    """A marker that may start at any phase of the print is never longer, and its
    optimum (span plus the gaps) is brute force's over every start, whatever the print's
    phase at the roll's start."""
    problem = _tiny((0.0, 9.0), origin)
    items = problem.items()
    fixed = _brute_force(problem, items, 90.0)
    best = _brute_force(problem, items, 90.0, period=11.0)
    assert best < fixed and best == pytest.approx(59.0)  # (the two origins' fixed: 67, 62)
    r = dotted_nest(problem, items, time_limit=10.0, limit=90.0, any_phase=True)
    assert r is not None and r.optimal and r.moves is not None
    assert r.length == pytest.approx(best, abs=1e-6)
    assert r.bound == pytest.approx(best, abs=0.021)
    layout = build_layout(problem, items, r.moves)
    assert verify_layout(layout, problem) == []  # on the print, starting up to a period in
    assert layout.length - r.length < 11.0 + 1e-6
    none = dotted_nest(problem, items, time_limit=10.0, limit=best - 0.05, any_phase=True)
    assert none is not None and none.moves is None and none.optimal
