"""The exact printed nest: a dotted-board model on every allowed position, solved by CP-SAT.

On a printed fabric a piece may sit only at its allowed positions (the print's
grain-keeping operations times the lattice translations, :class:`Item`), a discrete set
in both directions. That is the *dotted-board* problem of Toledo, Carravilla, Ribeiro,
Oliveira and Gomes ("The Dotted-Board Model: a new MIP model for nesting irregular
shapes", Int. J. Production Economics 145 (2013) 478-487): one boolean per (piece,
allowed position), exactly one per piece, pairwise non-overlap from no-fit information,
minimise the marker length. Here:

- options: every candidate map x every lattice translation that keeps the outline on
  the roll (width, gap, keep-outs, table length) and ends before an upper bound (the
  best marker known);
- clashes: whether two pieces under two candidate maps collide depends only on their
  relative lattice offset, so the colliding offsets are tabulated once per (piece,
  map) pair with shapely (the gap semantics of ``verify_layout``) and expanded to
  option pairs by index arithmetic;
- the model: exactly one option per piece; per option ``a`` of piece A and each other
  piece B, ``x_a + sum(x_b: b clashes with a) <= 1`` (B takes exactly one option, so
  this is exact, and far smaller than one constraint per clashing pair); the right edge
  ``R >= sum(right_a x_a)`` per piece; minimise ``R``: the marker starts at the roll's
  start, at the print's phase there. With ``any_phase`` it may start at any phase (a
  roll is cut wherever its print lies): minimise ``R - L``, ``L`` the left edge of
  the leftmost piece, one of the options' left edges within the first period.
  Translations across the roll (a lattice vector along y) are fixed by asking one piece
  to start within a period of the bottom edge.

CP-SAT (OR-tools) proves a lower bound as it goes, so the answer says how far the
marker is from the best possible on this print, not only how long it is;
:func:`narrow_bound` tightens that bound by feasibility probes where minimising does not.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass

import numpy as np
import shapely

from solver.nest.budget import Deadline, Progress, deadline_of
from solver.nest.instance import Item, NestProblem, affine, marker_span
from solver.nest.snapjoint import collide

SCALE = 100  # objective units per mm (0.01 mm)
# CP-SAT search workers: one proved the t-shirt's p1 optimum in 4.6 s, two in 8 s, four in
# 11 s on the station's two cores (the portfolio's helpers steal the main search's time)
WORKERS = 1
EDGE_EPS = 1e-9  # mm of slack at the fabric's edges (verify_layout allows 1e-6)
# share of the model's build time kept back for handing it to the solver (twice what was
# measured, as machines under load pay more)
HANDOVER = 0.2
# CP-SAT's first presolve pass is not interrupted by its time limit: asked to stop within
# less than about 1.7 model build times it overran by up to 0.7 s and found no marker
# (the shorts' 4940 positions, built in 0.70 s: asked 0.2 s, took 0.83; 0.5 -> 1.00;
# 1.0 -> 1.15; 1.5 -> 1.47; 2.0 -> 2.01, its first marker). The solver is started only
# with this many build times left.
SOLVE_MIN = 2.0
# above this many allowed positions in all the model does not fit a nest's budget (the
# strategy steps aside): the Berkeley dresses' p1 (11 pieces, 3475-3740) built in 1 s and
# solved from 1-2 s on; the shirt's p2 (14 pieces, 11167, 12 M literals) took 4.2 s to
# build and more than 4 s to presolve
MAX_OPTIONS = 4000
# any phase: share of the solver's time for a depth-first search, largest pieces first,
# each bottom to top, then left to right (CP-SAT's fixed search), before the default search
# from its marker. T-shirt p1: 822.5 mm proven in 1 s (the default search: 865 mm after
# 10 s); p2: 814 mm in 5.4 s (left to right first: 853 mm after 8 s)
FIXED_SHARE = 0.75


@dataclass
class Options:
    """One item's allowed positions: candidate map index and lattice coordinates each."""

    cand: np.ndarray  # (m,) int
    k: np.ndarray  # (m, 2) int
    left: np.ndarray  # (m,) left edge, mm
    right: np.ndarray  # (m,) right edge, mm
    bottom: np.ndarray  # (m,) lower edge, mm


