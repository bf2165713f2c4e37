"""Steps 2 to 5 together: planning one job, from the captured print to a checked program.

`plan_job` reads as the recipe: the garment (`steps.garment`), its placement on the print
(`steps.place`: aligned, optionally reshaped; on plain cloth only turned onto the grain),
the marker (`steps.nest`), the program (`steps.program`). It hands back a `Plan`, the
objects the cut and the pictures need; each step also writes its file into the job's
folder (placement.json, layout.json, job.nc, report.json after every step) for the
operator and for a job resumed by another process, never read back here.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from gcode.machine import Machine
from solver.fit import FitReport, fit_report
from solver.garment import Garment, save_obj
from solver.nest.bites import BitePlan
from solver.nest.layout import Layout
from solver.placement import Placement
from solver.reshape import ReshapeReport
from solver.wallpaper import Wallpaper
from station.allowance import rules_for_job
from station.config import Config
from station.daemon import JobControl
from station.jobstore import Job
from station.steps.capture import Captured
from station.steps.garment import grained, job_garment
from station.steps.nest import placed_marker
from station.steps.pictures import draw_fits
from station.steps.place import align_job, plain_placement, reshape_placed
from station.steps.program import planned_program
from station.steps.records import Plan, Stage
from station.stripes import stripe_grain, stripe_print

log = logging.getLogger("station.plan")
Cut = TypeVar("Cut")  # what a marker is nested of: a pattern, or an order's garments
Nested = TypeVar("Nested")

FABRIC_KEYS = ("group", "w1", "w2", "origin", "source", "confidence", "kind", "period_mm",
               "direction_deg", "grain_deg", "note")


class JobReport:
    """report.json, written after every step so a failed job still shows what it got
    to, with the seconds each step took."""

    def __init__(self, path: Path, data: dict[str, Any]) -> None:
        self.path, self.data = path, {**data, "seconds": {}}
        self._clock = time.perf_counter()

    def step_done(self, step: str) -> None:
        now = time.perf_counter()
        self.data["seconds"][step] = round(now - self._clock, 3)
        self._clock = now
        self.write()

    def write(self) -> None:
        self.path.write_text(json.dumps(self.data, indent=2, default=float))


@dataclass
class Pattern:
    """A pattern placed on the print: the garment, the job's copy of it, its fit."""

    garment: Garment
    path: Path
    fit: FitReport | None = None
    units: str | None = None  # the file's units, when it does not say them itself


def plan_job(job: Job, captured: Captured, workdir: Path, config: Config, machine: Machine,
             control: JobControl, *, can_bite: bool = True) -> Plan:
    """Align, optionally reshape, nest and program one job (see the module's docstring);
    ``can_bite``: a marker longer than the table may be cut in bites (the station has a
    camera to find the print again after each advance)."""
    garment, garment_path, symmetrised = job_garment(job, workdir, config)
    kind = captured.fabric.get("kind")
    report = JobReport(workdir / "report.json", {"job": job.id, "garment": job.garment})
    stages: list[Stage] = []  # the states of the fit, for the pictures
    if kind == "plain" or (kind == "stripes" and not job.options.get("match_stripes", True)):
        wallpaper = None  # nothing to align: the pieces are nested on grain as drawn
        chosen = Pattern(grained(garment, config, job.options), garment_path)
        placement = _on_grain(chosen, captured, config, report)
        control.start_step("nesting", 0.0)
        layout, bites = _nest(chosen, placement, workdir, config, job.options, None,
                              plain=True, can_bite=can_bite)
    else:
        wallpaper = print_of(captured, config, report)
        if symmetrised is not None:
            report.data["symmetrise"] = symmetrised.to_dict()
        try:
            patterns, placement = _place(job, Pattern(garment, garment_path), wallpaper,
                                         config, control, report, stages)
            chosen, (layout, bites) = _nest_printed(job, patterns, placement, workdir, config,
                                                    control, report, can_bite)
        except BaseException:
            draw_fits(stages, captured, wallpaper)  # a failed job shows what it got to
            raise
    marker, program = program_step(layout, bites, config, machine, workdir, control, report)
    return Plan(workdir, captured, chosen.garment, chosen.path, placement, layout, marker,
                program, report.data, wallpaper, chosen.fit, stages, bites)


