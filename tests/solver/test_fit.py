"""E_fit (paper Eq. 1) on hand-checkable garments and its invariances."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from solver.fit import e_fit, fit_report
from solver.placement import Placement
from solver.wallpaper import Wallpaper


def two_squares(gap: float = 10.0) -> SimpleNamespace:
    """Squares A = [0,10]² and B = [10+gap, 20+gap]x[0,10]; A's right edge, split in two
    edges of 5 mm, is sewn to B's left edge."""
    uv = np.array([[0, 0], [10, 0], [10, 5], [10, 10], [0, 10],
                   [10 + gap, 0], [20 + gap, 0], [20 + gap, 10], [10 + gap, 10],
                   [10 + gap, 5]], float)
    seam_edges = np.array([[1, 2, 5, 9], [2, 3, 9, 8]])
    return SimpleNamespace(
        uv=uv, seam_edges=seam_edges, n_pieces=2,
        piece_of_vertex=np.array([0] * 5 + [1] * 5),
        seam_weights=lambda: np.ones(2),
    )


def test_lattice_period_offset_fits_perfectly():
    g = two_squares(gap=10.0)
    fabric = Wallpaper("p1", (10, 0), (0, 10))
    assert e_fit(g, Placement.identity(2, fabric)) == pytest.approx(0.0, abs=1e-12)


def test_known_mismatch_sums_length_times_distance():
    g = two_squares(gap=10.0)
    fabric = Wallpaper("p1", (7, 0), (0, 7))  # the 10 mm shift is 3 mm off the lattice
    rep = fit_report(g, Placement.identity(2, fabric))
    np.testing.assert_allclose(rep.distance, [3.0, 3.0])
    np.testing.assert_allclose(rep.length, [5.0, 5.0])
    assert rep.e_fit_mm2 == pytest.approx(30.0)
    assert rep.e_fit_cm2 == pytest.approx(0.30)
    # Translating piece B by the residual removes the mismatch: p_wp = p2D - t.
    placed = Placement([0.0, 0.0], [[0, 0], [3, 0]], fabric)
    assert e_fit(g, placed) == pytest.approx(0.0, abs=1e-9)


def test_seam_weights_scale_each_edge():
    g = two_squares(gap=10.0)
    fabric = Wallpaper("p1", (7, 0), (0, 7))
    rep = fit_report(g, Placement.identity(2, fabric), weights=np.array([0.0, 2.0]))
    assert rep.e_fit_mm2 == pytest.approx(2.0 * 5.0 * 3.0)


def test_mirror_symmetric_seam_fits_a_pm_print_but_not_p1():
    # pm with w1 = 6 has mirror lines x = 0, 3, 6, 9, ... Shifting B by 2 mm puts its seam
    # points at wallpaper x = 8, the mirror image of A's x = 10 about the line x = 9.
    g = two_squares(gap=0.0)
    shifted = Placement([0.0, 0.0], [[0, 0], [2, 0]], Wallpaper("pm", (6, 0), (0, 9)))
    assert e_fit(g, shifted) == pytest.approx(0.0, abs=1e-9)
    plain = Placement([0.0, 0.0], [[0, 0], [2, 0]], Wallpaper("p1", (6, 0), (0, 9)))
    np.testing.assert_allclose(fit_report(g, plain).distance, [2.0, 2.0])


def test_moving_pattern_and_print_together_changes_nothing():
    g = two_squares(gap=4.0)
    rng = np.random.default_rng(0)
    fabric = Wallpaper("p4g", (13, 0), (0, 13), (2, 1))
    placement = Placement(rng.uniform(0, 6, 2), rng.uniform(-20, 20, (2, 2)), fabric)
    before = e_fit(g, placement)
    # A rigid motion of the whole pattern, carried into every piece's placement.
    a, t = 0.9, np.array([40.0, -7.0])
    r = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    g.uv = g.uv @ r.T + t
    moved = Placement(placement.angles + a, placement.translations @ r.T + t, fabric)
    assert e_fit(g, moved) == pytest.approx(before, rel=1e-9)


def test_placement_json_round_trip(tmp_path):
    fabric = Wallpaper("p6m", (30, 0), (-15, 15 * math.sqrt(3)))
    placement = Placement([0.1, -2.0], [[1, 2], [3, 4]], fabric, piece_names=["a", "b"],
                          report={"e_fit_aligned_mm2": 1.5}, garment="shirt.obj",
                          garment_units="m")
    path = tmp_path / "placement.json"
    placement.save(path)
    again = Placement.load(path)
    np.testing.assert_allclose(again.angles, placement.angles)
    np.testing.assert_allclose(again.translations, placement.translations)
    assert again.piece_names == ["a", "b"]
    assert (again.garment, again.garment_units) == ("shirt.obj", "m")
    assert again.fabric.group == "p6m"
    path.write_text('{"pieces": [{"index": 0}]}')
    with pytest.raises(ValueError, match="placement.json"):
        Placement.load(path)
