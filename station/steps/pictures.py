"""Pictures of a plan for people, drawn from the `Plan` once planning is done: the
pattern over the print before alignment, aligned and reshaped (seams coloured by
mismatch, the cut lines and notches), the marker on the fabric photo and the toolpath."""

from __future__ import annotations

from gcode.machine import Machine
from solver.garment.notches import cut_ready
from solver.wallpaper import Wallpaper
from station.render import draw_fit, draw_marker, draw_toolpath, garment_credit, photo_colours
from station.steps.capture import Captured
from station.steps.records import Plan, Stage


def draw_plan(plan: Plan, machine: Machine) -> None:
    """Every picture of the plan, into its job's folder."""
    draw_fits(plan.stages, plan.captured, plan.wallpaper)
    credit = garment_credit(plan.report["garment"])  # the submitted file's licence
    draw_toolpath(plan.program, machine, plan.job_dir / "toolpath.png", credit=credit)
    printed = plan.wallpaper is not None
    draw_marker(plan.layout, plan.job_dir / "marker.png",
                garment=plan.garment if printed else None, report=plan.fit,
                photo=plan.captured.photo if printed else None,
                photo_mm_per_px=plan.captured.mm_per_px if printed else 1.0, credit=credit,
                title=_order_title(plan.report.get("order")))


def _order_title(order: dict | None) -> str | None:
    """``order PO-1, sizes 44:1 50:1`` for an order's marker (None for one garment)."""
    if not order:
        return None
    ratio = " ".join(f"{s}:{n}" for s, n in order["ratio"].items())
    return f"order {order['name']}, sizes {ratio}"


def draw_fits(stages: list[Stage], captured: Captured, wallpaper: Wallpaper | None) -> None:
    """One picture per state of the fit, coloured as the print was photographed."""
    if not stages or wallpaper is None:
        return
    colour_of = photo_colours(captured.photo, captured.mm_per_px, wallpaper)
    for stage in stages:
        cuts, notches = (cut_ready(stage.garment, stage.rules, stage.placement)
                         if stage.rules is not None else (None, None))
        draw_fit(stage.garment, stage.placement, stage.fit, stage.picture,
                 title=stage.title, colour_of=colour_of, cuts=cuts, notches=notches,
                 original=stage.original)

