"""Steps 2 to 5 for a job that is an order: every garment (style, size, copy) loaded and
aligned by the same steps as a single garment (`steps.garment.grained`,
`steps.place.align_job`, or `plain_placement` on plain cloth; a DXF style's seams
confirmed first, `steps.dxfseams`), reshaped when the job asks
as a single garment is (`steps.plan.reshape_step`, once per style and size; the aligned
garments are cut if the reshaped ones cannot be nested), one marker holding every piece
of the order (`steps.order`), then the program (`steps.program`).

It writes what `plan_job` writes (placement.json as the order's placements, layout.json,
job.nc, report.json) and hands back the same `Plan`; its pictures are the marker (titled
with the order and its size ratio) and the toolpath.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

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
from station.steps.dxfseams import order_dxf_garments
from station.steps.garment import grained
from station.steps.nest import nest_in_window_or_bites
from station.steps.order import OrderedGarment, align_order, order_problem, write_aligned
from station.steps.place import align_job, plain_placement
from station.steps.plan import (
    JobReport,
    Pattern,
    first_nested,
    nest_progress,
    print_of,
    program_step,
    reshape_step,
    reshaping,
)
from station.steps.records import Plan
from station.steps.table import config_window
from station.stripes import stripe_grain


def plan_order(job: Job, captured: Captured, workdir: Path, config: Config, machine: Machine,
               control: JobControl, *, can_bite: bool = True) -> Plan:
    """Align every garment of the order, nest them in one marker, program it (in bites of
    the table when it is longer and ``can_bite``: see `station.steps.plan.plan_job`)."""
    order = read_order(job.garment)
    job = replace(job, options=order.job_options(job.options))  # the order's match_notches
    report = JobReport(workdir / "report.json", {"job": job.id, "garment": job.garment,
                                                 "order": order.to_dict()})
    kind = captured.fabric.get("kind")
    plain = kind == "plain" or (kind == "stripes" and not job.options.get("match_stripes",
                                                                          True))
    wallpaper = None if plain else print_of(captured, config, report)
    dxf_styles = order_dxf_garments(job, order, workdir, config)  # may wait: confirm seams
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
    aligned = align_order(order, align_one, inset, loaded=dxf_styles)
    report.data["garments"] = [a.report() for a in aligned]
    report.step_done("align")
    control.checkpoint()
    candidates = [aligned]  # reshaped first when asked, as for a single garment
    if wallpaper is not None and reshaping(job, config):
        candidates.insert(0, _reshaped(aligned, config, workdir, control, report))

    def nest_one(garments: list[OrderedGarment]) -> tuple[Layout, BitePlan | None]:
        write_aligned(order, garments, workdir / "placement.json")
        return _nest(garments, config, job, control, plain=wallpaper is None,
                     can_bite=can_bite)

    cut, (layout, bites) = first_nested(job, candidates, nest_one, report)
    layout.save(workdir / "layout.json")
    marker, program = program_step(layout, bites, config, machine, workdir, control, report)
    first = cut[0]
    return Plan(workdir, captured, first.garment, Path(job.garment), first.placement, layout,
                marker, program, report.data, wallpaper, bites=bites)


def _reshaped(aligned: list[OrderedGarment], config: Config, workdir: Path,
              control: JobControl, report: JobReport) -> list[OrderedGarment]:
    """The order's garments reshaped on their placements by the single garment's step
    (`steps.plan.reshape_step`), once per style and size (copies share it, as they share
    their alignment); the report gives each one's reshape."""
    control.start_step("reshaping", 0.0)
    styles = {(a.item.pattern, a.item.size, a.item.units) for a in aligned}
    done: dict[tuple, tuple[Pattern, dict[str, Any]]] = {}
    out = []
    for a in aligned:
        style = (a.item.pattern, a.item.size, a.item.units)
        if style not in done:
            control.progress.update(step="reshaping", fraction=len(done) / len(styles))
            control.checkpoint()
            path = workdir / f"garment-{len(done) + 1}-reshaped.obj"
            fitted, reshaped = reshape_step(Pattern(a.garment, Path(a.item.pattern)),
                                            a.placement, config, path)
            done[style] = fitted, {"garments": [], "pattern": str(a.item.pattern),
                                   "size": a.item.size, "reshaped": path.name,
                                   **reshaped.to_dict()}
        fitted, style_report = done[style]
        style_report["garments"].append(a.item.label)
        out.append(replace(a, garment=fitted.garment, placement=replace(
            a.placement, garment=str(fitted.path), garment_units=fitted.units)))
    report.data["reshape"] = {"styles": [r for _, r in done.values()]}
    report.step_done("reshape")
    control.checkpoint()
    return out


def _nest(aligned: list[OrderedGarment], config: Config, job: Job, control: JobControl, *,
          plain: bool, can_bite: bool) -> tuple[Layout, BitePlan | None]:
    """(the order's verified marker within the station's nesting time, its bites when it
    is longer than the table window)."""
    n = config["nest"]
    problem = order_problem(aligned, width=n["width_mm"], length=n["length_mm"],
                            gap=n["gap_mm"], allowance=rules_for_job(config, job.options),
                            plain=plain)
    return nest_in_window_or_bites(problem, config_window(config), n["seconds"],
                                   nest_progress(control, config), can_bite=can_bite)
