"""The job's steps (station.steps) at their seams: the one adapter from the solver's marker to
the machine's, and the daemon's path free of the simulators."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import shapely

from gcode.layout import load_layout, on_table
from gcode.machine import default_machine
from gcode.program import program_moves
from solver.nest.layout import Layout, Placed
from station.config import load_config
from station.steps.capture import real_camera
from station.steps.program import machine_layout, program_of


def _marker() -> Layout:
    """Two nested pieces as the solver hands them: one with a hole, notches (a direction
    not of unit length), marks, a grain line, a repeated closing point and coordinates
    finer than LAYOUT.json keeps."""
    square = np.array([[10.0, 10.0], [110.0, 10.0], [110.0, 90.0], [10.0, 90.0], [10.0, 10.0]])
    square[1] += 1e-11
    hole = np.array([[40.0, 40.0], [60.0, 40.0], [60.0, 60.0], [40.0, 60.0]])
    first = Placed("a", "front", np.array([[1.0, 0.0, 10.0], [0.0, 1.0, 10.0]]), False, square,
                   holes=[hole],
                   notches=[(np.array([110.0, 50.0]), np.array([2.0, 0.0]), 4.0),
                            (np.array([60.0, 10.0]), np.array([0.0, -1.0]), None)],
                   marks=np.array([[30.0, 30.0]]),
                   grainline=np.array([[20.0, 50.0], [100.0, 50.0]]))
    tri = np.array([[150.0, 20.0], [260.0, 20.0], [205.0, 95.0]])
    second = Placed("b", "back", np.array([[0.0, -1.0, 150.0], [1.0, 0.0, 20.0]]), True, tri)
    return Layout(width=1000.0, length=300.0, gap=2.0, pieces=[first, second])


def test_the_marker_in_memory_cuts_what_its_layout_file_cuts(tmp_path):
    """A job planned in this process cuts from the object; one resumed in another process
    from LAYOUT.json, read as untrusted input: both must be the same program, or a resumed
    piece would be cut along another line."""
    layout, origin, machine = _marker(), (5.0, 7.0), default_machine()
    in_memory = machine_layout(layout, origin, str(tmp_path / "layout.json"))
    layout.save(tmp_path / "layout.json")
    from_file = on_table(load_layout(tmp_path / "layout.json"), origin)
    for a, b in zip(in_memory.pieces, from_file.pieces, strict=True):
        assert (a.id, a.name) == (b.id, b.name)
        np.testing.assert_array_equal(a.outline, b.outline)
        assert [n.depth for n in a.notches] == [n.depth for n in b.notches]
        for n, m in zip(a.notches, b.notches, strict=True):
            np.testing.assert_array_equal(n.direction, m.direction)
            assert np.hypot(*n.direction) == pytest.approx(1.0)
    assert len(in_memory.pieces[0].outline) == 4  # the closing point is not a corner
    memory_program, _ = program_of(in_memory, machine, title="t")
    file_program, _ = program_of(from_file, machine, title="t")
    assert memory_program.text() == file_program.text()
    assert memory_program.summary()["pieces"] == 2
    only_b, toolpaths = program_of(in_memory, machine, {"b"}, title="t")
    assert [tp.id for tp in toolpaths] == ["b"] and only_b.summary()["pieces"] == 1


def test_a_fabric_laid_off_the_table_corner_is_cut_where_it_lies():
    """machine = fabric + origin: every cutting move of the daemon's program lies on a
    piece moved by ``[machine] fabric_origin``, not where the piece would lie with the
    fabric at the table's corner (where the fabric box would also clip the cut)."""
    layout, origin, machine = _marker(), np.array([40.0, 25.0]), default_machine()
    program, _ = program_of(machine_layout(layout, tuple(origin), "marker"), machine, title="t")
    burnt = np.concatenate([pts for _, on, _, pts in program_moves(program) if on])
    laid = shapely.union_all([shapely.Polygon(p.outline + origin) for p in layout.pieces])
    unlaid = shapely.union_all([shapely.Polygon(p.outline) for p in layout.pieces])
    assert shapely.distance(laid, shapely.points(burnt)).max() < 0.5  # kerf, sharp corners
    assert shapely.distance(unlaid, shapely.points(burnt)).max() > 20.0


def test_the_daemon_path_imports_no_simulator():
    """A real station's daemon, pipeline and steps never load `simulators`: only the
    simulation entry points (station.simstation) do."""
    code = ("import sys, station.daemon, station.pipeline, station.steps.cut; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] == 'simulators'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"


def test_a_real_station_refuses_the_simulated_camera_in_one_line():
    config = load_config(None, {"camera": {"source": "simulated"}})
    with pytest.raises(ValueError, match=r"dry run: start the station with `station serve "
                                         r"--simulate`"):
        real_camera(config)
