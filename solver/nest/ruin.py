"""Ruin and recreate on the lattice cosets: a shorter strip, and the pieces that do not fit yet.

A greedy fill or a snapped free nest stops where its construction stopped; on a coarse
lattice (a 50 mm repeat against 300-600 mm pieces) the strip shrinking of
:mod:`solver.nest.coset` rarely helps, because one move is a whole lattice step and a
small overlap cannot be resolved by a small move. Ruin and recreate [1]_ moves several
pieces at once instead, and never lets two pieces overlap:

- the strip is fixed one pixel shorter than the best marker so far; the pieces that do
  not fit in it are *left out* (the goal-driven form of [2]_: the search works on the
  area left out, and a marker is found when it reaches zero);
- *ruin*: a random piece and its nearest neighbours (1-3) are taken out;
- *recreate*: every piece left out goes back, largest first (with noise), at its
  bottom-left allowed position (the engine's FFT collision maps read only at the
  piece's lattice cosets, then the exact check); those with no room stay out;
- the new state is kept if it leaves out no more area than before (a walk on the
  plateaus of equal area that the greedy fill cannot make), else undone.

Each state is a valid partial marker, so the search may stop at any moment: it reads its
``Deadline`` before every placement.

.. [1] G. Schrimpf, J. Schneider, H. Stamm-Wilbrandt, G. Dueck, "Record breaking
   optimization results using the ruin and recreate principle", J. Comput. Phys. 159
   (2000). doi:10.1006/jcph.1999.6413
.. [2] J. Gardeyn, T. Wauters, "A goal-driven ruin and recreate heuristic for the 2D
   variable-sized bin packing problem with guillotine constraints", EJOR 301 (2022).
   doi:10.1016/j.ejor.2021.11.031
"""

from __future__ import annotations

import time

import numpy as np
import shapely

from solver.nest.budget import Deadline, Progress, deadline_of
from solver.nest.engine import LEANS, Board, Filler, default_resolution, fill_search, moves_of
from solver.nest.instance import Item, NestProblem, affine

EXTRA = (1, 2, 3)  # neighbours taken out with the ruin's seed piece, drawn uniformly
AT_END = 0.5  # chance that the ruin starts from a piece reaching the strip's end
SIDEWAYS = 0.3  # fraction of steps that keep the length (a walk on the plateau)
SLACK = 0.002  # a sideways step may push the sum of right edges right by this fraction
FILL_SHARE = 0.5  # of the time, for the first marker when none is given
REBUILD = 4  # the board is rebuilt once it holds this many times the pieces (removed ones)


