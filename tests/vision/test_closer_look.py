"""A print too fine for the shrunk working image is read again at full resolution on
the frame's centre (vision/pipeline.py, ``closer_look``)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from bench.vision import lattice_match
from simulators.classics import classic_print
from simulators.fabric import random_print, render_print
from solver.wallpaper import Wallpaper
from vision.pipeline import PART_OF_FRAME_CONFIDENCE, detect_fabric
from vision.subgroups import error_kind


def _wide_frame(name: str, repeat: float, rotation: float, seed: int
                ) -> tuple[np.ndarray, Wallpaper]:
    """A 4096 x 1800 px frame (pixels = mm) of a classic, lightly blurred and noisy."""
    p = classic_print(name, repeat, rotation=rotation)
    img = cv2.GaussianBlur(render_print(p, (4096, 1800), 1.0), (0, 0), 0.8)
    noise = np.random.default_rng(seed).normal(0, 5, img.shape)
    return np.clip(img + noise, 0, 255).astype(np.uint8), p.wallpaper


@pytest.mark.parametrize("repeat, rotation", [(41.3, 0.0), (41.3, 0.9), (55.2, 0.9),
                                              (63.7, 2.4)])
def test_a_fine_herringbone_in_a_wide_frame_is_read_at_full_resolution(repeat, rotation):
    """The herringbone's twill step (a third of its repeat) is 3.4-5.3 working px, under
    what the lattice search resolves: the working image alone reads a wrong lattice,
    fine or coarse (at 41.3 px and 0.9 degrees a multiple of index 11, whose 69 px step
    only the first look at the centre shows up). Read closer, the lattice is the
    print's and the group never a supergroup."""
    frame, truth = _wide_frame("herringbone", repeat, rotation, seed=int(repeat))
    det = detect_fabric(frame, mm_per_px=1.0)
    same, err = lattice_match(det.lattice.basis, truth.basis)
    assert same and err < 0.01, (det.lattice.basis, truth.basis)
    assert error_kind(det.classification.group, truth.group) in ("right", "subgroup")
    shrunk = detect_fabric(frame, mm_per_px=1.0, closer_look=False)
    assert not (shrunk.lattice.found and lattice_match(shrunk.lattice.basis, truth.basis)[0])


def test_a_print_the_working_image_loses_is_found_at_the_centre():
    """A 21 px herringbone (7 px twill step, 1.8 working px) shrinks to plain grey: the
    whole frame shows no print. The first look at the centre finds it; read closer, it
    goes to the operator, since the whole frame does not bear it out."""
    frame, truth = _wide_frame("herringbone", 21.3, 0.8, seed=21)
    assert detect_fabric(frame, mm_per_px=1.0, closer_look=False).lattice.kind == "plain"
    det = detect_fabric(frame, mm_per_px=1.0)
    same, err = lattice_match(det.lattice.basis, truth.basis)
    assert same and err < 0.01, (det.lattice.basis, truth.basis)
    assert error_kind(det.classification.group, truth.group) in ("right", "subgroup")
    assert det.classification.confidence <= PART_OF_FRAME_CONFIDENCE
    assert "shows no print" in det.fabric_json()["message"]


def test_a_coarse_print_is_read_on_the_whole_frame():
    """A repeat the working image resolves is not looked at again: the answer is the
    whole frame's, with the distortion measured over all of it."""
    frame, truth = _wide_frame("gingham", 160.0, 1.0, seed=3)
    det = detect_fabric(frame, mm_per_px=1.0)
    assert det.classification.group == "p4m" and det.classification.confidence > 0.9
    assert lattice_match(det.lattice.basis, truth.basis)[0]
    centres = det.distortion.centres
    assert np.ptp(centres[:, 0]) > 2000  # measured across the frame, not its centre


@pytest.mark.parametrize("group, seed, depth", [("pmm", 1, 0.3), ("p4m", 1, 0.6)])
def test_a_fine_print_under_shading_bands_is_not_read_as_stripes(group, seed, depth):
    """A 28 px print (7 working px) under shading bands 80-400 px wide (line-scan light,
    long wrinkles): the shrunk frame reads the bands as stripes. The first look at the
    centre finds the print; read closer, it goes to the operator."""
    rng = np.random.default_rng(seed)
    p = random_print(group, 28.0, rotation=0.0, seed=seed)
    img = render_print(p, (4096, 1800), 1.0).astype(np.float32) / 255.0
    x = np.arange(4096, dtype=np.float32)
    bands = sum(rng.uniform(0.3, 1) * np.sin(2 * np.pi * x / rng.uniform(80, 400)
                                             + rng.uniform(0, 6)) for _ in range(4)) / 4
    frame = (255 * np.clip((0.15 + 0.7 * img) * (1 + depth * bands)[None, :, None], 0, 1)
             ).astype(np.uint8)
    assert detect_fabric(frame, mm_per_px=1.0, closer_look=False).lattice.kind == "stripes"
    det = detect_fabric(frame, mm_per_px=1.0)
    assert det.classification.group == group
    assert lattice_match(det.lattice.basis, p.wallpaper.basis)[0]
    assert det.classification.confidence <= PART_OF_FRAME_CONFIDENCE
