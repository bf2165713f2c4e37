"""How CP-SAT searches the dotted board (:mod:`solver.nest.dotted_board`).

Found phase, CP-SAT's default search from the hint. Free of phase, a depth-first pass
first: the largest pieces first, each tried bottom to top, then left to right (CP-SAT's
fixed search), the first piece tried one period in from the roll's start before it is
tried within the first period; then the default search from its marker with what is left.
"""

from __future__ import annotations

import os
import time

import numpy as np

from solver.nest.dotted_board import Board

# any phase: share of the solver's time for the depth-first pass, before the default
# search from its marker. T-shirt p1: 822.5 mm proven in 1 s (the default search: 865 mm
# after 10 s); p2: 814 mm in 1.4-2.3 s (left to right first: 853 mm after 8 s)
FIXED_SHARE = 0.75


def cp_solver(cp_model, seconds: float, workers: int):
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


def depth_first_solver(cp_model, seconds: float, workers: int):
    """The solver of the depth-first pass: CP-SAT's fixed search in the model's order,
    without presolve and without the linear relaxation, neither of which it needs.

    T-shirt (2590 positions, 1.4 M literals in the at-most-ones), load 4-6: presolve
    took 1.2-2.4 s before the first marker, and the relaxation of the at-most-ones made
    each branch slow (p1: 5950 branches in 4 s, no proof). Without both, the first period
    last (:func:`depth_first_order`): p2 814 mm after 1.4-2.3 s of solving, p1 822.5 mm
    proven shortest in 0.8-1.5 s; with them, 2.5-5.2 s and 1.0-1.8 s.
    """
    solver = cp_solver(cp_model, seconds, workers)
    solver.parameters.search_branching = cp_model.FIXED_SEARCH
    solver.parameters.cp_model_presolve = False
    solver.parameters.linearization_level = 0
    return solver


def depth_first_order(board: Board, period: float) -> list:
    """The booleans in the depth-first pass's order: the largest pieces first, each
    bottom to top, then left to right; the first piece one period in first.

    Free of phase the marker starts where its leftmost piece does, within the first
    period, so the first piece placed there leaves no room before it: on the t-shirt p2
    the pass spent 2-4 s of its first 5 proving that no marker is shorter with the body
    leftmost, and the shortest starts with a sleeve 7 mm before it. One period in, every
    phase of the pieces before it is open. The positions of the first period come last.
    """
    g = board.problem.gap
    order = sorted(range(len(board.items)), key=lambda i: -board.area_of[i])
    literals = []
    for n, i in enumerate(order):
        o = board.opts[i]
        left = o.left + np.where(o.left < g + period, np.inf, 0.0) if n == 0 else o.left
        literals += [board.x[board.ids[i][j]] for j in np.lexsort((left, o.bottom))]
    return literals


def depth_first(board: Board, period: float, solver, reporter=None) -> tuple[int, dict]:
    """(status, hint): ``solver`` (:func:`depth_first_solver`) run on the board in
    :func:`depth_first_order`, without the board's hint, which held the search near it
    (t-shirt p1: 865 mm for 2.5 s); ``hint`` is that hint's values by variable index."""
    cp, model = board.cp_model, board.model
    model.add_decision_strategy(depth_first_order(board, period), cp.CHOOSE_FIRST,
                                cp.SELECT_MAX_VALUE)
    hint = model.proto.solution_hint
    hinted = dict(zip(list(hint.vars), list(hint.values)))
    model.clear_hints()
    return solver.solve(model, reporter), hinted


def depth_first_then_default(board: Board, period: float, seconds: float, workers: int,
                             reporter, least: float):
    """(solver, status): ``FIXED_SHARE`` of ``seconds`` of the depth-first pass
    (:func:`depth_first`), then the default search from its best marker if ``least`` s
    (its presolve) are left; the better of the two."""
    cp, model = board.cp_model, board.model
    t0 = time.monotonic()
    first = depth_first_solver(cp, FIXED_SHARE * seconds, workers)
    status, hinted = depth_first(board, period, first, reporter)
    rest = seconds - (time.monotonic() - t0)
    if status in (cp.OPTIMAL, cp.INFEASIBLE) or rest < least:
        return first, status
    model.proto.search_strategy.clear()
    if status == cp.FEASIBLE:  # its marker: never longer than the hint (the limit)
        hinted = {v.index: first.value(v) for v in [*board.x, board.right, board.left]}
    for index, value in hinted.items():
        model.proto.solution_hint.vars.append(index)
        model.proto.solution_hint.values.append(value)
    second = cp_solver(cp, rest, workers)
    then = second.solve(model, reporter)
    if then == cp.OPTIMAL or (then == cp.FEASIBLE and (
            status != cp.FEASIBLE or second.objective_value <= first.objective_value)):
        return second, then
    return first, status
