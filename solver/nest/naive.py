"""The naive print-matching baseline: nest freely with a covering-radius margin, then snap.

Any point is within the lattice's covering radius ``r`` of a lattice point, so snapping
a free placement to the nearest allowed one moves each piece by at most ``r``; growing
every piece by ``r`` beforehand (and keeping ``r`` more from the edges) makes the
snapped layout valid without any search. It wastes a band of ``2 r`` around every
piece, which is what the lattice-aware search (:mod:`solver.nest.lattice`) wins back.
"""

from __future__ import annotations

import numpy as np

from solver.nest.instance import NestProblem
from solver.nest.layout import Layout, build_layout
from solver.nest.plain import Progress, plain_moves
from solver.nest.regions import snap_to_lattice


def covering_radius(basis: np.ndarray) -> float:
    """Largest distance from a point of the plane to its nearest lattice point.

    For a reduced basis it is the circumradius of the acute triangle (0, w1, ±w2).
    """
    w1, w2 = np.asarray(basis, float)[:, 0], np.asarray(basis, float)[:, 1]
    if w1 @ w2 < 0:
        w2 = -w2
    a, b, c = np.linalg.norm(w1), np.linalg.norm(w2), np.linalg.norm(w1 - w2)
    area2 = abs(w1[0] * w2[1] - w1[1] * w2[0])
    return float(a * b * c / (2 * area2))


def nest_naive(problem: NestProblem, *, time_limit: float = 30.0, seed: int | None = 0,
               progress: Progress | None = None) -> Layout:
    """The baseline on a printed fabric (see module docstring)."""
    if problem.fabric is None:
        raise ValueError("the naive print baseline needs a fabric")
    items = problem.items()
    r = covering_radius(problem.lattice) * (1 + 1e-9)
    moves, _ = plain_moves(problem, items, extra=r, time_limit=time_limit, seed=seed,
                           progress=progress)
    return build_layout(problem, items, snap_to_lattice(problem, items, moves))
