"""Three- and six-fold prints however a generator lays out their hexagon (turned,
upright, on a rectangular tile of whole pixels), and near-hexagonal grounds that keep
their mirrors: the group read is the print's, never a supergroup."""

from __future__ import annotations

import numpy as np
import pytest

from bench.vision import lattice_match
from bench.vision_groups import hexagon_basis, near_hexagon_basis, tiled_hexagon
from simulators.fabric import random_print, render_print
from vision.pipeline import detect_fabric


def _read(group: str, basis: np.ndarray, seed: int, tiled: bool = False):
    pr = random_print(group, w1=basis[:, 0], w2=basis[:, 1], seed=seed)
    if tiled:
        img, truth = tiled_hexagon(pr, (360, 270), anti_alias=seed % 2 == 0)
    else:
        img = render_print(pr, (360.0, 270.0), 1.0, anti_alias=seed % 2 == 0)
        truth = pr.wallpaper.basis
    return detect_fabric(img, mm_per_px=1.0), truth


@pytest.mark.parametrize(("group", "layout", "seed"), [
    ("p3", "rounded tile", 1), ("p3m1", "turned", 2), ("p31m", "rounded tile", 3),
    ("p6", "rounded tile", 4), ("p6m", "upright", 5)])
def test_hexagonal_prints_are_read_in_any_layout(group, layout, seed):
    rng = np.random.default_rng(seed)
    det, truth = _read(group, hexagon_basis(layout, 36.0, rng), seed,
                       tiled=layout == "rounded tile")
    ok, err = lattice_match(det.lattice.basis, truth)
    assert ok and err < 0.03, (det.lattice, truth)
    assert det.classification.group == group, det.classification.message


@pytest.mark.parametrize(("group", "seed"), [("cmm", 6), ("cm", 7)])
def test_near_hexagonal_grounds_keep_their_mirrors(group, seed):
    """Rhombic cells of 58-64 degrees: six-fold candidates are tested, and refused."""
    det, _ = _read(group, near_hexagon_basis(group, 34.0, np.random.default_rng(seed)), seed)
    assert det.classification.group == group, det.classification.message
