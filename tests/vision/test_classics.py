"""The simulators' textile classics: stripes, checks, tweeds and dots."""

from __future__ import annotations

import pytest

from simulators.classics import CLASSIC_GROUPS, classic_print
from simulators.fabric import render_print
from vision.pipeline import detect_fabric


@pytest.mark.parametrize("name", [n for n in CLASSIC_GROUPS if n != "stripes"])
def test_classic_prints_get_their_group(name):
    p = classic_print(name, 40.0, rotation=17.0)
    det = detect_fabric(render_print(p, (240, 200), 0.6), mm_per_px=0.6)
    assert det.wallpaper is not None and det.wallpaper.group == p.truth.group


def test_classic_stripes_are_a_frieze_with_period_and_direction():
    p = classic_print("stripes", 40.0, rotation=17.0)
    det = detect_fabric(render_print(p, (240, 200), 0.6), mm_per_px=0.6)
    assert det.wallpaper is None and det.lattice.kind == "stripes"
    assert det.lattice.period == pytest.approx(40.0, rel=0.01)
    assert det.lattice.direction_deg == pytest.approx(107.0, abs=1.0)
    assert det.fabric_json()["group"] is None
