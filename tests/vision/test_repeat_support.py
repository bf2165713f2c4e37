"""Per-repeat evidence: a symmetry must hold on the single repeats, not only on their
mean, whatever the noise."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from simulators.fabric import random_print, render_print
from vision.classify import FEW_REPEATS_CONFIDENCE, REPEAT_SUPPORT, repeat_support
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
