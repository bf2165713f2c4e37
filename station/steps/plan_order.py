"""Steps 2 to 5 for a job that is an order: every garment (style, size, copy) loaded and
aligned by the same steps as a single garment (`steps.garment.grained`,
`steps.place.align_job`, or `plain_placement` on plain cloth), one marker holding every
piece of the order (`steps.order`), then the program (`steps.program`).

It writes what `plan_job` writes (placement.json as the order's placements, layout.json,
job.nc, report.json) and hands back the same `Plan`; its pictures are the marker (titled
with the order and its size ratio) and the toolpath.
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

from gcode.machine import Machine
from solver.garment import Garment
from solver.nest.bites import BitePlan
from solver.nest.layout import Layout
from solver.placement import Placement
from station.allowance import rules_for_job
from station.config import Config
from station.daemon import JobControl
from station.jobstore import Job
from station.order import OrderGarment, read_order
from station.steps.capture import Captured
from station.steps.garment import grained
from station.steps.nest import nest_in_window_or_bites
from station.steps.order import align_order, order_problem, write_aligned
from station.steps.place import align_job, plain_placement
from station.steps.plan import JobReport, print_of, program_step
from station.steps.records import Plan
from station.steps.table import config_window
from station.stripes import stripe_grain


def plan_order(job: Job, captured: Captured, workdir: Path, config: Config, machine: Machine,
               control: JobControl) -> Plan:
    """Align every garment of the order, nest them in one marker, program it."""
    order = read_order(job.garment)
    job = replace(job, options=order.job_options(job.options))  # the order's match_notches
    report = JobReport(workdir / "report.json", {"job": job.id, "garment": job.garment,
                                                 "order": order.to_dict()})
    kind = captured.fabric.get("kind")
    plain = kind == "plain" or (kind == "stripes" and not job.options.get("match_stripes",
                                                                          True))
    wallpaper = None if plain else print_of(captured, config, report)
    control.start_step("aligning", 0.0)
    done = 0

    def align_one(garment: Garment, item: OrderGarment) -> Placement:
        nonlocal done
        control.progress.update(step="aligning", fraction=done / len(order.garments))
        control.checkpoint()
        garment = grained(garment, config, job.options)
        done += 1
        if wallpaper is None:
            cloth = stripe_grain(captured.fabric, config["align"]["fabric_grain_deg"])
            return plain_placement(garment, config, cloth["grain_deg"])
        return align_job(garment, wallpaper, config, job.options,
                         fabric_grain_deg=report.data["fabric"].get("grain_deg"))

    inset = (rules_for_job(config, job.options).seam_mm, "the station's seam allowance")
    aligned = align_order(order, align_one, inset)
    write_aligned(order, aligned, workdir / "placement.json")
    report.data["garments"] = [a.report() for a in aligned]
    if config["reshape"]["enabled"]:  # said in the job's report, never silently skipped
        report.data["reshape"] = {"note": "not run for an order: each garment is cut as "
                                          "aligned"}
    report.step_done("align")
    control.checkpoint()
    layout, bites = _nest(aligned, config, job, control, plain=wallpaper is None)
    layout.save(workdir / "layout.json")
    marker, program = program_step(layout, bites, config, machine, workdir, control, report)
    first = aligned[0]
    return Plan(workdir, captured, first.garment, Path(job.garment), first.placement, layout,
                marker, program, report.data, wallpaper, bites=bites)


def _nest(aligned, config: Config, job: Job, control: JobControl, *, plain: bool
          ) -> tuple[Layout, BitePlan | None]:
    """(the order's verified marker within the station's nesting time, its bites when it
    is longer than the table window)."""
    n = config["nest"]
    control.start_step("nesting", 0.0)
    t0 = time.monotonic()

    def on_nest(_message: str) -> None:
        control.progress.update(step="nesting", fraction=min(
            1.0, (time.monotonic() - t0) / n["seconds"]))

    problem = order_problem(aligned, width=n["width_mm"], length=n["length_mm"],
                            gap=n["gap_mm"], allowance=rules_for_job(config, job.options),
                            plain=plain)
    return nest_in_window_or_bites(problem, config_window(config), n["seconds"], on_nest)
