"""The print's mismatch across seams as cut on the simulated roll (station.simseams):
hand-made cases with known answers."""

from types import SimpleNamespace

import numpy as np
import pytest

from simulators.roll import Pose
from solver.wallpaper import Wallpaper
from station.simseams import (
    fit_to_trace,
    mapped,
    on_cloth,
    percentiles,
    planned_maps,
    seam_mismatch,
    traced_points,
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
    square = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [0.0, 100.0]])
    bites = [{"a": square}, {"b": square + [50.0, 0.0]}]

    def rows(points, power=1000.0, rapid=0.0):
        p = np.asarray(points, float) + [5.0, 7.0]  # work mm: the fabric at (5, 7)
        return np.column_stack([p, p, np.full(len(p), 600.0), np.full(len(p), power),
                                np.full(len(p), rapid)])

    trace = np.vstack([rows([[0, 0], [100, 0], [100, 100.3]]),  # bite 0, one 0.3 mm off
                       rows([[400, 400]], power=0.0, rapid=1.0),  # a rapid: not a cut
                       rows([[150, 0], [150, 100], [60, 100]])])  # bite 1 (60: inside 0 too)
    xy, bite, off = traced_points(trace, (5.0, 7.0), bites)
    assert bite.tolist() == [0, 0, 0, 1, 1, 1]
    assert xy[2] == pytest.approx([100.0, 100.3])
    assert off == pytest.approx([0, 0, 0.3, 0, 0, 0])


def test_a_piece_is_refitted_to_where_the_machine_really_cut_it():
    outline = np.array([[0.0, 0.0], [300.0, 0.0], [300.0, 120.0], [150.0, 200.0],
                        [0.0, 120.0]])
    truly = np.array([[np.cos(0.002), -np.sin(0.002), 0.4],
                      [np.sin(0.002), np.cos(0.002), -0.25]])  # 0.11 deg, (0.4, -0.25) mm
    ring = np.vstack([outline, outline[:1]])
    along = np.concatenate([a + np.linspace(0, 1, 20, endpoint=False)[:, None] * (b - a)
                            for a, b in zip(ring[:-1], ring[1:])])
    burnt = along @ truly[:, :2].T + truly[:, 2]
    fix = fit_to_trace(outline, burnt)
    moved = outline @ fix[:, :2].T + fix[:, 2]
    assert moved == pytest.approx(outline @ truly[:, :2].T + truly[:, 2], abs=1e-3)