@dataclass
class DottedResult:
    moves: list[np.ndarray] | None  # None: none found (``bound`` says if none exists)
    length: float  # of ``moves`` (inf without)
    bound: float  # proven: no marker on these positions is shorter (mm)
    optimal: bool  # ``length == bound`` is proven (or, without moves, nothing fits)
    options: int  # booleans of the model
    build_s: float
    solve_s: float


def lattice_points(basis: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(m, 2) int coordinates ``k`` with ``basis @ k`` inside the box [lo, hi] (mm)."""
    corners = np.array([[lo[0], lo[1]], [lo[0], hi[1]], [hi[0], lo[1]], [hi[0], hi[1]]])
    f = np.linalg.solve(basis, corners.T).T
    a = np.arange(math.floor(f[:, 0].min()), math.ceil(f[:, 0].max()) + 1)
    b = np.arange(math.floor(f[:, 1].min()), math.ceil(f[:, 1].max()) + 1)
    k = np.stack(np.meshgrid(a, b, indexing="ij"), -1).reshape(-1, 2)
    t = k @ basis.T
    return k[np.all((t >= lo - EDGE_EPS) & (t <= hi + EDGE_EPS), axis=1)]


def shape_at_zero(item: Item, c: int) -> np.ndarray:
    """(n, 2) the item's outline under candidate map ``c``, lattice translation zero."""
    return affine(item.candidates[c], item.ref)


def item_options(problem: NestProblem, item: Item, limit: float) -> Options:
    """Every allowed position of ``item`` on the roll, ending before ``limit`` (mm).

    Per candidate map the box of lattice translations that keep the outline between the
    gap and the roll's edges, then (vectorised) those clear of the keep-outs.
    """
    g, basis = problem.gap, item.lattice
    end = limit if problem.length is None else min(limit, problem.length)
    cands, ks, lefts, rights, bottoms = [], [], [], [], []
    for c in range(len(item.candidates)):
        ring = shape_at_zero(item, c)
        lo, hi = ring.min(0), ring.max(0)
        k = lattice_points(basis, np.array([g, g]) - lo,
                           np.array([end - g, problem.width - g]) - hi)
        t = k @ basis.T
        if problem.keepouts and len(k):
            polys = shapely.polygons(ring[None] + t[:, None])
            ok = np.ones(len(k), bool)
            for ring_k in problem.keepouts:
                ok &= ~collide(polys, shapely.Polygon(ring_k), g)
            k, t = k[ok], t[ok]
        cands.append(np.full(len(k), c))
        ks.append(k)
        lefts.append(lo[0] + t[:, 0])
        rights.append(hi[0] + t[:, 0])
        bottoms.append(lo[1] + t[:, 1])
    return Options(np.concatenate(cands), np.concatenate(ks).reshape(-1, 2).astype(np.int64),
                   np.concatenate(lefts), np.concatenate(rights), np.concatenate(bottoms))


def positions(problem: NestProblem, items: list[Item], length: float) -> float:
    """About how many allowed positions the items have on a marker ``length`` long (the
    size of the dotted-board model), from the area of each map's box of translations over
    the lattice cell's, without listing them (a 1 mm stripe step has millions)."""
    g, total = problem.gap, 0.0
    end = length if problem.length is None else min(length, problem.length)
    for it in items:
        cell = abs(np.linalg.det(it.lattice))
        for c in range(len(it.candidates)):
            size = np.ptp(shape_at_zero(it, c), axis=0)
            room = np.array([end, problem.width]) - 2 * g - size
            total += float(np.prod(np.maximum(room, 0.0))) / cell
    return total


def clash_offsets(ring_a: np.ndarray, ring_b: np.ndarray, basis: np.ndarray,
                  gap: float) -> np.ndarray:
    """(d, 2) int lattice offsets ``k_b - k_a`` at which outline B collides with outline A.

    Only offsets whose boxes come within the gap can collide; those are checked exactly
    (``collide``: closer than the gap, or overlapping at gap 0), all at once.
    """
    lo_a, hi_a = ring_a.min(0), ring_a.max(0)
    lo_b, hi_b = ring_b.min(0), ring_b.max(0)
    d = lattice_points(basis, lo_a - hi_b - gap, hi_a - lo_b + gap)
    if len(d) == 0:
        return d.reshape(0, 2)
    polys = shapely.polygons(ring_b[None] + (d @ basis.T)[:, None])
    return d[collide(shapely.Polygon(ring_a), polys, gap)]


def _index_grid(k: np.ndarray, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A dense table lattice coordinates -> option id (-1: none) and its origin."""
    origin = k.min(0)
    grid = np.full(tuple(np.ptp(k, axis=0) + 1), -1, np.int64)
    grid[tuple((k - origin).T)] = ids
    return grid, origin


def clash_lists(opts_a: Options, opts_b: Options, offsets: dict, ids_b: np.ndarray,
                ) -> list[np.ndarray]:
    """Per option of A, the ids of B's options that collide with it.

    ``offsets[ca, cb]`` are the colliding offsets of the two maps (:func:`clash_offsets`);
    B's options are looked up in a dense grid per map, by index arithmetic.
    """
    parts = []  # (m_a, d) arrays of B ids, -1 where none
    for cb in np.unique(opts_b.cand):
        sel = opts_b.cand == cb
        grid, origin = _index_grid(opts_b.k[sel], ids_b[sel])
        block = np.full((len(opts_a.cand), 0), -1, np.int64)
        for ca in np.unique(opts_a.cand):
            d = offsets[int(ca), int(cb)]
            rows = np.flatnonzero(opts_a.cand == ca)
            if len(d) == 0 or len(rows) == 0:
                continue
            kb = opts_a.k[rows, None, :] + d[None] - origin  # (r, d, 2)
            inside = np.all((kb >= 0) & (kb < grid.shape), axis=2)
            got = np.full(kb.shape[:2], -1, np.int64)
            got[inside] = grid[kb[inside][:, 0], kb[inside][:, 1]]
            if block.shape[1] < got.shape[1]:
                block = np.pad(block, ((0, 0), (0, got.shape[1] - block.shape[1])),
                               constant_values=-1)
            block[rows, :got.shape[1]] = got
        parts.append(block)
    rows = np.concatenate(parts, axis=1) if parts else np.full((len(opts_a.cand), 0), -1)
    return [r[r >= 0] for r in rows]


def _reporter(cp_model, progress: Progress | None, gap: float, t0: float):
    """A CP-SAT solution callback giving a progress line per better marker (``gap``: mm
    the marker has beyond the objective)."""

    class Reporter(cp_model.CpSolverSolutionCallback):
        def on_solution_callback(self) -> None:
            if progress:
                progress(f"dotted: {time.monotonic() - t0:5.1f} s  length "
                         f"{self.objective_value / SCALE + gap:.4g}  bound "
                         f"{self.best_objective_bound / SCALE + gap:.4g}")

    return Reporter()


def dotted_nest(problem: NestProblem, items: list[Item], *, time_limit: float | Deadline,
                hint: list[np.ndarray] | None = None, limit: float | None = None,
                progress: Progress | None = None, workers: int = WORKERS,
                max_options: int | None = None, any_phase: bool = False,
                ) -> DottedResult | None:
    """The shortest marker on the allowed positions, or the best found by the deadline.

    ``hint``: the best marker known (its moves); it bounds the length (no option ends
    beyond it) and starts the search, so the result is never longer. Without it,
    ``limit`` (mm) bounds the length: a result without moves and ``optimal`` proves that
    no marker is that short. Returns None when the deadline passes while the model is
    built or leaves the solver less than its uninterruptible presolve takes
    (``SOLVE_MIN``), or when the search ends without a marker and without a proof, or
    when the pieces have more than ``max_options`` allowed positions in all (a stripe
    print's 1 mm steps, many pieces: the model would not be built in time).

    ``any_phase``: the marker may start at any phase of the print along the roll (a roll
    is cut wherever its print lies), so its length is its span plus the gap at both
    ends, minimised with the leftmost piece within the first period (needs a lattice
    vector along the roll); the moves stay on the print as given, starting up to a
    period in (the table length and keep-outs, if any, still bound them there).
    """
    deadline = deadline_of(time_limit)
    t0 = time.monotonic()
    # imported here, within the budget: 0.4-0.6 s (load 6 on 2 cores) on first use, that
    # every `station nest`, plain fabric and large inputs included, would otherwise pay
    from ortools.sat.python import cp_model

    period = phase_period(items[0].lattice) if any_phase else 0.0
    if period is None:
        raise ValueError("any_phase needs a lattice vector along the roll")
    limit = _length_limit(problem, items, hint, limit, any_phase)
    reach = limit + period  # any phase: a marker starting up to a period in
    if max_options is not None and (n := positions(problem, items, reach)) > max_options:
        if progress:
            progress(f"dotted: about {n:.0f} allowed positions, more than {max_options}: "
                     "skipped")
        return None
    opts = [item_options(problem, it, reach) for it in items]
    if any(len(o.cand) == 0 for o in opts):  # a piece alone does not fit
        return DottedResult(None, math.inf, limit, True, 0, time.monotonic() - t0, 0.0)
    board = _Board(problem, items, opts, cp_model)
    if not board.build(deadline, reach, limit, period if any_phase else None):
        return None
    if hint is not None:
        board.add_hint(hint)
    build = time.monotonic() - t0
    if progress:
        progress(f"dotted: {board.n_options} allowed positions, model built in {build:.2f} s")
    # Handing the model over costs about a tenth of building it, outside the solver's own
    # time limit (0.08 s after a 0.92 s build of the shorts' 4940 positions): kept back.
    left = deadline.left() - HANDOVER * build
    if left < SOLVE_MIN * build:
        if progress:
            progress(f"dotted: {left:.2f} s left, less than its presolve takes: skipped")
        return None
    reporter = _reporter(cp_model, progress, 2 * problem.gap if any_phase else problem.gap, t0)
    if any_phase:
        solver, status = board.solve_left_to_right_first(left, workers, reporter,
                                                         SOLVE_MIN * build)
    else:
        solver = _solver(cp_model, left, workers)
        status = solver.solve(board.model, reporter)
    if progress:
        progress(f"dotted: {solver.status_name(status)} after {time.monotonic() - t0:.1f} s")
    build_and_solve = (board.n_options, build, time.monotonic() - t0 - build)
    if status == cp_model.INFEASIBLE:
        return DottedResult(None, math.inf, limit, True, *build_and_solve)
    if status not in (cp_model.OPTIMAL, cp_model.FEASIBLE):
        return None
    moves, length = board.solution(solver, any_phase)
    # edges were rounded outwards by up to one unit each
    bound = ((solver.best_objective_bound - 2) / SCALE + 2 * problem.gap if any_phase
             else (solver.best_objective_bound - 1) / SCALE + problem.gap)
    return DottedResult(moves, length, min(bound, length), status == cp_model.OPTIMAL,
                        *build_and_solve)


def phase_period(lattice: np.ndarray | None) -> float | None:
    """The print's period along the roll (mm): a marker free to start at any phase starts
    within one of the roll's start. None without a lattice vector along the roll (an
    oblique print: its phases are not a period of the roll, and the marker keeps the one
    found)."""
    if lattice is None:
        return None
    along = [abs(v[0]) for v in lattice.T if abs(v[1]) < 1e-9]
    return along[0] if along else None


def _length_limit(problem: NestProblem, items: list[Item], hint: list[np.ndarray] | None,
                  limit: float | None, any_phase: bool) -> float:
    """The longest marker the model allows: the hint's length, else ``limit``."""
    if hint is not None:
        limit = marker_span(items, hint, problem.gap) if any_phase else problem.gap + max(
            float(affine(m, it.ref)[:, 0].max()) for it, m in zip(items, hint))
    if limit is None:
        raise ValueError("the dotted-board model needs a hint or a length limit")
    return limit


def _solver(cp_model, seconds: float, workers: int):
    """A CP-SAT solver tuned for the dotted board, stopping after ``seconds``."""
    solver = cp_model.CpSolver()
    solver.parameters.max_time_in_seconds = seconds
    solver.parameters.num_workers = max(1, min(workers, os.cpu_count() or 1))
    # one presolve pass, no probing, no symmetry detection: the model is already tight and
    # its at-most-ones are large, so the default presolve took 2.8 s of a t-shirt p2 nest
    # (2091 positions) before the hint was read, this one 0.8 s; time to the proven optimum
    # on five Berkeley cases 14.0 s -> 10.3 s in all (cp_model_presolve off: 4 not in 20 s)
    solver.parameters.max_presolve_iterations = 1
    solver.parameters.cp_model_probing_level = 0
    solver.parameters.symmetry_level = 0
    return solver


class _Board:
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

    def solve_left_to_right_first(self, seconds: float, workers: int, reporter,
                                  least: float):
        """(solver, status): ``FIXED_SHARE`` of ``seconds`` of depth-first search (the
        largest pieces first, each tried bottom to top, left to right), then the default
        search from its best marker if ``least`` s (its presolve) are left; the better."""
        cp = self.cp_model
        literals = []
        for i in sorted(range(len(self.items)), key=lambda i: -self.area_of[i]):
            o = self.opts[i]
            literals += [self.x[self.ids[i][j]] for j in np.lexsort((o.left, o.bottom))]
        self.model.add_decision_strategy(literals, cp.CHOOSE_FIRST, cp.SELECT_MAX_VALUE)
        # without the hint, which held the search near it (t-shirt p1: 865 mm for 2.5 s)
        hint = self.model.proto.solution_hint
        hinted = dict(zip(list(hint.vars), list(hint.values)))
        self.model.clear_hints()
        t0 = time.monotonic()
        first = _solver(cp, FIXED_SHARE * seconds, workers)
        first.parameters.search_branching = cp.FIXED_SEARCH
        status = first.solve(self.model, reporter)
        rest = seconds - (time.monotonic() - t0)
        if status in (cp.OPTIMAL, cp.INFEASIBLE) or rest < least:
            return first, status
        self.model.proto.search_strategy.clear()
        if status == cp.FEASIBLE:  # its marker: never longer than the hint (the limit)
            hinted = {v.index: first.value(v) for v in [*self.x, self.right, self.left]}
        for index, value in hinted.items():
            self.model.proto.solution_hint.vars.append(index)
            self.model.proto.solution_hint.values.append(value)
        second = _solver(cp, rest, workers)
        then = second.solve(self.model, reporter)
        if then == cp.OPTIMAL or (then == cp.FEASIBLE and (
                status != cp.FEASIBLE or second.objective_value <= first.objective_value)):
            return second, then
        return first, status

    def add_hint(self, hint: list[np.ndarray]) -> None:
        """Start from the ``hint`` marker, complete (every boolean): CP-SAT then starts
        from it at once. Interchangeable copies take their positions in option order."""
        local = [_option_of(it, m, o) for it, m, o in zip(self.items, hint, self.opts)]
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
            moves.append(_move(it, self.opts[i], j))
        g = self.problem.gap
        if any_phase:
            return moves, marker_span(self.items, moves, g)
        return moves, g + max(float(affine(m, it.ref)[:, 0].max())
                              for it, m in zip(self.items, moves))


def _move(item: Item, opts: Options, j: int) -> np.ndarray:
    m = item.candidates[int(opts.cand[j])].copy()
    m[:, 2] += item.lattice @ opts.k[j]
    return m


def _option_of(item: Item, move: np.ndarray, opts: Options) -> int | None:
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


def narrow_bound(problem: NestProblem, items: list[Item], best: DottedResult, *,
                 time_limit: float | Deadline, probe: float, first: float | None = None,
                 progress: Progress | None = None, tol: float = 0.5,
                 any_phase: bool = False) -> DottedResult:
    """Narrow ``best``'s interval [bound, length] by bisection on the marker length.

    Each probe asks for a marker no longer than a target, within ``probe`` seconds: none
    exists (proved) raises the bound, one found lowers the length. A probe that proves
    nothing in time is retried nearer the bound, where refuting is easier. ``first``: a
    target to probe before bisecting (the length that would meet an aim). Minimising
    the length directly proved the bound slowly where many markers are nearly optimal
    (t-shirt, p2: 638 mm, the area bound, after 60 s), single probes fast (no marker up
    to 708 mm in 7 s, up to 800 mm in 26 s).
    """
    deadline = deadline_of(time_limit)
    lo, hi, moves = best.bound, best.length, best.moves
    top = hi  # probes above ``top`` timed out
    target = first if first is not None and lo < first < hi else None
    while hi - lo > tol and deadline.left() > 0.5:
        if target is None:
            target = 0.5 * (lo + min(hi, top))
        r = dotted_nest(problem, items, time_limit=deadline.within(probe), limit=target,
                        progress=progress, any_phase=any_phase)
        if r is None:
            top = target
        elif r.moves is None:
            lo = target
        else:
            hi, moves = r.length, r.moves
        if progress:
            progress(f"dotted bound: probe {target:.1f} mm -> "
                     f"{'unknown' if r is None else 'none' if r.moves is None else 'found'}; "
                     f"[{lo:.1f}, {hi:.1f}]")
        target = None
        if top - lo <= tol:
            break
    return DottedResult(moves, hi, lo, hi - lo <= tol, best.options, best.build_s,
                        best.solve_s)
