"""The dotted-board CP-SAT model of one nest (:mod:`solver.nest.dotted`): a boolean per
(piece, allowed position), exactly one per piece, at most one of each position and the
positions of a later piece that clash with it, the right edge beyond every piece, and
the objective: the right edge, or free of phase the span from the leftmost piece.
"""

from __future__ import annotations

import math

import numpy as np
import shapely

from solver.nest.budget import Deadline
from solver.nest.dotted_options import EDGE_EPS, Options, clash_lists, clash_offsets, shape_at_zero
from solver.nest.instance import Item, NestProblem, affine, marker_span

SCALE = 100  # objective units per mm (0.01 mm)


class Board:
    """The dotted-board CP-SAT model of one nest: a boolean per (item, option)."""

    def __init__(self, problem: NestProblem, items: list[Item], opts: list[Options],
                 cp_model) -> None:
        self.problem, self.items, self.opts = problem, items, opts
        self.cp_model, self.model = cp_model, cp_model.CpModel()
        model = self.model
        starts = np.cumsum([0] + [len(o.cand) for o in opts])
        self.n_options = int(starts[-1])
        self.ids = [np.arange(starts[i], starts[i + 1]) for i in range(len(items))]
        self.x = [model.new_bool_var(f"x{j}") for j in range(self.n_options)]
        self.right = None  # the right edge's variable, once built
        self.right_floor = 0  # its lower bound from the pieces' area
        self.left = None  # any phase: the marker's start (a variable), and its values
        self.first = np.zeros(0, np.int64)
        self.area_of = [shapely.Polygon(it.ref).area for it in items]
        self.area = sum(self.area_of)

    def build(self, deadline: Deadline, reach: float, limit: float,
              period: float | None) -> bool:
        """Every constraint and the objective (``period``: any phase); False when the
        deadline passes first."""
        for i in range(len(self.items)):
            self.model.add_exactly_one(self.x[j] for j in self.ids[i])
        if not self._add_clashes(deadline) or not self._add_right_edge(deadline, reach):
            return False
        self._order_copies()
        self._start_near_the_bottom()
        if period is not None:
            self._minimise_span(limit, period)
        else:
            self.model.minimize(self.right)
        return True

    def _add_clashes(self, deadline: Deadline) -> bool:
        """Per option of one item and each later item: at most one of it and the later
        item's options it clashes with. Colliding offsets are computed once per pair of
        (item key, map): copies share them."""
        items, opts, ids = self.items, self.opts, self.ids
        rings = {}
        for it in items:
            for c in range(len(it.candidates)):
                rings.setdefault((it.key, c), shape_at_zero(it, c))
        offsets: dict = {}
        for i, a in enumerate(items):
            for j in range(i + 1, len(items)):  # one way: half the model, solved 3x faster
                if deadline.expired():
                    return False
                table = self._offset_table(a, items[j], rings, offsets)
                for n, (row, clashing) in enumerate(zip(ids[i], clash_lists(
                        opts[i], opts[j], table, ids[j]))):
                    if n % 256 == 255 and deadline.expired():
                        return False
                    if len(clashing):  # straight into the model's proto: the booleans
                        # are its first variables (x[j] is variable j), and building one
                        # expression per literal took 1.4 s of a t-shirt p2 model's 2.3
                        self.model.proto.constraints.add().at_most_one.literals.extend(
                            [int(row), *clashing.tolist()])
        return True

    def _offset_table(self, a: Item, b: Item, rings: dict, offsets: dict) -> dict:
        """Colliding lattice offsets of ``b`` against ``a`` per pair of candidate maps."""
        table = {}
        for ca in range(len(a.candidates)):
            for cb in range(len(b.candidates)):
                key = (a.key, ca, b.key, cb)
                if key not in offsets:
                    offsets[key] = clash_offsets(rings[a.key, ca], rings[b.key, cb],
                                                 self.items[0].lattice, self.problem.gap)
                table[ca, cb] = offsets[key]
        return table

    def _add_right_edge(self, deadline: Deadline, reach: float) -> bool:
        """The marker's right edge: beyond every piece, and beyond the area bound."""
        g = self.problem.gap
        self.right = self.model.new_int_var(0, int(math.ceil(reach * SCALE)) + 1, "right")
        self.right_floor = int(math.floor((g + self.area / (self.problem.width - 2 * g)) * SCALE))
        self.model.add(self.right >= self.right_floor)
        for i in range(len(self.items)):
            if deadline.expired():
                return False
            self.model.add(self.right >= self._weighted(i, np.ceil(self.opts[i].right * SCALE)))
        return True

    def _weighted(self, i: int, values: np.ndarray):
        """The linear expression sum(values[n] * x_n) over item ``i``'s options."""
        return self.cp_model.LinearExpr.weighted_sum(
            [self.x[j] for j in self.ids[i]], values.astype(np.int64).tolist())

    def _order_copies(self) -> None:
        """Interchangeable copies (same options, adjacent in ``items``) in the order of
        their options, so the solver does not explore their permutations."""
        ids = self.ids
        for i in range(len(self.items) - 1):
            if self.items[i].key == self.items[i + 1].key:
                self.model.add(self._weighted(i, np.arange(len(ids[i])))
                               < self._weighted(i + 1, np.arange(len(ids[i + 1]))))

    def _start_near_the_bottom(self) -> None:
        """A shift across the roll by a period keeps everything: one piece starts within
        a period of the bottom edge."""
        up = [v for v in self.items[0].lattice.T if abs(v[0]) < 1e-9]
        if up and not self.problem.keepouts:
            reach = self.problem.gap + abs(up[0][1]) - EDGE_EPS
            low = np.concatenate([self.ids[i][o.bottom < reach]
                                  for i, o in enumerate(self.opts)])
            self.model.add_bool_or([self.x[j] for j in low])

    def _minimise_span(self, limit: float, period: float) -> None:
        """Any phase: minimise the span from the leftmost piece (within the first period)
        to the right edge."""
        g, model = self.problem.gap, self.model
        starts = [np.floor(o.left * SCALE) for o in self.opts]
        # the marker starts where one piece does: its left edge is one of the options'
        # within the first period (a finite domain; in one trial from a 919 mm t-shirt
        # p1 hint: 830 mm in 5 s, none better with an interval)
        first = np.unique(np.concatenate(starts))
        first = first[first <= (g + period) * SCALE].astype(np.int64)
        left = model.new_int_var_from_domain(
            self.cp_model.Domain.from_values(first.tolist()), "left")
        self.left, self.first = left, first
        for i in range(len(self.items)):
            model.add(left <= self._weighted(i, starts[i]))
        model.add(self.right - left <= int(math.ceil((limit - 2 * g) * SCALE)) + 2)
        model.add(self.right - left >= int(math.floor(
            self.area / (self.problem.width - 2 * g) * SCALE)))
        model.minimize(self.right - left)

    def add_hint(self, hint: list[np.ndarray]) -> None:
        """Start from the ``hint`` marker, complete (every boolean): CP-SAT then starts
        from it at once. Interchangeable copies take their positions in option order."""
        local = [option_of(it, m, o) for it, m, o in zip(self.items, hint, self.opts)]
        runs: dict = {}
        for i, it in enumerate(self.items):
            runs.setdefault(it.key, []).append(i)
        for run in runs.values():
            got = sorted((local[i] for i in run), key=lambda v: (v is None, v or 0))
            for i, v in zip(run, got):
                local[i] = v
        chosen = {int(self.ids[i][j]) for i, j in enumerate(local) if j is not None}
        for j, v in enumerate(self.x):
            self.model.add_hint(v, j in chosen)
        if any(j is None for j in local):
            return
        # the edges too: without them the single worker did not complete the any-phase
        # hint of a t-shirt p2 marker within 4 s, and found nothing
        right = max(math.ceil(o.right[j] * SCALE) for o, j in zip(self.opts, local))
        self.model.add_hint(self.right, max(right, self.right_floor))
        if self.left is not None:
            start = min(math.floor(o.left[j] * SCALE) for o, j in zip(self.opts, local))
            below = self.first[self.first <= start]
            if len(below):
                self.model.add_hint(self.left, int(below[-1]))

    def solution(self, solver, any_phase: bool) -> tuple[list[np.ndarray], float]:
        """The solver's marker: every item's move, and the marker's length (mm)."""
        moves = []
        for i, it in enumerate(self.items):
            ids = self.ids[i]
            j = next(j for j in range(len(ids)) if solver.boolean_value(self.x[ids[j]]))
            moves.append(move_of(it, self.opts[i], j))
        g = self.problem.gap
        if any_phase:
            return moves, marker_span(self.items, moves, g)
        return moves, g + max(float(affine(m, it.ref)[:, 0].max())
                              for it, m in zip(self.items, moves))


def move_of(item: Item, opts: Options, j: int) -> np.ndarray:
    m = item.candidates[int(opts.cand[j])].copy()
    m[:, 2] += item.lattice @ opts.k[j]
    return m


def option_of(item: Item, move: np.ndarray, opts: Options) -> int | None:
    """The option index of ``move`` (a candidate map plus a lattice translation), if any."""
    for c, cand in enumerate(item.candidates):
        if not np.allclose(cand[:, :2], move[:, :2], atol=1e-9):
            continue
        f = np.linalg.solve(item.lattice, move[:, 2] - cand[:, 2])
        if np.allclose(f, np.round(f), atol=1e-6):
            hit = np.flatnonzero((opts.cand == c) & np.all(opts.k == np.round(f), axis=1))
            if len(hit):
                return int(hit[0])
    return None
