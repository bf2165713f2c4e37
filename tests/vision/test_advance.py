"""Finding the print again after an advance (issue 35): the roll's real advance and skew,
measured from two photographs of the table window on the simulated roll."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simulators.classics import classic_print
from simulators.fabric import random_print
from simulators.roll import Conveyor, RollCamera, RollPrint, kerf_cover
from vision.advance import measure_advance

WINDOW = (0.0, 0.0, 800.0, 500.0)  # a small table, 1 mm per pixel: the test stays fast


def _table(seed: int = 3, **conveyor):
    design = random_print("p2", 50.0, seed=seed)  # w1 = (50, 0): one repeat along the roll
    roll = RollPrint(design, width=WINDOW[3])
    pivot = ((WINDOW[2] - 1) / 2, (WINDOW[3] - 1) / 2)  # the photographs' centre
    conv = Conveyor(pivot=pivot, seed=seed, **conveyor)
    lattice = np.column_stack([design.wallpaper.w1, design.wallpaper.w2])
    return RollCamera(roll, conv, WINDOW, seed=seed), conv, lattice


def _truth(conv: Conveyor) -> tuple[float, float, float]:
    """The last advance in the frame of the pose before it: (along, across, skew_deg)."""
    p0, p1 = conv.poses[-2], conv.poses[-1]
    a = math.radians(p0.angle_deg)
    d = np.array([p1.along - p0.along, p1.across - p0.across])
    along, across = np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]]) @ d
    return float(along), float(across), p1.angle_deg - p0.angle_deg


@pytest.mark.parametrize(("slip", "skew"), [(3.0, 0.2), (-3.0, -0.2)])
def test_a_slipped_and_skewed_advance_is_measured(slip, skew):
    camera, conv, lattice = _table()
    conv.advance(180.0, slip=0.4, skew=0.1)  # the roll already lies a little askew
    before = camera.photograph()
    conv.advance(500.0, slip=slip, skew=skew)
    adv = measure_advance(before, camera.photograph(), commanded_mm=500.0, lattice=lattice)
    along, across, turned = _truth(conv)
    assert abs(adv.advance_mm - along) < 0.3 and abs(adv.slip_mm - slip) < 0.3
    assert abs(adv.skew_deg - turned) < 0.05
    assert abs(adv.across_mm - across) < 0.3
    assert adv.residual < 0.03 and adv.tiles >= 6


def test_a_print_ambiguous_by_one_repeat_is_resolved_by_the_commanded_advance():
    camera, conv, lattice = _table(seed=5, drift_mm=0.0)
    before = camera.photograph()
    conv.advance(450.0, slip=2.5, skew=0.0)
    after = camera.photograph()
    # the print alone cannot tell 452.5 from 402.5 or 502.5 mm (it repeats every 50 mm
    # along the roll): both commanded lengths find a perfect match, one repeat apart
    right = measure_advance(before, after, commanded_mm=450.0, lattice=lattice)
    wrong = measure_advance(before, after, commanded_mm=500.0, lattice=lattice)
    assert right.advance_mm == pytest.approx(452.5, abs=0.3)
    assert wrong.advance_mm == pytest.approx(502.5, abs=0.3)
    assert wrong.residual < 2 * right.residual + 0.01  # the photographs alone: a tie


def test_a_larger_skew_across_the_window_is_still_one_motion():
    camera, conv, lattice = _table(seed=6)
    before = camera.photograph()
    conv.advance(400.0, slip=-1.0, skew=1.5)  # as 0.65 deg on a 1 m table: tiles spread 10 px
    adv = measure_advance(before, camera.photograph(), commanded_mm=400.0, lattice=lattice)
    along, _, turned = _truth(conv)
    assert abs(adv.advance_mm - along) < 0.3 and abs(adv.skew_deg - turned) < 0.05
    assert adv.tiles == 30  # every tile of the 400 x 500 mm strip (5 x 6), not the middle 12


def test_an_advance_that_leaves_nothing_in_view_is_refused():
    camera, _, lattice = _table()
    frame = camera.photograph()
    with pytest.raises(ValueError, match=r"an advance of 780 mm leaves 20 mm of cloth in "
                       r"both photographs of the 800 mm window; at least 40 mm"):
        measure_advance(frame, frame, commanded_mm=780.0, lattice=lattice)


def _striped_table(repeat: float, rotation: float):
    """Stripes of ``repeat`` mm on the roll: along it (rotation 90) or across it (0)."""
    design = classic_print("stripes", repeat, rotation=rotation)
    pivot = ((WINDOW[2] - 1) / 2, (WINDOW[3] - 1) / 2)
    conv = Conveyor(pivot=pivot, seed=3)
    return RollCamera(RollPrint(design, width=WINDOW[3]), conv, WINDOW, seed=3), conv


def _oval_kerfs(cx: float, cy: float, rx: float = 60.0, ry: float = 80.0) -> np.ndarray:
    """(n, 4) segments of an oval piece's cut line, table mm."""
    t = np.linspace(0.0, 2 * np.pi, 90, endpoint=False)
    ring = np.column_stack([cx + rx * np.cos(t), cy + ry * np.sin(t)])
    return np.column_stack([ring, np.roll(ring, -1, axis=0)])


