"""Denser printed markers: joint snapping of free nests, strip shrinking on the cosets.

Real pieces (the bundled Berkeley t-shirt's cut lines) on a 50 mm print; every layout
passes the exact verifier and keeps the print under every piece (sampled points).
"""

from __future__ import annotations

import itertools
import time

import numpy as np
import pytest
import shapely

from solver.garment import load_garment
from solver.nest import NestProblem, Piece, verify_layout
from solver.nest.budget import Deadline
from solver.nest.coset import CosetSearch, coset_search
from solver.nest.instance import affine, compose, invert
from solver.nest.layout import build_layout
from solver.nest.plain import plain_moves
from solver.nest.regions import conflicting, snap_to_lattice
from solver.nest.snapjoint import (
    REACHES,
    collide,
    earlier_nests,
    joint_snap,
    snap_nests,
    snap_options,
)
from solver.nest.sources import garment_pieces
from solver.wallpaper import Wallpaper, covering_radius
from tests.conftest import DATA


@pytest.fixture(scope="module")
def tshirt() -> list[Piece]:
    g = load_garment(DATA / "garments" / "berkeley" / "tshirt-coarse.obj", units="m")
    return garment_pieces(g)


@pytest.fixture(scope="module")
def printed(tshirt) -> NestProblem:
    return NestProblem(tshirt, 1500.0, gap=2.0,
                       fabric=Wallpaper("p2", (50.0, 0.0), (0.0, 50.0), origin=(7.0, 3.0)))


@pytest.fixture(scope="module")
def free(printed):
    """A tight free nest that does not depend on timing: the pieces in a row, 3 mm apart
    (the gap is 2), at an offset that is no lattice vector."""
    items = printed.items()
    moves, x = [], 9.3
    for it in items:
        m = it.candidates[0].copy()
        ring = affine(m, it.ref)
        m[:, 2] += np.array([x, 307.7]) - ring.min(0)
        moves.append(m)
        x = affine(m, it.ref)[:, 0].max() + 3.0
    return items, (moves, x - 1.0)


def _assert_on_print(layout, problem) -> None:
    """The print under sampled points of every placed piece is the print there before."""
    wp = problem.fabric
    rng = np.random.default_rng(1)
    by_name = {p.name: p for p in problem.pieces}
    for placed in layout.pieces:
        piece = by_name[placed.name]
        g = compose(placed.transform, invert(piece.base))
        lo, hi = piece.outline.min(0), piece.outline.max(0)
        pts = rng.uniform(lo, hi, (32, 2))
        assert wp.mismatch_distance(affine(g, pts), pts).max() < 1e-6


def test_joint_snap_is_valid_where_nearest_snapping_collides(printed, free):
    items, (moves, _) = free
    items, moves = items[:4], moves[:4]  # a row of four: a choice exists within 4 steps
    free_len = max(affine(m, it.ref)[:, 0].max() for it, m in zip(items, moves)) + 2.0
    nearest = snap_to_lattice(printed, items, moves)
    polys = np.array([shapely.Polygon(affine(m, it.ref)) for it, m in zip(items, nearest)])
    assert conflicting(printed, polys).any()  # a tight free nest does not snap for free
    step = 50.0
    got = joint_snap(printed, items, moves, reach=1.5 * step, push=4 * step,
                     deadline=time.monotonic() + 10)
    assert got is not None
    snapped, length = got
    sub = NestProblem(printed.pieces[:4], printed.width, gap=printed.gap,
                      fabric=printed.fabric)
    assert [it.id for it in sub.items()] == [it.id for it in items]
    layout = build_layout(sub, items, snapped)
    assert verify_layout(layout, sub) == []
    _assert_on_print(layout, sub)
    assert length == pytest.approx(layout.length)
    # every piece stays where the free nest put it, up to the reach (and push along x)
    for it, a, b in zip(items, moves, snapped):
        c = np.asarray(shapely.Polygon(it.ref).centroid.coords[0])
        d = affine(b, c)[0] - affine(a, c)[0]
        assert -1.5 * step - 1e-6 <= d[0] <= 5.5 * step + 1e-6
        assert abs(d[1]) <= 1.5 * step + 1e-6
    # a row of n pieces loses at most a lattice step per piece to the snap
    assert length <= free_len + len(items) * step


