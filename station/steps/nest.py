"""Step 4 of a job: the marker, every aligned piece's cut line nested on the fabric in
view, each kept on its print position (on plain cloth, free of any print).

A marker longer than the table window is not refused: when the pieces cannot lie in one
window (their area alone says so, or the nest within the window fails), they are nested
on the roll without a length limit and cut into bites of the window
(`station.steps.bites.plan_job_bites`, issue 35); the `BitePlan` says which bite each
piece is cut in.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

from solver.garment import Garment
from solver.nest.bites import BitePlan
from solver.nest.budget import Deadline
from solver.nest.instance import NestProblem
from solver.nest.layout import Layout, verify_layout
from solver.nest.solve import nest
from solver.nest.sources import placement_problem
from solver.placement import Placement
from station.allowance import rules_for_job
from station.config import Config
from station.steps.bites import plan_job_bites
from station.steps.table import TableWindow, config_window

#: above this share of the window's area in pieces, one window cannot hold the marker
#: (no nest packs denser): it is planned in bites at once, without trying the window
WINDOW_FILL_LIMIT = 0.9


def nest_placement(garment: Garment, placement: Placement, config: Config,
                   progress: Callable[[str], None] | None = None,
                   options: dict[str, Any] | None = None, *, plain: bool = False) -> Layout:
    """The verified marker of the placed pieces (fabric mm); ``options`` are the job's
    (its seam allowances), ``plain`` nests without the print."""
    deadline = Deadline(config["nest"]["seconds"])  # making the cut lines counts too
    problem = placement_problem(garment, placement, **problem_size(config),
                                allowance=rules_for_job(config, options or {}), plain=plain)
    return nest_verified(problem, deadline, progress)


def placed_marker(garment: Garment, placement: Placement, config: Config,
                  progress: Callable[[str], None] | None = None,
                  options: dict[str, Any] | None = None, *, plain: bool = False,
                  can_bite: bool = True) -> tuple[Layout, BitePlan | None]:
    """(the verified marker, its bites or None): as `nest_placement`, but a marker longer
    than the table window is nested on the roll and planned in bites (when ``can_bite``: the
    station can find the print again after an advance)."""
    seconds = config["nest"]["seconds"]
    deadline = Deadline(seconds)  # making the cut lines and verifying count too
    problem = placement_problem(garment, placement, **problem_size(config),
                                allowance=rules_for_job(config, options or {}), plain=plain)
    return nest_in_window_or_bites(problem, config_window(config), seconds, progress,
                                   deadline=deadline, can_bite=can_bite)


def problem_size(config: Config) -> dict[str, float]:
    """The roll's width, the window's length and the gap, as the nest problems take them."""
    n = config["nest"]
    return {"width": n["width_mm"], "length": n["length_mm"], "gap": n["gap_mm"]}


def nest_verified(problem: NestProblem, deadline: Deadline,
                  progress: Callable[[str], None] | None = None) -> Layout:
    """``problem`` nested and verified; a fault is a ValueError. On a print the marker
    may start at any phase of it (the roll is cut wherever its print lies): its pieces
    lie on the print as found, and ``Layout.phase_mm`` says where it starts."""
    layout = nest(problem, time_limit=deadline, seed=0, progress=progress, any_phase=True)
    faults = verify_layout(layout, problem)
    if faults:
        raise ValueError(f"the marker failed verification: {faults[0]}")
    return layout


def nest_in_window_or_bites(problem: NestProblem, window: TableWindow, seconds: float,
                            progress: Callable[[str], None] | None = None, *,
                            deadline: Deadline | None = None, can_bite: bool = True
                            ) -> tuple[Layout, BitePlan | None]:
    """(the marker, its bites or None): the marker within the window when it fits there
    (by ``deadline``, default ``seconds`` from now), else nested on the roll with no
    length limit, in ``seconds`` more, and planned in bites of the window. A station that
    cannot cut in bites (``can_bite`` False: no camera to find the print after an advance)
    gets the window's nest or its refusal, never bites it could not cut."""
    area = sum(p.area * p.quantity * (2 if p.mirrored_pair else 1) for p in problem.pieces)
    if not can_bite or area < WINDOW_FILL_LIMIT * window.length * window.width:
        try:  # the whole time, as ever: a marker that fits is nested as it always was
            return nest_verified(problem, deadline or Deadline(seconds), progress), None
        except ValueError as exc:
            if "verification" in str(exc) or not can_bite:
                raise  # a fault of the nest, or no bites: not a marker for the roll
    roll = replace(problem, length=None)  # (a second budget: the window was not enough)
    bites = plan_job_bites(nest_verified(roll, Deadline(seconds), progress), window,
                           problem.lattice)
    faults = verify_layout(bites.layout, roll)  # its blocks moved off the boundaries
    if faults:
        raise ValueError(f"the marker's bites failed verification: {faults[0]}")
    return bites.layout, bites