def program_step(layout: Layout, bites: BitePlan | None, config: Config, machine: Machine,
                 workdir: Path, control: JobControl, report: JobReport):
    """The nest's figures into the report, then the machine's program from the marker (one
    garment's or a whole order's): the step after nesting, written once."""
    report.data["nest"] = {"length_mm": layout.length, "width_mm": layout.width,
                           "density": layout.density, "pieces": len(layout.pieces),
                           "phase_mm": layout.phase_mm,  # where the marker starts
                           **({"bites": bites.summary()} if bites is not None else {})}
    report.step_done("nest")
    control.checkpoint()
    control.start_step("programming")
    marker, program = planned_program(layout, bites, config, machine, workdir)
    report.data["program"] = program.summary()
    report.step_done("program")
    return marker, program


def print_of(captured: Captured, config: Config, report: JobReport) -> Wallpaper:
    """The print to align on: capture's object, else FABRIC.json's (a stripe print as
    the 1-D lattice that matches stripes across the seams); the report names it."""
    fabric = captured.fabric
    if fabric.get("kind") == "stripes":
        fabric = stripe_print(fabric, config["align"]["fabric_grain_deg"])
    report.data["fabric"] = {k: fabric.get(k) for k in FABRIC_KEYS if k in fabric}
    if captured.wallpaper is not None and fabric is captured.fabric:
        return captured.wallpaper
    return Wallpaper.from_dict(fabric, captured.path)  # a file: checked as untrusted


def _on_grain(pattern: Pattern, captured: Captured, config: Config, report: JobReport
              ) -> Placement:
    """Plain cloth (the camera found only the weave), or stripes the job does not match:
    each piece turned so that its grain runs along the cloth's (stripes set it)."""
    cloth = stripe_grain(captured.fabric, config["align"]["fabric_grain_deg"])
    report.data["fabric"] = cloth
    return plain_placement(pattern.garment, config, cloth["grain_deg"])


def _place(job: Job, pattern: Pattern, wallpaper: Wallpaper, config: Config,
           control: JobControl, report: JobReport, stages: list[Stage]
           ) -> tuple[list[Pattern], Placement]:
    """(the patterns to try, best first: reshaped, then aligned; the placement). Each
    state of the fit joins ``stages`` for its picture."""
    garment, group, folder = pattern.garment, wallpaper.group, pattern.path.parent
    before = Placement.identity(garment.n_pieces, wallpaper)
    identity = fit_report(garment, before)
    report.data["e_fit_identity_mm2"] = identity.e_fit_mm2
    stages.append(Stage(folder / "fit-before.png", f"before alignment on {group}", garment,
                        before, identity))
    control.start_step("aligning", 0.0)

    def on_restart(k: int, n: int, _e_random: float, _e_aligned: float) -> None:
        control.progress.update(step="aligning", fraction=min(1.0, k / max(n, 1)))
        control.checkpoint()

    garment = grained(garment, config, job.options)
    placement = align_job(garment, wallpaper, config, job.options, on_restart,
                          fabric_grain_deg=report.data["fabric"].get("grain_deg"))
    placement.garment = str(pattern.path)
    report.data["align"] = placement.report
    aligned = Pattern(garment, pattern.path, fit_report(garment, placement),
                      placement.garment_units)
    rules = rules_for_job(config, job.options)
    report.data["allowance"] = rules.to_dict()
    stages.append(Stage(folder / "fit-aligned.png", f"aligned on {group}", garment,
                        placement, aligned.fit, rules))
    report.step_done("align")
    control.checkpoint()
    if not reshaping(job, config):
        return [aligned], placement
    control.start_step("reshaping")
    fitted, reshaped = reshape_step(aligned, placement, config, folder / "garment-reshaped.obj")
    report.data["reshape"] = reshaped.to_dict()
    stages.append(Stage(folder / "fit-reshaped.png", f"reshaped on {group}", fitted.garment,
                        placement, fitted.fit, rules, original=garment))
    report.step_done("reshape")
    control.checkpoint()
    return [fitted, aligned], placement


