"""Step 4 of a job: the marker, every aligned piece's cut line nested on the fabric in
view, each kept on its print position (on plain cloth, free of any print)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from solver.garment import Garment
from solver.nest.budget import Deadline
from solver.nest.layout import Layout, verify_layout
from solver.nest.solve import nest
from solver.nest.sources import placement_problem
from solver.placement import Placement
from station.allowance import rules_for_job
from station.config import Config


def nest_placement(garment: Garment, placement: Placement, config: Config,
                   progress: Callable[[str], None] | None = None,
                   options: dict[str, Any] | None = None, *, plain: bool = False) -> Layout:
    """The verified marker of the placed pieces (fabric mm); ``options`` are the job's
    (its seam allowances), ``plain`` nests without the print."""
    n = config["nest"]
    deadline = Deadline(n["seconds"])  # making the cut lines and verifying count too
    problem = placement_problem(garment, placement, width=n["width_mm"],
                                length=n["length_mm"], gap=n["gap_mm"],
                                allowance=rules_for_job(config, options or {}), plain=plain)
    layout = nest(problem, time_limit=deadline, seed=0, progress=progress)
    faults = verify_layout(layout, problem)
    if faults:
        raise ValueError(f"the marker failed verification: {faults[0]}")
    return layout
