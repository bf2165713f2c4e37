"""Bite by bite on the simulated roll (issue 35): each advance is measured from the print
and the rest of the marker is carried onto the cloth as it really lies."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from simulators.classics import classic_print
from simulators.fabric import random_print
from simulators.roll import Conveyor, RollCamera, RollPrint
from solver.nest import NestProblem, Piece
from solver.nest.layout import build_layout
from station.steps.bites import (
    CUT_IN_VIEW_MM,
    OPERATOR_ADVANCE,
    ROLL_MARGIN_MM,
    BiteStep,
    RollTrack,
    bites_report,
    find_bite,
    plan_job_bites,
)
from station.steps.table import TableWindow
from vision.advance import MIN_OVERLAP_MM

WINDOW = TableWindow(0.0, 0.0, 800.0, 500.0)


def _marker(lead: float = 0.0):
    """Thirty 140 x 200 mm pieces in two rows: a marker 2.25 m long, three windows;
    ``lead`` mm of cloth before the first (a marker placed on a print's phase)."""
    pieces = [Piece(f"r{i}", [[0, 0], [140, 0], [140, 200], [0, 200]]) for i in range(30)]
    problem = NestProblem(pieces, width=WINDOW.width, gap=5.0)
    moves = [np.array([[1.0, 0.0, lead + 5.0 + 150.0 * (i // 2)],
                       [0.0, 1.0, 5.0 + 210.0 * (i % 2)]]) for i in range(30)]
    return build_layout(problem, problem.items(), moves)


def _truth_window_points(conv: Conveyor, cloth: np.ndarray) -> np.ndarray:
    """Where the cloth points ``cloth`` lie on the table now (the simulator's truth)."""
    pose = conv.pose
    a = math.radians(-pose.angle_deg)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    pivot = np.asarray(pose.pivot)
    return (cloth - pivot - [pose.along, pose.across]) @ rot.T + pivot


def test_the_marker_follows_the_cloth_through_every_advance():
    design = random_print("p2", 50.0, seed=4)
    lattice = np.column_stack([design.wallpaper.w1, design.wallpaper.w2])
    conv = Conveyor(pivot=(399.5, 249.5), seed=8)  # slips up to 3 mm, turns up to 0.2 deg
    camera = RollCamera(RollPrint(design, width=WINDOW.width), conv,
                        (WINDOW.x0, WINDOW.y0, WINDOW.x1, WINDOW.y1))
    plan = plan_job_bites(_marker(), WINDOW, lattice)
    assert len(plan.bites) == 3
    step, done = None, []
    for bite in plan.bites:
        step = find_bite(step, bite, advance=conv.advance, photograph=camera.photograph,
                         lattice=lattice)
        bite = step.bite
        done.append(bite)
        layout = step.track.bite_layout(plan, bite)
        assert sorted(p.id for p in layout.pieces) == sorted(bite.pieces)
        for placed, planned in zip(layout.pieces, (p for p in plan.layout.pieces
                                                   if p.id in bite.pieces)):
            # the cloth under the planned outline at the first bite (the roll's pose then
            # was the identity, and the marker lay where it was planned on the print)
            cloth = planned.outline
            err = np.hypot(*(placed.outline - _truth_window_points(conv, cloth)).T)
            assert err.max() < 0.3
            xs = placed.outline[:, 0]
            assert xs.min() > WINDOW.x0 and xs.max() < WINDOW.x1  # the slips stay inside
    report = bites_report(done)
    assert [b["pieces"] for b in report] == [list(b.pieces) for b in plan.bites]
    assert report[0]["advance_measured_mm"] is None
    for row in report[1:]:
        assert abs(row["advance_measured_mm"] - row["advance_commanded_mm"]) <= 3.3
        assert abs(row["skew_deg"]) <= 0.25
    assert sum(len(b["pieces"]) for b in report) == 30


def test_an_operator_is_asked_for_the_advance_in_mm():
    track = RollTrack()
    plan = plan_job_bites(_marker(), WINDOW, None)
    asked = OPERATOR_ADVANCE.format(mm=track.advance_for(plan.bites[1]))
    # the next bite begins ROLL_MARGIN_MM into the window, room for a slip backwards
    assert asked == f"advance the fabric {plan.bites[1].start_mm - ROLL_MARGIN_MM:.1f} mm"


def test_the_bites_keep_cloth_in_view_across_each_advance():
    plan = plan_job_bites(_marker(), WINDOW, None)
    usable = WINDOW.length - 2 * ROLL_MARGIN_MM
    assert plan.window_mm == pytest.approx(usable)
    assert max(b.advance_commanded_mm for b in plan.bites) <= usable - 40.0 + 1e-9


def test_a_marker_that_begins_into_the_window_keeps_its_first_bite_and_advance_in_view():
    """The first bite is cut where it was planned: 45 mm into the window, it still ends
    ROLL_MARGIN_MM before the window does, and the first advance leaves cloth in view."""
    plan = plan_job_bites(_marker(lead=45.0), WINDOW, None)
    first = [p for p in plan.layout.pieces if p.id in plan.bites[0].pieces]
    assert max(p.outline[:, 0].max() for p in first) <= WINDOW.length - ROLL_MARGIN_MM
    advance = RollTrack().advance_for(plan.bites[1])
    assert WINDOW.length - advance >= MIN_OVERLAP_MM


def _stripes_along_the_roll():
    """Stripes running along the roll: the print cannot give the advance."""
    conv = Conveyor(pivot=(399.5, 249.5), seed=8)
    camera = RollCamera(RollPrint(classic_print("stripes", 20.0, rotation=90.0),
                                  width=WINDOW.width), conv,
                        (WINDOW.x0, WINDOW.y0, WINDOW.x1, WINDOW.y1))
    return camera, conv


def _cut(camera: RollCamera, step, plan) -> BiteStep:
    """Burn the cut lines of ``step``'s bite where the track puts them, and photograph
    the window again, as the station does after each bite."""
    rings = [p.outline for p in step.track.bite_layout(plan, step.bite).pieces]
    camera.burn(np.concatenate([np.column_stack([r, np.roll(r, -1, axis=0)]) for r in rings]))
    return replace(step, cut_photograph=camera.photograph())


@pytest.mark.parametrize("keep_cut_in_view", [True, False])
def test_on_stripes_along_the_roll_the_advance_is_measured_from_the_last_cut_or_not_at_all(
        keep_cut_in_view):
    camera, conv = _stripes_along_the_roll()
    plan = plan_job_bites(_marker(), WINDOW, None)
    first = _cut(camera, find_bite(None, plan.bites[0], advance=conv.advance,
                                   photograph=camera.photograph, lattice=None), plan)
    step = find_bite(first, plan.bites[1], lattice=None, photograph=camera.photograph,
                     advance=lambda mm: conv.advance(mm, slip=3.0, skew=0.2),
                     plan=plan if keep_cut_in_view else None)
    along = conv.poses[-1].along - conv.poses[-2].along
    row = bites_report([first.bite, step.bite], {1: step.how()})[1]
    assert row["advance_commanded_mm"] == pytest.approx(along - 3.0, abs=1e-3)
    if keep_cut_in_view:  # the first bite's cut ends CUT_IN_VIEW_MM into the window
        assert step.bite.advance_commanded_mm == pytest.approx(
            plan.bites[0].end_mm - CUT_IN_VIEW_MM)
        assert row["advance_source"] == "cut edges" and row["advance_unmeasured"] == []
        assert abs(row["advance_measured_mm"] - along) < 0.3
    else:  # the advance the plan asks for leaves the cut at the strip's edge, then off it
        assert row["advance_source"] == "commanded" and row["advance_unmeasured"] == ["along"]
        assert row["advance_measured_mm"] is None  # not a false "measured" value
    assert abs(row["skew_deg"] - 0.2) < 0.05  # the stripes give the skew either way
