"""The print's mismatch across seams as cut on the simulated roll (station.simseams):
hand-made cases with known answers."""

from types import SimpleNamespace

import numpy as np
import pytest
import shapely

from simulators.roll import Pose
from solver.wallpaper import Wallpaper
from station.simseams import (
    mapped,
    on_cloth,
    percentiles,
    planned_maps,
    seam_mismatch,
    trace_check,
)

SQUARE = Wallpaper("p1", (50.0, 0.0), (0.0, 50.0))
SHIFT = lambda dx, dy: np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]])  # noqa: E731


def test_a_piece_cut_off_its_print_shows_its_shift_at_the_seams():
    pts = np.array([[10.0, 10.0], [30.0, 12.0], [45.0, 40.0]])
    a, b = np.array(["a"] * 3, object), np.array(["b"] * 3, object)
    planned = {"a": SHIFT(0, 0), "b": SHIFT(100.0, 50.0)}  # b a whole repeat away: matched
    cut = {"a": SHIFT(0, 0), "b": SHIFT(101.5, 48.0)}  # b cut 1.5 mm on, 2 mm across
    assert np.allclose(seam_mismatch(SQUARE, mapped(pts, a, planned),
                                     mapped(pts, b, planned)), 0.0)
    cut_mismatch = seam_mismatch(SQUARE, mapped(pts, a, cut), mapped(pts, b, cut))
    assert np.allclose(cut_mismatch, 2.5)
    assert percentiles(cut_mismatch) == {"p50": 2.5, "p90": 2.5, "max": 2.5, "seams": 3}


def test_the_mismatch_is_the_prints_own_symmetry():
    # on a mirror print (pm, mirror x = 0) a left piece cut mirrored matches its right one;
    # on the plain lattice (p1) the same cut is off by twice its distance to the mirror
    mirror = Wallpaper("pm", (50.0, 0.0), (0.0, 50.0))
    a, b = np.array([[12.0, 7.0]]), np.array([[-12.0, 7.0]])
    assert seam_mismatch(mirror, a, b) == pytest.approx([0.0], abs=1e-9)
    assert seam_mismatch(SQUARE, a, b) == pytest.approx([24.0])


def test_cloth_points_follow_each_bites_pose():
    poses = [Pose(0.0, 0.0, 0.0, (500.0, 300.0)), Pose(1203.0, -0.4, 0.2, (500.0, 300.0))]
    window = np.array([[500.0, 300.0], [500.0, 300.0], [900.0, 300.0]])
    cloth = on_cloth(window, poses, [0, 1, 1])
    assert np.allclose(cloth[0], [500.0, 300.0])
    assert np.allclose(cloth[1], [1703.0, 299.6])
    assert cloth[2] == pytest.approx([500 + 400 * np.cos(np.radians(0.2)) + 1203.0,
                                      300 + 400 * np.sin(np.radians(0.2)) - 0.4])


def test_uncompensated_bites_are_moved_by_the_commanded_advances_only():
    layout = SimpleNamespace(pieces=[SimpleNamespace(id="x", transform=SHIFT(2000.0, 10.0))])
    bites = [{"pieces": [], "advance_commanded_mm": 0.0},
             {"pieces": [], "advance_commanded_mm": 1370.0},
             {"pieces": ["x"], "advance_commanded_mm": 600.5}]
    assert np.allclose(planned_maps(layout, bites)["x"], SHIFT(29.5, 10.0))


def test_the_trace_is_held_against_the_pieces_of_the_bite_being_cut():
    shapes = [shapely.MultiPolygon([shapely.box(x0, 0, x0 + 100, 100)]) for x0 in (0, 50)]

    def rows(points, power=1000.0, rapid=0.0):
        p = np.asarray(points, float) + [5.0, 7.0]  # work mm: the fabric at (5, 7)
        return np.column_stack([p, p, np.full(len(p), 600.0), np.full(len(p), power),
                                np.full(len(p), rapid)])

    trace = np.vstack([rows([[0, 0], [100, 0], [100, 100.3]]),  # bite 0, one 0.3 mm off
                       rows([[400, 400]], power=0.0, rapid=1.0),  # a rapid: not a cut
                       rows([[150, 0], [150, 100], [60, 100]])])  # bite 1 (60: inside 0 too)
    got = trace_check(trace, (5.0, 7.0), shapes)
    assert got == {"segments_burning": 6, "per_bite": [3, 3], "off_max_mm": 0.3}
