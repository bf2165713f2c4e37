"""One entry point for nesting: plain or printed fabric, window, keep-outs."""

from __future__ import annotations

import numpy as np

from solver.nest.budget import Deadline, Progress, deadline_of, finish_reserve
from solver.nest.instance import NestProblem, affine
from solver.nest.lattice import nest_lattice
from solver.nest.layout import Layout, build_layout
from solver.nest.naive import nest_naive
from solver.nest.plain import plain_moves
from solver.nest.regions import repair

METHODS = ("auto", "resnap", "resnap-margin", "fill", "repair", "coset", "joint", "naive")


def nest(problem: NestProblem, *, time_limit: float | Deadline = 30.0, seed: int | None = 0,
         progress: Progress | None = None, method: str = "auto",
         any_phase: bool = False) -> Layout:
    """Nest ``problem``; on a print ``method`` picks the search (auto: best of all).

    ``any_phase``: on a print, the marker may start at any phase of it (a roll is cut
    wherever its print lies; the station's every job): the layout's ``phase_mm`` says
    where it starts on the print as found (:func:`solver.nest.lattice.nest_lattice`).

    Plain fabric goes to sparrow; when the operator marked keep-outs or the table is
    shorter than sparrow's marker, the offending pieces are re-inserted around the rest.
    ``time_limit`` (seconds from now, or the caller's Deadline) covers everything up to a
    verified layout: the searches stop early enough to leave building and verifying it.
    """
    if method not in METHODS:
        raise ValueError(f"unknown nesting method {method!r}; expected one of {METHODS}")
    _check_widths(problem)
    items = problem.items()
    deadline = deadline_of(time_limit).before(
        finish_reserve(len(items), printed=problem.fabric is not None))
    if problem.fabric is not None:
        if method == "naive":
            layout = nest_naive(problem, time_limit=deadline, seed=seed, progress=progress)
        else:
            strategies = None if method == "auto" else (method,)
            layout = nest_lattice(problem, time_limit=deadline, seed=seed, progress=progress,
                                  strategies=strategies, any_phase=any_phase)
    else:
        regions = bool(problem.keepouts) or problem.length is not None
        share = 0.7 if regions else 1.0
        moves, length = plain_moves(problem, items, time_limit=deadline.share(share),
                                    seed=seed, progress=progress)
        if regions and (problem.keepouts or length > problem.length):
            r = repair(problem, items, moves, time_limit=deadline, seed=seed,
                       progress=progress)
            if r is None:
                raise ValueError(_no_fit(problem))
            moves = r[0]
        layout = build_layout(problem, items, moves)
    if problem.length is not None and layout.length > problem.length + 1e-9:
        raise ValueError(_no_fit(problem) + f" (needs {layout.length:.1f} mm)")
    return layout


def _check_widths(problem: NestProblem) -> None:
    """Refuse, naming the piece, one that is wider than the fabric at every allowed angle
    (the searches would only give up, sparrow with a panic)."""
    room = problem.width - 2 * problem.gap
    seen = set()
    for item in problem.items():
        free = problem.fabric is None and problem.pieces[item.piece].orientations is None
        if item.key in seen or free:  # free rotation: sparrow may find an angle between
            continue
        seen.add(item.key)
        across = min(float(np.ptp(affine(c, item.ref)[:, 1])) for c in item.candidates)
        if across > room + 1e-9:
            raise ValueError(f"piece {item.name!r} cannot be nested: it is {across:.1f} mm "
                             "across the roll at its narrowest allowed angle; the fabric "
                             f"leaves {room:g} mm "
                             "(wider fabric, --width, or a smaller allowance)")


def _no_fit(problem: NestProblem) -> str:
    """Why the pieces found no room: the window, or (no length given) the keep-outs."""
    if problem.length is None:
        return (f"the pieces do not fit on the fabric {problem.width:g} mm wide around its "
                f"{len(problem.keepouts)} keep-out(s)")
    return (f"the pieces do not fit on the fabric window {problem.length:g} x "
            f"{problem.width:g} mm")


def piece_area(layout: Layout) -> float:
    return float(np.sum([p.polygon().area for p in layout.pieces]))
