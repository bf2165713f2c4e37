"""Skew and bow of badly spread cloth, from the local lattice grid."""

from __future__ import annotations

import pytest

from simulators.camera import Sheet, render_rectified
from simulators.fabric import random_print
from vision.pipeline import detect_fabric

REGION = (20.0, 20.0, 580.0, 380.0)


def _detect(**faults):
    sheet = Sheet(random_print("pmm", 30.0, seed=5), size=(600.0, 400.0), **faults)
    img = render_rectified(sheet, REGION, 1.0)
    return detect_fabric(img, mm_per_px=1.0, offset=REGION[:2])


def test_straight_cloth_has_no_warning():
    det = _detect()
    assert det.wallpaper.group == "pmm"
    d = det.distortion
    assert abs(d.skew_deg) < 0.2 and abs(d.bow_mm) < 1.0 and d.warning is None
    assert len(d.centres) >= 4 and d.max_strain < 0.01


@pytest.mark.parametrize("skew", [-2.0, 3.0])
def test_skewed_check_is_measured_and_warned(skew):
    d = _detect(skew=skew).distortion
    assert abs(d.skew_deg) == pytest.approx(abs(skew), abs=0.3)
    assert "skew" in d.warning


def test_bowed_check_is_measured_and_warned():
    d = _detect(bow=12.0).distortion
    assert abs(d.bow_mm) == pytest.approx(12.0, rel=0.25)
    assert "bow" in d.warning and "skew" not in d.warning


def test_tolerances_are_the_operators():
    sheet = Sheet(random_print("pmm", 30.0, seed=5), size=(600.0, 400.0), skew=2.0)
    img = render_rectified(sheet, REGION, 1.0)
    assert detect_fabric(img, mm_per_px=1.0, skew_tol_deg=3.0).distortion.warning is None
