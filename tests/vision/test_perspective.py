"""Perspective left in a photo: found from the local lattices, undone, and the group read
on the rectified image (vision/perspective.py, vision/pipeline.py)."""

from __future__ import annotations

import numpy as np
import pytest

from bench.vision import lattice_match, tilted_frame
from solver.wallpaper import GROUP_NAMES
from vision.perspective import _jacobians, fit_view
from vision.pipeline import detect_fabric
from vision.subgroups import error_kind


def test_fit_recovers_a_known_vanishing_line_and_ignores_a_flat_view():
    rng = np.random.default_rng(3)
    shape = (480, 640)
    centre = np.array([(shape[1] - 1) / 2, (shape[0] - 1) / 2])
    pts = centre + rng.uniform(-200, 200, (9, 2))
    b0 = np.array([[30.0, 4.0], [-3.0, 26.0]])
    c = np.array([3e-4, -2e-4])
    # The local lattice the view shows at x: g carries it back onto b0.
    local = np.linalg.inv(_jacobians(c, pts - centre)) @ b0
    local *= 1 + rng.normal(0, 0.002, local.shape)  # the scatter of real local fits
    view = fit_view(pts, local, shape, 1.0)
    assert view is not None and view.explained > 0.95
    assert np.allclose(view.c, c, atol=2e-5)
    flat = np.repeat(b0[None], 9, axis=0) * (1 + rng.normal(0, 0.01, (9, 2, 2)))
    assert fit_view(pts, flat, shape, 1.0) is None  # noise alone is no perspective


@pytest.mark.parametrize("tilt", [6.0, 12.0])
def test_every_group_is_read_through_a_tilted_camera(tilt):
    """Frames straight from a tilted camera, never rectified: the repeat changes by up
    to about 20 % across the frame. Every group comes out right on at least 16 of 17,
    never as a supergroup, the perspective is reported and the lattice at the frame's
    centre is found within 5 %."""
    outcomes = []
    for i, group in enumerate(GROUP_NAMES):
        frame, mm_per_px, truth = tilted_frame(group, tilt, seed=100 * int(tilt) + i)
        det = detect_fabric(frame, mm_per_px=mm_per_px)
        outcomes.append((group, det.classification.group,
                         error_kind(det.classification.group, group)))
        if det.classification.group is not None:
            assert det.distortion.perspective is not None, group
            assert det.distortion.perspective["lattice_change"] > 0.04
            assert "perspective" in det.distortion.warning
            same, err = lattice_match(det.lattice.basis, truth)
            assert same and err < 0.05, (group, err)
    assert not [o for o in outcomes if o[2] in ("supergroup", "other")], outcomes
    assert sum(o[2] == "right" for o in outcomes) >= 16, outcomes


def test_a_straight_view_reports_no_perspective():
    for i, group in enumerate(("p4m", "p31m", "pg")):
        frame, mm_per_px, _ = tilted_frame(group, 0.0, seed=7 + i)
        det = detect_fabric(frame, mm_per_px=mm_per_px)
        assert det.classification.group == group
        assert det.distortion.perspective is None
