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


@pytest.mark.parametrize(("group", "layout", "repeat", "seed"), [
    ("p3", "rounded tile", 36.0, 1), ("p3m1", "turned", 36.0, 2),
    ("p31m", "rounded tile", 36.0, 3), ("p6", "rounded tile", 36.0, 4),
    ("p6m", "upright", 36.0, 5)])
def test_hexagonal_prints_are_read_in_any_layout(group, layout, repeat, seed):
    rng = np.random.default_rng(seed)
    det, truth = _read(group, hexagon_basis(layout, repeat, rng), seed,
                       tiled=layout == "rounded tile")
    ok, err = lattice_match(det.lattice.basis, truth)
    assert ok and err < 0.03, (det.lattice, truth)
    assert det.classification.group == group, det.classification.message


@pytest.mark.parametrize(("group", "seed"), [("cmm", 6), ("cm", 7)])
def test_near_hexagonal_grounds_keep_their_mirrors(group, seed):
    """Rhombic cells of 58-64 degrees: six-fold candidates are tested, and refused."""
    det, _ = _read(group, near_hexagon_basis(group, 34.0, np.random.default_rng(seed)), seed)
    assert det.classification.group == group, det.classification.message


def test_a_hexagon_on_a_tile_of_odd_width_is_read_on_the_hexagon():
    """A 49 x 85 px tile puts the centre repeat half a pixel off, unsmoothed: the lattice
    is still the hexagon, not the tile (it read pmg on the tile while the centred
    refinement was never tried and the repeat along x lost its peaks)."""
    basis = hexagon_basis("rounded tile", 49.0, np.random.default_rng(0))
    pr = random_print("p6m", w1=basis[:, 0], w2=basis[:, 1], seed=462383316)
    img, truth = tiled_hexagon(pr, (842, 631), anti_alias=False)
    det = detect_fabric(img, mm_per_px=1.0)
    ok, err = lattice_match(det.lattice.basis, truth)
    assert ok and err < 0.03, (det.lattice, truth)
    assert det.classification.group == "p6m", det.classification.message