def test_joint_snap_finds_the_shortest_choice_by_brute_force(printed, free):
    """Three neighbouring pieces: the search's optimum equals full enumeration's."""
    items, (moves, _) = free
    sub_items, sub_moves = items[:3], moves[:3]
    reach, push = 50.0, 100.0
    got = joint_snap(printed, sub_items, sub_moves, reach=reach, push=push)
    opts = [snap_options(printed, it, m, reach, push) for it, m in zip(sub_items, sub_moves)]
    # every combination at once: pairwise collisions broadcast over the three choices
    clash = {(a, b): collide(opts[a][1][:, None], opts[b][1][None, :], printed.gap)
             for a, b in itertools.combinations(range(3), 2)}
    ok = ~(clash[0, 1][:, :, None] | clash[0, 2][:, None, :] | clash[1, 2][None, :, :])
    right = [shapely.bounds(p)[:, 2] for _, p in opts]
    ends = np.maximum(np.maximum(right[0][:, None, None], right[1][None, :, None]),
                      right[2][None, None, :])
    best = ends[ok].min() + printed.gap if ok.any() else np.inf
    assert sum(len(p) for _, p in opts) > 30 and not ok.all()  # a real, constrained choice
    assert np.isfinite(best) and got is not None and got[1] == pytest.approx(best)
    # and none when a table too short leaves no collision-free choice
    short = NestProblem(printed.pieces, printed.width, length=best - 1.0, gap=printed.gap,
                        fabric=printed.fabric)
    assert joint_snap(short, sub_items, sub_moves, reach=reach, push=push) is None


def test_coset_shrink_shortens_a_loose_marker_on_the_print(printed):
    """A valid but loose marker (pieces in a row) gets shorter; moves stay symmetries."""
    items = printed.items()
    basis = printed.lattice
    moves, x = [], 2.0
    for it in items:  # each piece left to right with about a lattice step between
        c = it.candidates[0]
        ring = affine(c, it.ref)
        f = np.ceil(np.linalg.solve(basis, np.array([x, 2.0]) - ring.min(0)))
        m = c.copy()
        m[:, 2] += basis @ f
        moves.append(m)
        x = affine(m, it.ref)[:, 0].max() + 52.0
    loose = build_layout(printed, items, moves)
    assert verify_layout(loose, printed) == []
    got = coset_search(printed, items, time_limit=3.0, seed=0, start=moves)
    assert got is not None
    layout = build_layout(printed, items, got[0])
    assert verify_layout(layout, printed) == []
    _assert_on_print(layout, printed)
    assert layout.length < 0.7 * loose.length


@pytest.mark.parametrize("gap", [0.0, 2.0])
def test_separation_resolves_collisions_on_the_cosets(printed, gap):
    """Two pieces put on the same spot are separated by allowed moves only."""
    problem = NestProblem(printed.pieces[:2], 1500.0, gap=gap, fabric=printed.fabric)
    items = problem.items()
    search = CosetSearch(problem, items, 1500.0, 6.0, np.random.default_rng(0))
    sol = [(0, np.zeros(2)), (0, np.zeros(2))]
    for k, it in enumerate(items):  # both pieces' lower left corners near (100, 100)
        lo = affine(it.candidates[0], it.ref).min(0)
        sol[k] = (0, problem.lattice @ np.ceil(np.linalg.solve(problem.lattice, 100.0 - lo)))
    polys = np.array([search.polygon(k, p) for k, p in enumerate(sol)], dtype=object)
    assert len(search.collisions(polys)[0]) == 1
    assert search.separate(sol, 1500.0, Deadline(3.0))
    polys = np.array([search.polygon(k, p) for k, p in enumerate(sol)], dtype=object)
    assert len(search.collisions(polys)[0]) == 0 and search.inside(polys, 1500.0).all()
    layout = build_layout(problem, items, [np.column_stack([it.candidates[c][:, :2],
                                                            it.candidates[c][:, 2] + t])
                                           for it, (c, t) in zip(items, sol)])
    assert verify_layout(layout, problem) == []
    _assert_on_print(layout, problem)


