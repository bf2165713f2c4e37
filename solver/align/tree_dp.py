"""Exact placement of the pieces over a spanning tree of the seam graph (issue 18).

The greedy tree placement of :mod:`solver.align.global_` fixes each piece against the
pieces placed before it, and an early choice is never undone. On a tree, the sum of
the seams' E_fit over every piece's k x k grid of print offsets is minimised exactly by
min-sum dynamic programming (leaves to root, then back): O(edges k^4) instead of the
k^(2 pieces) of a joint grid. The tree is the maximum-weight spanning forest of the seam
graph; seams that close cycles are left to the refinement that follows. Tables come from
:func:`solver.align.brute.grid_tables`, the same ones the joint grid uses.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import breadth_first_order, minimum_spanning_tree

from solver.align.brute import grid_tables
from solver.align.problem import AlignProblem


def tree_dp_placement(problem: AlignProblem, angles: np.ndarray, t: np.ndarray, *,
                      grid: int = 8) -> np.ndarray:
    """Translations (P,2): the grid optimum of E_fit over the spanning tree's seams, each
    movable piece offset from ``t`` by one of ``grid`` x ``grid`` points of a cell."""
    movable = np.flatnonzero(~problem.fix_trans)
    if len(movable) == 0:
        return t.copy()
    seams = problem.piece_weights()
    strength = (seams + seams.T)[np.ix_(movable, movable)]
    tree = minimum_spanning_tree(csr_matrix(-strength))
    tree = (tree + tree.T).tocsr()
    edges = {(int(min(i, j)), int(max(i, j))) for i, j in zip(*tree.nonzero())}
    unary, pair, cands = grid_tables(problem, angles, t, movable, grid, pairs=edges)
    m, kk = unary.shape
    total = unary.copy()
    best_child: dict[int, np.ndarray] = {}
    x = np.full(m, -1)
    rows = np.arange(kk)
    for root in np.argsort(-strength.sum(axis=1), kind="stable"):
        if x[root] >= 0:
            continue
        order, pred = breadth_first_order(tree, int(root), directed=False)
        for c in order[::-1]:  # leaves first: pass each subtree's best up to its parent
            p = pred[c]
            if p < 0:
                continue
            table = pair[(c, p)].T if c < p else pair[(p, c)]  # (x_p, x_c)
            cost = table + total[c][None, :]
            best_child[c] = np.argmin(cost, axis=1)
            total[p] += cost[rows, best_child[c]]
        x[root] = int(np.argmin(total[root]))
        for c in order[1:]:  # root first: each child's best for its parent's choice
            x[c] = best_child[c][x[pred[c]]]
    out = t.copy()
    for i, c in enumerate(movable):
        out[c] = cands[i][x[i]]
    return out