def reshaping(job: Job, config: Config) -> bool:
    """Whether ``job`` is reshaped: its option, else the station's ``[reshape] enabled``."""
    return bool(job.options.get("reshape", config["reshape"]["enabled"]))


def reshape_step(aligned: Pattern, placement: Placement, config: Config, path: Path
                 ) -> tuple[Pattern, ReshapeReport]:
    """(the pattern nudged so the print fits across its seams on ``placement``, written at
    ``path`` as an OBJ in mm for the operator and whatever reads the plan back; its fit),
    and the reshape's report: one garment's, or one style and size of an order's."""
    new, reshaped = reshape_placed(aligned.garment, placement, config)
    if reshaped.seams_out_of_reach:  # the report's seams say what each would take
        log.warning("reshape: no change within %g mm fits the print across %s: their ideal "
                    "lines turn up to %.0f deg away (see report.json, reshape.seams)",
                    config["reshape"]["max_move_mm"], ", ".join(reshaped.seams_out_of_reach),
                    max(s["ideal_turn_deg"] for s in reshaped.seams if not s["within_reach"]))
    save_obj(new, path)
    return Pattern(new, path, fit_report(new, placement), "mm"), reshaped


def nest_progress(control: JobControl, config: Config) -> Callable[[str], None]:
    """The nest's progress callback, the nesting step started: the share of the station's
    nesting time spent."""
    seconds = config["nest"]["seconds"]
    control.start_step("nesting", 0.0)
    t0 = time.monotonic()

    def on_nest(_message: str) -> None:
        control.progress.update(step="nesting", fraction=min(
            1.0, (time.monotonic() - t0) / seconds))

    return on_nest


def first_nested(job: Job, candidates: list[Cut], nest: Callable[[Cut], Nested],
                 report: JobReport) -> tuple[Cut, Nested]:
    """(the candidate cut, its marker): the first (reshaped) if the cutter can use it, else,
    saying so, the next (aligned): a reshaped outline crossing itself must not stop the
    job. A candidate is a garment's pattern or an order's garments."""
    for candidate in candidates[:-1]:
        try:
            return candidate, nest(candidate)
        except ValueError as exc:
            log.error("job %d: the reshaped pattern cannot be nested (%s); cutting the "
                      "aligned pattern instead", job.id, exc)
            report.data["reshape"]["rejected"] = f"not used for cutting: {exc}"
    return candidates[-1], nest(candidates[-1])


def _nest_printed(job: Job, patterns: list[Pattern], placement: Placement, workdir: Path,
                  config: Config, control: JobControl, report: JobReport, can_bite: bool
                  ) -> tuple[Pattern, tuple[Layout, BitePlan | None]]:
    """(the pattern cut, its marker): `first_nested` of the reshaped and aligned ones."""
    def nest_one(pattern: Pattern) -> tuple[Layout, BitePlan | None]:
        return _nest(pattern, placement, workdir, config, job.options,
                     nest_progress(control, config), can_bite=can_bite)

    return first_nested(job, patterns, nest_one, report)


def _nest(pattern: Pattern, placement: Placement, workdir: Path, config: Config,
          options: dict[str, Any], progress, *, plain: bool = False, can_bite: bool = True
          ) -> tuple[Layout, BitePlan | None]:
    """(the marker of ``pattern``, its bites if longer than the table); placement.json
    and layout.json written beside it."""
    placement.garment = str(pattern.path)
    placement.garment_units = pattern.units or placement.garment_units  # reshaped: mm
    placement.save(workdir / "placement.json")
    layout, bites = placed_marker(pattern.garment, placement, config, progress, options,
                                  plain=plain, can_bite=can_bite)
    layout.save(workdir / "layout.json")
    return layout, bites