@pytest.fixture(scope="module")
def sparrow_run(tshirt):
    """One short sparrow run on the t-shirt under a p1 print (a quarter covering radius
    of margin, as the joint strategy nests): its final nest and the earlier ones."""
    problem = NestProblem(tshirt, 1500.0, gap=2.0,
                          fabric=Wallpaper("p1", (50.0, 0.0), (0.0, 50.0), origin=(7.0, 3.0)))
    items = problem.items()
    others: list = []
    free, free_len = plain_moves(problem, items, extra=0.25 * covering_radius(problem.lattice),
                                 time_limit=1.0, seed=0, others=others)
    return problem, items, free, free_len, others


def test_sparrow_reports_its_earlier_nests_as_valid_free_markers(tshirt):
    plain = NestProblem(tshirt, 1500.0, gap=2.0)
    items = plain.items()
    others: list = []
    _, length = plain_moves(plain, items, time_limit=1.0, seed=0, others=others)
    assert len(others) >= 2
    for moves, other_len in others[:: max(1, len(others) // 8)]:
        layout = build_layout(plain, items, moves)
        assert verify_layout(layout, plain) == []
        assert layout.length <= other_len + 1e-6 and other_len >= length - 1e-6


def test_earlier_nests_go_coarse_to_fine_within_reach():
    lengths = [800.0, 801.0, 806.0, 812.0, 826.0, 851.0, 875.0, 899.0, 1000.0]
    picked = [L for _, L in earlier_nests([(None, L) for L in lengths], 800.0, 50.0)]
    # a lattice step (50 mm) from the final nest first, then 25, 12.5 and 6.25 mm apart;
    # beyond 10 % longer (899, 1000) and within 6.25 mm of the final (801, 806) never
    assert picked == [851.0, 826.0, 875.0, 812.0]
    assert len(picked) == len(set(picked))


def test_snapping_earlier_nests_gives_a_valid_marker_no_longer_than_the_final_snaps(
        sparrow_run):
    problem, items, free, free_len, others = sparrow_run
    step = 50.0
    # sparrow's run is timed, so which reach snaps its final nest varies: take them all
    finals = [joint_snap(problem, items, free, reach=reach * step, push=push * step)
              for reach, push in REACHES]
    t0 = time.monotonic()
    got = snap_nests(problem, items, free, free_len, others, final=t0 + 30.0,
                     deadline=t0 + 4.0)
    assert got is not None  # the looser earlier nests snap even when the final one does not
    assert got[1] <= min([f[1] for f in finals if f is not None], default=np.inf) + 1e-9
    layout = build_layout(problem, items, got[0])
    assert verify_layout(layout, problem) == []
    _assert_on_print(layout, problem)
    assert layout.length == pytest.approx(got[1])


def test_snapping_earlier_nests_stops_at_its_deadline(sparrow_run):
    problem, items, free, free_len, others = sparrow_run
    assert len(earlier_nests(others, free_len, 50.0)) >= 2  # more work than the time given
    t0 = time.monotonic()
    assert snap_nests(problem, items, free, free_len, others, final=t0 - 1.0,
                      deadline=t0 - 1.0) is None
    for limit in (0.2, 0.5):
        t0 = time.monotonic()
        got = snap_nests(problem, items, free, free_len, others, final=t0 + limit / 2,
                         deadline=t0 + limit)
        assert time.monotonic() - t0 < limit + 0.25  # one step of the search past it at most
        if got is not None:
            assert verify_layout(build_layout(problem, items, got[0]), problem) == []
