"""The exact printed nest: a dotted-board model on every allowed position, solved by CP-SAT.

On a printed fabric a piece may sit only at its allowed positions (the print's
grain-keeping operations times the lattice translations, :class:`Item`), a discrete set
in both directions. That is the *dotted-board* problem of Toledo, Carravilla, Ribeiro,
Oliveira and Gomes ("The Dotted-Board Model: a new MIP model for nesting irregular
shapes", Int. J. Production Economics 145 (2013) 478-487): one boolean per (piece,
allowed position), exactly one per piece, pairwise non-overlap from no-fit information,
minimise the marker length. Here:

- options (:mod:`solver.nest.dotted_options`): every candidate map x every lattice
  translation that keeps the outline on the roll (width, gap, keep-outs, table length)
  and ends before an upper bound (the best marker known);
- clashes (the same module): whether two pieces under two candidate maps collide
  depends only on their relative lattice offset, so the colliding offsets are tabulated
  once per (piece, map) pair with shapely (the gap semantics of ``verify_layout``) and
  expanded to option pairs by index arithmetic;
- the model (:mod:`solver.nest.dotted_board`): exactly one option per piece; per option
  ``a`` of piece A and each other piece B, ``x_a + sum(x_b: b clashes with a) <= 1``
  (B takes exactly one option, so this is exact, and far smaller than one constraint
  per clashing pair); the right edge ``R >= sum(right_a x_a)`` per piece; minimise
  ``R``: the marker starts at the roll's start, at the print's phase there. With
  ``any_phase`` it may start at any phase (a roll is cut wherever its print lies):
  minimise ``R - L``, ``L`` the left edge of the leftmost piece, one of the options'
  left edges within the first period.
  Translations across the roll (a lattice vector along y) are fixed by asking one piece
  to start within a period of the bottom edge;
- the search (:mod:`solver.nest.dotted_search`): free of phase, a depth-first pass first.

CP-SAT (OR-tools) proves a lower bound as it goes, so the answer says how far the
marker is from the best possible on this print, not only how long it is;
:func:`narrow_bound` tightens that bound by feasibility probes where minimising does not.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from solver.nest.budget import Deadline, Progress, deadline_of
from solver.nest.dotted_board import SCALE, Board
from solver.nest.dotted_options import item_options, positions
from solver.nest.dotted_search import cp_solver, depth_first_then_default
from solver.nest.instance import Item, NestProblem, affine, marker_span

# CP-SAT search workers: one proved the t-shirt's p1 optimum in 4.6 s, two in 8 s, four in
# 11 s on the station's two cores (the portfolio's helpers steal the main search's time)
WORKERS = 1
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


@dataclass
class DottedResult:
    moves: list[np.ndarray] | None  # None: none found (``bound`` says if none exists)
    length: float  # of ``moves`` (inf without)
    bound: float  # proven: no marker on these positions is shorter (mm)
    optimal: bool  # ``length == bound`` is proven (or, without moves, nothing fits)
    options: int  # booleans of the model
    build_s: float
    solve_s: float


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
    board = Board(problem, items, opts, cp_model)
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
        solver, status = depth_first_then_default(board, period, left, workers, reporter,
                                                  SOLVE_MIN * build)
    else:
        solver = cp_solver(cp_model, left, workers)
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
