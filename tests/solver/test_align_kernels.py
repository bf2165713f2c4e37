"""The alignment's compiled search kernels against plain enumeration: the joint grid's
branch and bound, the grid tables' step lookups and the tree dynamic programme."""

from __future__ import annotations

import itertools
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from garments_synthetic import cut_sheet  # noqa: E402

from solver.align.brute import grid_tables  # noqa: E402
from solver.align.kernels import joint_grid_best  # noqa: E402
from solver.align.problem import AlignProblem  # noqa: E402
from solver.align.tree_dp import tree_dp_placement  # noqa: E402
from solver.wallpaper import Wallpaper  # noqa: E402

PRINTS = {
    "p1": ((31.0, 2.0), (9.0, 27.0)),
    "pmg": ((36.0, 0.0), (0.0, 25.0)),
    "cm": ((30.0, 18.0), (30.0, -18.0)),
    "p6m": ((30.0, 0.0), (-15.0, 15.0 * np.sqrt(3))),
}


@pytest.mark.parametrize("sizes", [(7, 5, 6, 4), (9, 8, 1, 1), (11, 1, 1, 1)])
def test_joint_grid_best_is_the_exhaustive_minimum(sizes):
    rng = np.random.default_rng(sum(sizes))
    k = max(sizes)
    unary = rng.uniform(0, 10, (4, k))
    pair = rng.uniform(0, 10, (4, 4, k, k))
    for i, n in enumerate(sizes):  # unused pieces: size 1, zero tables
        if n == 1:
            unary[i] = 0.0
            pair[i] = pair[:, i] = 0.0
    vals, idx = joint_grid_best(unary, pair, np.array(sizes, np.int64), 6)
    sums = [sum(unary[i, x[i]] for i in range(4))
            + sum(pair[i, j, x[i], x[j]] for i in range(4) for j in range(i + 1, 4))
            for x in itertools.product(*(range(n) for n in sizes))]
    np.testing.assert_allclose(vals, np.sort(sums)[:6], rtol=1e-12)
    for v, x in zip(vals, idx):
        again = (sum(unary[i, x[i]] for i in range(4))
                 + sum(pair[i, j, x[i], x[j]] for i in range(4) for j in range(i + 1, 4)))
        assert again == pytest.approx(v, rel=1e-12)


@pytest.mark.parametrize("group", list(PRINTS))
def test_tree_dp_finds_the_grid_optimum_of_a_chain_of_pieces(group):
    """Three pieces cut side by side sew into a chain (a tree): the dynamic programme
    must reach the joint grid's minimum, and the tables must add up to E_fit."""
    g, _, _ = cut_sheet(width=150, height=60, nx=15, ny=6, cuts_x=(0.34, 0.67), cuts_y=(),
                        seed=4)
    assert g.n_pieces == 3
    rng = np.random.default_rng(1)
    problem = AlignProblem.build(g, Wallpaper(group, *PRINTS[group], origin=(2.0, 5.0)))
    angles = rng.uniform(0, 2 * np.pi, 3)
    t = rng.uniform(-40, 40, (3, 2))
    k = 6
    movable = np.arange(3)
    unary, pair, cands = grid_tables(problem, angles, t, movable, k)
    assert set(pair) == {(0, 1), (1, 2)}
    # the tables reproduce E_fit at random grid combinations
    for x in rng.integers(0, k * k, (10, 3)):
        tt = np.stack([cands[i][x[i]] for i in range(3)])
        direct = problem.energy(angles[None], tt[None])[0]
        tabled = unary[np.arange(3), x].sum() + pair[(0, 1)][x[0], x[1]] \
            + pair[(1, 2)][x[1], x[2]]
        assert tabled == pytest.approx(direct, rel=1e-9)
    u4 = np.zeros((4, k * k))
    u4[:3] = unary
    p4 = np.zeros((4, 4, k * k, k * k))
    p4[0, 1], p4[1, 2] = pair[(0, 1)], pair[(1, 2)]
    vals, _ = joint_grid_best(u4, p4, np.array([k * k] * 3 + [1], np.int64), 1)
    t_dp = tree_dp_placement(problem, angles, t, grid=k)
    assert problem.energy(angles[None], t_dp[None])[0] == pytest.approx(vals[0], rel=1e-9)
