"""The nesting search's restarts: greedy fills of the raster board over several orderings
(area, length, width, then randomised), each compacted, the shortest marker kept.

The board and the filler are :mod:`solver.nest.engine`; this module decides how long a
board to try, at what pixel size, in which orders, and when to widen the board because a
greedy fill did not fit.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import shapely

from solver.nest.budget import Deadline, Progress, deadline_of
from solver.nest.engine import LEANS, SHELF_PER_ITEM, Filler, moves_of
from solver.nest.instance import Item, NestProblem, affine

#: measured cost of one greedy placement per candidate map (s; 2-20 ms on the benchmark
#: inputs at load average 4-7 on 2 cores, the high end for albano's and shirts' long
#: boards): what a fill that must finish is given before the time runs out
FILL_PER_CANDIDATE = 0.012


#: pixel size factor when a fill that must finish has less time than it needs: about
#: halves its time (measured on shirts under a 0.5 p1 print: 1.05 -> 0.58 s); a coarser
#: raster does not save more (the exact checks dominate)
COARSE = 2.0


def first_fill_estimate(items: list[Item]) -> float:
    """Seconds one greedy fill of ``items`` takes, roughly (see FILL_PER_CANDIDATE)."""
    return FILL_PER_CANDIDATE * sum(len(it.candidates) for it in items)


def default_resolution(problem: NestProblem, items: list[Item]) -> float:
    """Pixel size: fine enough for the smallest piece and the lattice, small enough to be fast."""
    small = min(float(np.min(np.ptp(it.ref, axis=0))) for it in items)
    return max(min(problem.width / 256.0, small / 8.0), problem.width / 1000.0)


def estimate_length(problem: NestProblem, items: list[Item]) -> float:
    area = sum(shapely.Polygon(it.ref).area for it in items)
    longest = max(float(np.ptp(it.ref[:, 0])) for it in items)
    return 2.0 * area / problem.width + 2 * longest + 4 * problem.gap


def orderings(items: list[Item], rng: np.random.Generator):
    """Area, length and width orders first, then randomised area orders, forever."""
    area = np.array([shapely.Polygon(it.ref).area for it in items])
    ext = np.array([np.ptp(it.ref, axis=0) for it in items])
    yield list(np.argsort(-area, kind="stable"))
    yield list(np.argsort(-ext[:, 0] * 1e6 - area, kind="stable"))
    yield list(np.argsort(-ext[:, 1] * 1e6 - area, kind="stable"))
    while True:
        yield list(np.argsort(-area * rng.uniform(0.6, 1.4, len(items)), kind="stable"))


def fill_search(problem: NestProblem, items: list[Item], *, time_limit: float | Deadline,
                seed: int | None, progress: Progress | None = None, res: float | None = None,
                start: list[np.ndarray | None] | None = None,
                targets: list[np.ndarray | None] | None = None, interruptible: bool = False,
                ) -> tuple[list[np.ndarray], float] | None:
    """Best greedy fill + compaction over several orderings within ``time_limit``.

    ``start`` optionally gives the moves of items that are already placed (None for the
    items to insert); they stay put during the fill and may move during compaction.
    ``targets`` optionally gives, for the items to insert, where they would like to be:
    the first run inserts them as close to it as possible instead of bottom-left.
    Every fill after the first stops at the deadline (its partial layout is dropped);
    the first one gives a result on time, shelving the items left at the deadline
    (:meth:`Filler.shelve`): a greedy fill cut short and shelved beats the naive marker
    on many small pieces (shirts under a 0.5 p1 print). ``interruptible`` (the caller
    has another result): None at once when not even shelving every item fits.
    """
    t0 = time.monotonic()
    deadline = deadline_of(time_limit)
    total = deadline.left()
    missing = len(items) if start is None else sum(m is None for m in start)
    if interruptible and not deadline.allows(SHELF_PER_ITEM * missing):
        return None
    if res is None:
        res = default_resolution(problem, items)
        if deadline.left() < first_fill_estimate(items):
            res *= COARSE  # a fill that must finish in less than it needs: fewer pixels
    fixed = [shapely.Polygon(k) for k in problem.keepouts]
    length = problem.length or estimate_length(problem, items)
    if start is not None and problem.length is None:
        placed = [shapely.Polygon(affine(m, it.ref)).bounds[2]
                  for it, m in zip(items, start) if m is not None]
        length += max(placed, default=0.0)
    rng = np.random.default_rng(seed)
    search = _Restarts(problem, items, deadline, total, progress, t0)
    for _ in range(8):
        filler = Filler(items, problem.width, length, problem.gap, res, fixed)
        outcome = search.on_board(filler, start, targets, rng)
        if outcome == "late":
            return search.result()
        if outcome == "done" or search.best is not None:
            break
        if problem.length is not None:
            return None
        length *= 1.6  # the estimate was too short for a greedy fill: widen the board
    return search.result()


@dataclass
class _Restarts:
    """The restarts of :func:`fill_search`: the shortest fill so far and how many ran."""

    problem: NestProblem
    items: list[Item]
    deadline: Deadline
    total: float  # the whole search's time (s): each ordering compacts within a quarter
    progress: Progress | None
    t0: float
    best: list[np.ndarray] | None = None
    best_len: float = math.inf
    runs: int = 0

    def result(self) -> tuple[list[np.ndarray], float] | None:
        return (self.best, self.best_len) if self.best is not None else None

    def on_board(self, filler: Filler, start, targets, rng: np.random.Generator) -> str:
        """Fill one board in one ordering after another until the deadline: "done";
        "stuck" when a fill did not fit the board; "late" when a fill after the first
        was cut short by the deadline."""
        n = len(self.items)
        pre = [None] * n if start is None else [
            None if m is None else filler.pose(k, m) for k, m in enumerate(start)]
        wish = None if targets is None else [
            None if m is None else filler.pose(k, m) for k, m in enumerate(targets)]
        for order in orderings(self.items, rng):
            if self.best is not None and self.deadline.expired():
                break
            if not self._run(filler, order, pre, wish):
                return "late" if self.best is not None and self.deadline.expired() else "stuck"
        return "done"

    def _run(self, filler: Filler, order: list[int], pre: list, wish: list | None) -> bool:
        """One greedy fill in ``order`` (the first one towards ``wish``), compacted and kept
        if it is the shortest; False when it did not place every item."""
        n = len(self.items)
        board, sol, index = filler.board(), list(pre), [0] * n
        for k in range(n):
            if sol[k] is not None:
                index[k] = board.add(filler.polygon(k, sol[k]))
        self.runs += 1
        filler.lean = LEANS[(self.runs - 1) % len(LEANS)]
        complete = self.best is None
        if wish is not None and self.runs == 1:  # nearest to the wished positions, left first
            todo = [k for k in range(n) if pre[k] is None]
            todo.sort(key=lambda k: filler.left(k, wish[k]) if wish[k] else math.inf)
            ok = filler.fill(todo, board, sol, index, wish, self.deadline, complete)
        else:
            ok = filler.fill([k for k in order if pre[k] is None], board, sol, index,
                             deadline=self.deadline, complete=complete)
        if not ok:
            return False
        sol = filler.compact(sol, board, self.deadline.within(self.total / 4), index)
        used = max(filler.right(k, p) for k, p in enumerate(sol)) + self.problem.gap
        if used < self.best_len:
            self.best, self.best_len = moves_of(filler, sol), used
            if self.progress:
                self.progress(f"lattice fill: {time.monotonic() - self.t0:5.1f} s  "
                              f"run {self.runs}  length {used:.4g}  density "
                              f"{problem_density(self.items, self.problem, used):.1%}")
        return True


def problem_density(items: list[Item], problem: NestProblem, length: float) -> float:
    area = sum(shapely.Polygon(it.ref).area for it in items)
    return area / (problem.width * length)
