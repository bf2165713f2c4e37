"""The naive print-matching baseline: nest freely with a covering-radius margin, then snap.

Any point is within the lattice's covering radius ``r`` of a lattice point, so snapping
a free placement to the nearest allowed one moves each piece by at most ``r``; growing
every piece by ``r`` beforehand (and keeping ``r`` more from the edges) makes the
snapped layout valid without any search. It wastes a band of ``2 r`` around every
piece, which is what the lattice-aware search (:mod:`solver.nest.lattice`) wins back.
"""

from __future__ import annotations

import numpy as np

from solver.nest.budget import Deadline, Progress
from solver.nest.instance import Item, NestProblem, affine
from solver.nest.layout import Layout, build_layout
from solver.nest.plain import plain_moves
from solver.nest.regions import snap_to_lattice
from solver.wallpaper import covering_radius


def nest_naive(problem: NestProblem, *, time_limit: float | Deadline = 30.0, seed: int | None = 0,
               progress: Progress | None = None) -> Layout:
    """The baseline on a printed fabric (see module docstring)."""
    items = problem.items()
    moves, _ = naive_moves(problem, items, time_limit=time_limit, seed=seed, progress=progress)
    return build_layout(problem, items, moves)


def naive_moves(problem: NestProblem, items: list[Item], *, time_limit: float | Deadline,
                seed: int | None, progress: Progress | None = None,
                interruptible: bool = False) -> tuple[list[np.ndarray], float]:
    """Moves and marker length of the baseline: valid without any search after sparrow.
    ``interruptible`` (the caller has another marker): sparrow late is given up (Late)."""
    if problem.fabric is None:
        raise ValueError("the naive print baseline needs a fabric")
    r = covering_radius(problem.lattice) * (1 + 1e-9)
    moves, _ = plain_moves(problem, items, extra=r, time_limit=time_limit, seed=seed,
                           progress=progress, interruptible=interruptible)
    moves = snap_to_lattice(problem, items, moves)
    right = max(float(affine(m, it.ref)[:, 0].max()) for it, m in zip(items, moves))
    return moves, right + problem.gap
