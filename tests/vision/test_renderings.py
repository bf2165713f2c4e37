"""Renderings: prints drawn by a program, repeating by whole pixels, with hard edges.

A generator or a design file repeats its tile by whole pixels and rounds every edge to
the grid, the same way in every repeat, so the rounding is a residual all repeats share,
as a faint stroke of the print is. Read as one, it turned most groups into subgroups.
"""

from __future__ import annotations

import numpy as np
import pytest

import vision.classify as classify_module
from bench.vision import lattice_match
from simulators.fabric import random_print, render_print
from solver.wallpaper import GROUP_NAMES, GROUPS
from vision.consistency import PIXEL_GRID_DRIFT, pixel_rounding
from vision.pipeline import CONFIRM_BELOW, detect_fabric

#: Lattices of whole pixels per lattice type (at 1 mm per px).
WHOLE_PIXELS = {"oblique": ((40, 0), (13, 34)), "rectangular": ((48, 0), (0, 32)),
                "square": ((40, 0), (0, 40)), "rhombic": ((24, 32), (24, -32))}
#: Symmetry elements off every point the pixel grid is itself symmetric about.
OFF_GRID = (0.3, 0.7)


def _rendering(group: str, seed: int = 0) -> np.ndarray:
    w1, w2 = (np.array(v, float) for v in WHOLE_PIXELS[GROUPS[group].lattice])
    p = random_print(group, w1=w1, w2=w2, seed=seed, origin=OFF_GRID)
    return render_print(p, (600, 600), 1.0, anti_alias=False)


#: A hexagonal lattice is never whole pixels along both axes.
GROUPS_ON_WHOLE_PIXELS = [g for g in GROUP_NAMES if GROUPS[g].lattice != "hexagonal"]


@pytest.mark.parametrize("group", GROUPS_ON_WHOLE_PIXELS)
def test_hard_edged_renderings_get_their_group(group):
    det = detect_fabric(_rendering(group), mm_per_px=1.0)
    assert det.classification.group == group, det.classification.op_scores


def test_without_the_slack_most_renderings_lose_symmetries(monkeypatch):
    monkeypatch.setattr(classify_module, "pixel_rounding", lambda *a, **kw: None)
    right = sum(detect_fabric(_rendering(g), mm_per_px=1.0).classification.group == g
                for g in GROUPS_ON_WHOLE_PIXELS)
    assert right <= len(GROUPS_ON_WHOLE_PIXELS) // 2


def test_a_faint_dot_in_a_rendering_is_never_a_confident_symmetry():
    """Every repeat of a p4m rendering carries a small faint dot off the mirrors: the
    print is p1. The allowance lets an edge sit a pixel off its image, not a stroke
    with no image at all; a dot lying along an edge of the print can hide in it, so a
    group read only with the allowance goes to the operator."""
    w1, w2 = (np.array(v, float) for v in WHOLE_PIXELS["square"])
    cell = np.column_stack([w1, w2])
    yy, xx = np.mgrid[0:600, 0:600]
    frac = np.stack([xx - OFF_GRID[0], yy - OFF_GRID[1]], -1) @ np.linalg.inv(cell).T
    offset = np.moveaxis((frac - np.floor(frac) - (0.31, 0.13)) @ cell.T, -1, 0)
    answers = []
    for radius, contrast in ((2.0, 0.6), (3.0, 0.4), (5.0, 0.4)):
        for seed in range(4):
            img = _rendering("p4m", seed).astype(float)
            dot = np.hypot(*offset) < radius
            img[dot] = (1 - contrast) * img[dot] + contrast * (255 - img[dot])
            cls = detect_fabric(img.astype(np.uint8), mm_per_px=1.0).classification
            answers.append(cls.group)
            if cls.group != "p1":
                assert cls.confidence < CONFIRM_BELOW, (radius, contrast, seed, cls.group)
    assert answers.count("p1") >= 0.75 * len(answers), answers


def test_a_group_read_only_with_the_allowance_goes_to_the_operator():
    det = detect_fabric(_rendering("p4"), mm_per_px=1.0)
    assert det.classification.group == "p4"
    assert det.classification.confidence < CONFIRM_BELOW
    assert "whole pixels apart" in det.classification.message


def test_rounding_is_allowed_only_where_repeats_lie_whole_pixels_apart():
    ij = np.array([(i, j) for i in range(-4, 5) for j in range(-4, 5)], float)
    whole = np.array([[40.0, 13.0], [0.0, 34.0]])
    assert pixel_rounding(whole, 1.0, ij, 96) is not None
    # A photograph's lattice is never whole pixels: the grid drifts across the repeats.
    assert pixel_rounding(whole + 0.03, 1.0, ij, 96) is None
    # Within the drift allowed over these repeats it still counts as whole.
    near = whole + PIXEL_GRID_DRIFT / 20
    assert pixel_rounding(near, 1.0, ij, 96) is not None
    # Too few repeats to tell whole pixels from chance.
    assert pixel_rounding(whole, 1.0, ij[np.abs(ij).max(axis=1) <= 1], 96) is None
    # A hexagonal rendering: whole pixels along x only.
    hexagonal = np.array([[40.0, 20.0], [0.0, 20 * np.sqrt(3)]])
    assert pixel_rounding(hexagonal, 1.0, ij, 96) is not None
    # Shrunk to a working image: whole pixels of the input, not of the working image.
    assert pixel_rounding(whole * 0.37, 0.37, ij, 96) is not None


def _half_pixel_cmm(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A cmm rendering whose centred cell (61 x 45 px) is whole pixels and whose
    primitive vectors are not: alternate repeats are rounded to the grid two ways."""
    p = random_print("cmm", w1=np.array([30.5, 22.5]), w2=np.array([30.5, -22.5]),
                     seed=seed, origin=OFF_GRID)
    return render_print(p, (700, 600), 1.0, anti_alias=False), p.wallpaper.basis


def test_a_half_pixel_step_of_a_rendering_is_still_a_repeat(monkeypatch):
    """Two ways of rounding alternate repeats are no difference of the print's: the
    lattice is not traded for its index-2 sublattice for them (vision.repeat) with the
    allowance; without it, some of the same renderings are read on the doubled cell."""
    import vision.repeat as repeat_module

    renderings = [_half_pixel_cmm(seed) for seed in range(6)]
    for img, basis in renderings:
        det = detect_fabric(img, mm_per_px=1.0)
        assert det.classification.group == "cmm"
        assert lattice_match(det.lattice.basis, basis)[0]
    monkeypatch.setattr(repeat_module, "_rounding_of", lambda *a: (lambda parity: None))
    doubled = sum(not lattice_match(detect_fabric(img, mm_per_px=1.0).lattice.basis,
                                   basis)[0] for img, basis in renderings)
    assert doubled >= 1