class RuinRecreate:
    """A valid marker on the cosets, and the filler that re-inserts its pieces."""

    def __init__(self, problem: NestProblem, items: list[Item], start: list[np.ndarray],
                 res: float, rng: np.random.Generator) -> None:
        self.problem, self.items, self.rng = problem, items, rng
        length = marker_length(problem, items, start)
        fixed = [shapely.Polygon(k) for k in problem.keepouts]
        self.filler = Filler(items, problem.width, length, problem.gap, res, fixed)
        self.area = np.array([self.filler.area[it.key] for it in items])
        self.sol = [self.filler.pose(k, m) for k, m in enumerate(start)]
        self._rebuild()

    def _rebuild(self) -> None:
        self.board: Board = self.filler.board()
        self.index = [self.board.add(self.filler.polygon(k, p)) for k, p in enumerate(self.sol)]

    def rights(self, sol: list) -> np.ndarray:
        return np.array([self.filler.right(k, p) for k, p in enumerate(sol)])

    def length(self) -> float:
        return float(self.rights(self.sol).max()) + self.problem.gap

    def ruin(self, target: float) -> list[int]:
        """The pieces to take out for a marker ``target`` long: those reaching beyond it,
        and the nearest neighbours of a seed piece (one of those, or any)."""
        rights = self.rights(self.sol)
        beyond = np.flatnonzero(rights + self.problem.gap > target + 1e-9)
        at_end = len(beyond) and self.rng.random() < AT_END
        seed = int(self.rng.choice(beyond)) if at_end else int(self.rng.integers(len(self.sol)))
        centres = np.array([self._centre(k) for k in range(len(self.sol))])
        near = np.argsort(np.hypot(*(centres - centres[seed]).T), kind="stable")
        extra = near[:1 + int(self.rng.choice(EXTRA))]
        return sorted(set(beyond.tolist()) | set(extra.tolist()))

    def _centre(self, k: int) -> np.ndarray:
        s = self.filler.shapes[self.items[k].key][self.sol[k][0]]
        return (s.lo + s.hi) / 2 + self.sol[k][1]

    def recreate(self, out: list[int], target: float, deadline: Deadline) -> list | None:
        """The marker with ``out`` re-inserted bottom-left inside ``target`` (the board
        holds it), or None (the board is left as it was)."""
        f, board = self.filler, self.board
        for k in out:
            board.remove(self.index[k])
        mark = len(board.polys)
        order = sorted(out, key=lambda k: -self.area[k] * self.rng.uniform(0.6, 1.4))
        f.length = target
        f.lean = LEANS[int(self.rng.integers(len(LEANS)))]
        trial, index = list(self.sol), list(self.index)
        if f.fill(order, board, trial, index, deadline=deadline):
            self.index = index
            return trial
        for k in out:  # undo: the pieces placed this round out, the old ones back
            if index[k] >= mark:
                board.remove(index[k])
            self.index[k] = board.add(f.polygon(k, self.sol[k]))
        return None

    def step(self, deadline: Deadline) -> bool:
        """One ruin and recreate; True if the marker got shorter."""
        if len(self.board.polys) > REBUILD * len(self.sol):
            self._rebuild()
        now = self.length()
        sideways = self.rng.random() < SIDEWAYS
        # strictly shorter, by up to a lattice step (so that more pieces move), or equal
        target = now if sideways else now - 1e-6 - self.rng.random() * self.filler.step
        out = self.ruin(target)
        before = self.rights(self.sol).sum()
        trial = self.recreate(out, target, deadline)
        if trial is None:
            return False
        if sideways and self.rights(trial).sum() > before * (1 + SLACK):
            for k in out:  # undo a sideways step that pushed the pieces right
                self.board.remove(self.index[k])
                self.index[k] = self.board.add(self.filler.polygon(k, self.sol[k]))
            return False
        self.sol = trial
        return self.length() < now - 1e-9


def marker_length(problem: NestProblem, items: list[Item], moves: list[np.ndarray]) -> float:
    """The right-most point of the moved outlines plus the gap."""
    return max(float(affine(m, it.ref)[:, 0].max()) for it, m in zip(items, moves)) + problem.gap


def ruin_search(problem: NestProblem, items: list[Item], *, time_limit: float | Deadline,
                seed: int | None, progress: Progress | None = None,
                start: list[np.ndarray] | None = None, res: float | None = None,
                ) -> tuple[list[np.ndarray], float] | None:
    """Ruin and recreate from ``start`` (a valid printed marker) until the deadline.

    Without ``start``, a lattice fill (:func:`solver.nest.engine.fill_search`) gives the
    first marker in a share of the time. Returns (moves, length) of the shortest marker
    found, or None when nothing shorter than ``start`` came out.
    """
    deadline = deadline_of(time_limit)
    t0 = time.monotonic()
    given = start is not None
    if start is None:
        r = fill_search(problem, items, time_limit=deadline.share(FILL_SHARE), seed=seed,
                        progress=progress)
        if r is None:
            return None
        start = r[0]
    if deadline.expired():
        return None if given else (start, marker_length(problem, items, start))
    search = RuinRecreate(problem, items, start, res or default_resolution(problem, items),
                          np.random.default_rng(seed))
    first = best_len = search.length()
    best, steps = list(search.sol), 0
    while not deadline.expired():
        steps += 1
        if search.step(deadline) and search.length() < best_len - 1e-9:
            best, best_len = list(search.sol), search.length()
            if progress:
                progress(f"ruin and recreate: {time.monotonic() - t0:5.1f} s  step {steps}  "
                         f"length {best_len:.4g}")
    if progress:
        progress(f"ruin and recreate: {steps} steps, {first:.4g} -> {best_len:.4g}")
    if given and best_len >= first - 1e-9:
        return None
    return moves_of(search.filler, best), best_len
