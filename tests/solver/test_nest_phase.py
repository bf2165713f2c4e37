"""A printed marker free to start at any phase of the print (issue 35, item 7).

The station's nest of the bundled Berkeley shorts' cut lines under a 50 mm p1 print
chooses where along the print the marker starts: its pieces stay on their aligned print
positions, the layout records the start (``phase_mm``), and the dotted-board model
proves that no marker starting at the print's phase at the roll's start is as short.
The program cuts the pieces there.
"""

from __future__ import annotations

import pytest
import shapely

from gcode.machine import default_machine
from gcode.program import program_moves
from solver.garment import load_garment
from solver.nest import NestProblem, verify_layout
from solver.nest.dotted import dotted_nest
from solver.nest.layout import Layout
from solver.nest.sources import garment_pieces
from solver.wallpaper import Wallpaper
from station.steps.nest import nest_in_window_or_bites
from station.steps.program import machine_layout, program_of
from station.steps.table import TableWindow
from tests.conftest import DATA

WINDOW = TableWindow(0.0, 0.0, 1600.0, 900.0)  # the default table's, 900 mm of roll across


@pytest.fixture(scope="module")
def shorts_marker() -> tuple[NestProblem, Layout]:
    g = load_garment(DATA / "garments" / "berkeley" / "shorts-iso.obj", units="m")
    problem = NestProblem(garment_pieces(g), WINDOW.width, length=WINDOW.length, gap=2.0,
                          fabric=Wallpaper("p1", (50.0, 0.0), (0.0, 50.0), origin=(7.0, 3.0)))
    layout, bites = nest_in_window_or_bites(problem, WINDOW, 6.0)
    assert bites is None  # it fits the window
    return problem, layout


def test_the_station_nest_chooses_the_phase_and_is_denser_than_any_at_the_found_one(
        shorts_marker):
    problem, layout = shorts_marker
    assert verify_layout(layout, problem) == []  # every piece on its aligned print position
    assert 0.0 < layout.phase_mm < 50.0 + problem.gap  # it starts within a repeat
    assert layout.marker_length == pytest.approx(layout.length - layout.phase_mm)
    first = min(p.outline[:, 0].min() for p in layout.pieces)
    assert first == pytest.approx(layout.phase_mm + problem.gap, abs=1e-6)
    assert Layout.from_dict(layout.to_dict()).phase_mm == pytest.approx(layout.phase_mm)
    # the gain, measured: at the print's phase at the roll's start, no marker is as short
    # (so none is as dense) as this one from where it starts
    found = dotted_nest(problem, problem.items(), time_limit=20.0, limit=layout.marker_length)
    assert found is not None and found.moves is None and found.optimal


def test_the_program_cuts_the_pieces_where_the_chosen_phase_put_them(shorts_marker):
    problem, layout = shorts_marker
    machine = default_machine()  # the fabric at the table's corner: machine mm = fabric mm
    program, _ = program_of(machine_layout(layout, (0.0, 0.0), "marker"), machine,
                            title="phase")
    ids = {r.number: r.id for r in program.pieces}
    pieces = {p.id: p.polygon() for p in layout.pieces}
    cut = {i: 0 for i in pieces}
    for _, cutting, number, points in program_moves(program):
        if not cutting or number == 0:
            continue
        on_fabric = shapely.points(points)
        # the cut line offset by half the kerf (more at sharp corners, notches inside):
        # the piece as placed on the print, not a repeat or a phase away
        assert shapely.distance(pieces[ids[number]], on_fabric).max() <= (
            machine.cut.kerf + machine.cut.tolerance)
        cut[ids[number]] += len(points)
    assert all(cut.values())  # every piece is cut
    first_cut = min(p[:, 0].min() for _, on, n, p in program_moves(program) if on and n)
    assert first_cut >= layout.phase_mm + problem.gap - machine.cut.kerf
