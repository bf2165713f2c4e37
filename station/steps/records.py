"""The objects planning hands on: `Plan` (what the cut and the pictures need) and its
`Stage` list (the states of the fit, one picture each)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gcode.layout import Layout as MachineLayout
from gcode.program import Program
from solver.fit import FitReport
from solver.garment import Garment
from solver.garment.allowance import AllowanceRules
from solver.nest.bites import BitePlan
from solver.nest.layout import Layout
from solver.placement import Placement
from solver.wallpaper import Wallpaper
from station.steps.capture import Captured


@dataclass
class Stage:
    """One state of the pattern on the print, for its picture: with ``rules`` (the job's
    seam allowances) the cut lines and notches, with ``original`` the outlines before
    reshaping."""

    picture: Path
    title: str
    garment: Garment
    placement: Placement
    fit: FitReport
    rules: AllowanceRules | None = None
    original: Garment | None = None


@dataclass
class Plan:
    """What planning made: the pattern cut, its placement, the marker (the solver's and
    the machine's) and the checked program; what the pictures need (the print, the
    stages of the fit); and the report; ``bites`` when the marker is cut in bites (then
    ``marker`` and ``program`` are the first bite's). `record` is what the job store
    keeps."""

    job_dir: Path
    captured: Captured
    garment: Garment
    garment_path: Path
    placement: Placement
    layout: Layout
    marker: MachineLayout
    program: Program
    report: dict[str, Any]
    wallpaper: Wallpaper | None = None
    fit: FitReport | None = None
    stages: list[Stage] = field(default_factory=list)
    bites: BitePlan | None = None  # a marker longer than the table: cut in these bites

    @property
    def pieces(self) -> list[str]:
        return [p.id for p in self.layout.pieces]

    def record(self) -> dict[str, Any]:
        d = self.job_dir
        garments = {p.id: p.garment for p in self.layout.pieces if p.garment}
        return {"fabric": self.captured.path, "garment": str(self.garment_path),
                "placement": str(d / "placement.json"), "layout": str(d / "layout.json"),
                "program": str(d / "job.nc"), "report": str(d / "report.json"),
                "pieces": self.pieces,
                **({"bites": str(d / "bites.json")} if self.bites is not None else {}),
                **({"garments": garments} if garments else {})}  # an order's: piece -> garment