def test_stripes_along_the_roll_leave_the_advance_unmeasured_and_the_cut_edges_measure_it():
    camera, conv = _striped_table(20.0, rotation=90.0)
    conv.advance(180.0, slip=0.4, skew=0.1)
    before = camera.photograph()
    camera.burn(np.concatenate([_oval_kerfs(700.0, 130.0), _oval_kerfs(650.0, 360.0)]))
    cut = camera.photograph()  # the same window, the bite's pieces cut into it
    conv.advance(500.0, slip=3.0, skew=0.2)
    after = camera.photograph()
    along, across, turned = _truth(conv)
    by_print = measure_advance(before, after, commanded_mm=500.0)
    # the stripes give the drift and the skew, never the advance: not a false 503
    assert by_print.unmeasured == ("along",) and not by_print.along_measured
    assert by_print.advance_mm == 500.0
    assert abs(by_print.across_mm - across) < 0.3 and abs(by_print.skew_deg - turned) < 0.05
    by_cut = measure_advance(cut, after, commanded_mm=500.0)
    assert by_cut.unmeasured == ()
    assert abs(by_cut.advance_mm - along) < 0.3 and abs(by_cut.slip_mm - 3.0) < 0.3
    assert abs(by_cut.skew_deg - turned) < 0.05


@pytest.mark.parametrize(("repeat", "measured"), [(6.0, False), (20.0, True)])
def test_a_repeat_along_the_roll_within_the_slip_is_not_measured(repeat, measured):
    camera, conv = _striped_table(repeat, rotation=0.0)  # stripes across the roll
    before = camera.photograph()
    conv.advance(500.0, slip=3.0, skew=0.2)
    adv = measure_advance(before, camera.photograph(), commanded_mm=500.0)
    along, _, turned = _truth(conv)
    # a 6 mm repeat matches again within twice the slip (8 mm) of the true advance
    assert adv.along_measured is measured and "across" in adv.unmeasured
    assert abs(adv.advance_mm - (along if measured else 500.0)) < 0.3
    assert abs(adv.skew_deg - turned) < 0.05


def test_a_plain_cloth_measures_nothing_and_its_cut_edges_the_advance():
    rng = np.random.default_rng(0)
    h, w = int(WINDOW[3]), int(WINDOW[2])

    def plain(kerfs: np.ndarray | None = None) -> np.ndarray:
        grey = np.full((h, w), 0.6, np.float32) + rng.normal(0.0, 0.02, (h, w)).astype(
            np.float32)
        if kerfs is not None:  # the kerfs, charred, over the cloth
            cover = kerf_cover(kerfs, (h, w), 0.5)
            grey = grey * (1.0 - cover) + 0.1 * cover
        return (np.clip(grey, 0.0, 1.0) * 255).astype(np.uint8)

    nothing = measure_advance(plain(), plain(), commanded_mm=500.0)
    assert nothing.unmeasured == ("along", "across", "skew")
    assert (nothing.advance_mm, nothing.across_mm, nothing.skew_deg) == (500.0, 0.0, 0.0)
    cut = _oval_kerfs(700.0, 250.0)
    moved = cut - np.array([503.0, -0.4, 503.0, -0.4])  # advanced 503 mm, drifted 0.4
    by_cut = measure_advance(plain(cut), plain(moved), commanded_mm=500.0)
    assert by_cut.along_measured and abs(by_cut.advance_mm - 503.0) < 0.3
    assert "across" not in by_cut.unmeasured and abs(by_cut.across_mm + 0.4) < 0.3
