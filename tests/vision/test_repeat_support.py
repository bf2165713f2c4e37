"""Per-repeat evidence: a symmetry must hold on the single repeats, not only on their
mean, whatever the noise."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from simulators.fabric import random_print, render_print
from vision.classify import FEW_REPEATS_CONFIDENCE
from vision.decision import REPEAT_SUPPORT, repeat_support
from vision.pipeline import CONFIRM_BELOW, detect_fabric

N = 48
MIRROR = (np.array([[-1, 0], [0, 1]]), np.array([0, 0]))
HALF_TURN = (np.array([[-1, 0], [0, -1]]), np.array([0, 0]))


def _mirror_cells(rng, repeats, noise):
    x = rng.standard_normal((N, N))
    cell = x + x[(-np.arange(N)) % N, :]  # c(-a, b) = c(a, b)
    return cell[None] + noise * cell.std() * rng.standard_normal((repeats, N, N))


@pytest.mark.parametrize("noise", [0.1, 0.5, 1.0])
def test_a_true_mirror_is_supported_and_a_missing_half_turn_is_not(noise):
    cells = _mirror_cells(np.random.default_rng(3), 12, noise)
    mirror, half_turn = repeat_support(cells, [MIRROR, HALF_TURN])
    assert mirror == pytest.approx(1.0, abs=0.15)
    assert half_turn < REPEAT_SUPPORT


def test_distorted_repeats_of_an_asymmetric_cell_do_not_support_a_half_turn():
    """Each repeat is the cell moved by a few pixels (local distortion): neighbours still
    match well, but no repeat matches its own half-turn."""
    rng = np.random.default_rng(5)
    base = ndimage.gaussian_filter(rng.standard_normal((N, N)), 2.0, mode="wrap")
    cells = np.stack([np.roll(base, (int(a), int(b)), (0, 1))
                      for a, b in rng.integers(-2, 3, (16, 2))])
    cells += 0.2 * base.std() * rng.standard_normal(cells.shape)
    support, mirror_found = repeat_support(cells, [HALF_TURN, MIRROR])
    assert support < REPEAT_SUPPORT and mirror_found < REPEAT_SUPPORT


def test_an_answer_from_fewer_than_three_repeats_goes_to_the_operator():
    p = random_print("p4m", 90.0, rotation=5.0, seed=4)
    det = detect_fabric(render_print(p, (250, 200), 0.5), mm_per_px=0.5)
    assert det.classification.n_repeats < 3 and det.lattice.found
    assert det.classification.confidence <= FEW_REPEATS_CONFIDENCE < CONFIRM_BELOW


def _print_under_a_beat(group: str, seed: int, amplitude: float) -> tuple[np.ndarray, object]:
    """A print of ``group`` (7 mm repeat) under a strong square beat (a weave's moire
    with the pixels) on a lattice 1.43 times coarser and turned: the beat repeats on
    its lattice, the print does not. Returns the image and the beat's lattice."""
    from vision.lattice import LatticeResult

    rng = np.random.default_rng(seed)
    pr = random_print(group, 7.0, rotation=rng.uniform(0, 90), seed=int(rng.integers(1 << 30)))
    img = render_print(pr, (300.0, 240.0), 0.5).astype(float)
    y, x = np.mgrid[0:img.shape[0], 0:img.shape[1]] * 0.5
    period, t = 7.0 * 1.43, rng.uniform(0, np.pi / 2)
    u = (x * np.cos(t) + y * np.sin(t)) / period
    v = (-x * np.sin(t) + y * np.cos(t)) / period
    beat = amplitude * img.std() * (np.cos(2 * np.pi * u) + np.cos(2 * np.pi * v))
    lat = LatticeResult("lattice", w1=period * np.array([np.cos(t), np.sin(t)]),
                        w2=period * np.array([-np.sin(t), np.cos(t)]), mm_per_px=0.5,
                        strength=0.8)
    return np.clip(img + beat[..., None], 0, 255).astype(np.uint8), lat


@pytest.mark.parametrize(("group", "seed"), [("pm", 202), ("p3", 203), ("p4", 212)])
def test_a_lattice_the_print_does_not_repeat_on_claims_no_symmetry(group, seed):
    """Read on the beat's lattice, the mean cell is the beat's square grid (the pm and
    p3 prints read p4m without the check, the p4 print p4) while single repeats
    differ; the answer is p1, sent to the operator, never the beat's symmetry."""
    from vision.classify import classify

    img, lat = _print_under_a_beat(group, seed, 0.8)
    c = classify(img, lat)
    assert c.group == "p1" and c.confidence <= FEW_REPEATS_CONFIDENCE < CONFIRM_BELOW
    assert "look little alike" in c.message


def test_a_print_read_on_its_own_lattice_keeps_its_symmetry():
    """A print of the same scale read on its own lattice: repeats look alike and the
    group is read in full."""
    from vision.classify import classify
    from vision.lattice import LatticeResult

    p = random_print("p4m", 7.0, rotation=20.0, seed=11)
    img = render_print(p, (300.0, 240.0), 0.5)
    lat = LatticeResult("lattice", w1=p.wallpaper.w1, w2=p.wallpaper.w2, mm_per_px=0.5,
                        strength=0.9)
    c = classify(img, lat)
    assert c.group == "p4m" and not c.message
