"""A print that repeats over part of the frame only: cloth over a bulge (a shoulder, a
chest), which no one view explains. The whole frame shows no lattice; the print is read
on the frame's centre and the operator confirms it (vision/pipeline.py)."""

from __future__ import annotations

import cv2
import numpy as np

from bench.vision import lattice_match
from solver.wallpaper import GROUP_NAMES
from vision.lattice import detect_lattice
from vision.pipeline import CONFIRM_BELOW, PART_OF_FRAME_CONFIDENCE, detect_fabric
from vision.subgroups import error_kind


def _on_a_bulge(img: np.ndarray, bulge: float) -> np.ndarray:
    """``img`` as seen on a bulge: true at the frame's centre, shrinking towards the
    edges as 1 / (1 + bulge r^2) (r = 1 at the frame's half width)."""
    h, w = img.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    u, v = (xx - w / 2) / (w / 2), (yy - h / 2) / (h / 2)
    f = 1 + bulge * (u * u + v * v)
    return cv2.remap(img, w / 2 + u * f * w / 2, h / 2 + v * f * h / 2, cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REFLECT)


def test_a_print_on_a_bulge_is_read_at_the_centre_and_goes_to_the_operator(vt):
    outcomes = []
    for i, group in enumerate(GROUP_NAMES):
        flat, truth = vt.synth(group, seed=40 + i, shape=(600, 600), period=26.0,
                               rotation=10.0)
        frame = _on_a_bulge(flat, 1.0)
        assert not detect_lattice(frame).found, group  # no lattice holds over the frame
        det = detect_fabric(frame, mm_per_px=1.0)
        fabric = det.fabric_json()
        assert fabric["kind"] == "lattice", (group, fabric)
        assert det.classification.confidence <= PART_OF_FRAME_CONFIDENCE < CONFIRM_BELOW
        assert "confirm that it covers the fabric" in fabric["message"], fabric["message"]
        same, err = lattice_match(det.lattice.basis, truth.basis)
        assert same and err < 0.1, (group, det.lattice.basis, truth.basis)
        outcomes.append((group, det.classification.group,
                         error_kind(det.classification.group, group)))
    assert not [o for o in outcomes if o[2] in ("supergroup", "other")], outcomes
    assert sum(o[2] == "right" for o in outcomes) >= 15, outcomes


def test_plain_cloth_on_a_bulge_stays_plain():
    """The centre is read only for a print: cloth without one stays plain there too."""
    rng = np.random.default_rng(5)
    for sigma in (1.0, 3.0, 8.0):
        cloth = cv2.GaussianBlur(rng.normal(0.5, 0.2, (600, 600)).astype(np.float32),
                                 (0, 0), sigma)
        frame = (255 * np.clip(_on_a_bulge(cloth, 1.0), 0, 1)).astype(np.uint8)
        det = detect_fabric(frame, mm_per_px=1.0)
        assert det.classification.group is None and det.lattice.kind == "plain", sigma
