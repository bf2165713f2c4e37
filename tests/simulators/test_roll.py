"""The simulated roll (issue 35): a print that drifts along the roll, a conveyor that
slips, a camera that sees only the table window."""

from __future__ import annotations

import numpy as np

from simulators.fabric import random_print
from simulators.roll import Conveyor, RollCamera, RollPrint


def test_the_conveyor_slips_and_skews_within_its_bounds():
    conv = Conveyor(pivot=(800.0, 500.0), seed=2)
    for _ in range(40):
        conv.advance(1500.0)
    along = np.diff([p.along for p in conv.poses])
    turned = np.diff([p.angle_deg for p in conv.poses])
    assert np.all(np.abs(along - 1500.0) <= 3.0) and np.ptp(along) > 3.0  # it does slip
    assert np.all(np.abs(turned) <= 0.2) and np.ptp(turned) > 0.2
    forced = conv.advance(100.0, slip=-3.0, skew=0.2)
    assert forced.along == conv.poses[-2].along + 97.0
    assert forced.angle_deg == conv.poses[-2].angle_deg + 0.2


def test_the_print_bows_skews_and_stretches_slowly_along_the_roll():
    roll = RollPrint(random_print("p1", 40.0), width=1000.0)
    u = np.linspace(0.0, 12000.0, 2401)
    edge, _ = roll.design_point(u, np.zeros_like(u))
    far_edge, _ = roll.design_point(u, np.full_like(u, 1000.0))
    middle, _ = roll.design_point(u, np.full_like(u, 500.0))
    bow = middle - (edge + far_edge) / 2  # zero at both edges by construction
    assert 3.5 < np.abs(bow).max() <= 4.0
    skew = np.degrees(np.arctan((far_edge - edge) / 1000.0))
    assert 0.45 < np.abs(skew).max() <= 0.5
    drift = middle - u  # where the print lies against its design
    assert np.ptp(drift) > 5.0  # over metres of roll the print leaves its design by mm
    assert np.abs(np.diff(drift)).max() < 0.1  # 5 mm steps: slowly


def test_the_camera_sees_the_window_and_the_cloth_moves_under_it():
    roll = RollPrint(random_print("p2", 50.0, seed=1), width=500.0)
    conv = Conveyor(pivot=(399.5, 249.5), drift_mm=0.0, seed=1)
    camera = RollCamera(roll, conv, (0.0, 0.0, 800.0, 500.0), noise=0.01)
    before = camera.photograph().astype(float)
    assert before.shape == (500, 800, 3)
    conv.advance(300.0, slip=0.0, skew=0.0)
    after = camera.photograph().astype(float)
    same_cloth = np.abs(after[:, :500] - before[:, 300:]).mean()
    other_cloth = np.abs(after[:, :500] - before[:, :500]).mean()
    assert same_cloth < 5.0 < other_cloth
