"""The symmetry is read on the harmonics whose detail repeats: detail that differs from
repeat to repeat (a lace's hand-twisted threads, a knit's stitches) is the cloth's."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from vision.neighbours import LOWEST_BAND, print_band

N = 48
SQUARE = np.eye(2) * 40.0 ** 2  # metric of a 40 px square cell


def _cells(rng, fine: float, noise: float, rows: int = 6, cols: int = 6):
    """Repeats (R, N, N) of one coarse cell, each with its own fine detail (``fine``,
    relative) and pixel noise (``noise``), and their (i, j) indices."""
    coarse = ndimage.gaussian_filter(rng.standard_normal((N, N)), 6.0, mode="wrap")
    coarse /= coarse.std()
    i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    ij = np.stack([i.ravel(), j.ravel()], axis=1).astype(float)
    own = ndimage.gaussian_filter(rng.standard_normal((len(ij), N, N)), (0, 1.2, 1.2),
                                  mode="wrap")
    own /= own.std()
    cells = coarse[None] + fine * own + noise * rng.standard_normal((len(ij), N, N))
    return cells - cells.mean(axis=(1, 2), keepdims=True), ij


def test_repeats_alike_at_every_scale_keep_the_whole_band():
    cells, ij = _cells(np.random.default_rng(0), fine=0.0, noise=0.02)
    assert print_band(cells, ij, SQUARE, 1.0, 12.0) == 12.0
    assert print_band(cells, ij, SQUARE, 1.0, 6.0) == 6.0  # never above the one asked


def test_fine_detail_unlike_from_repeat_to_repeat_lowers_the_band():
    cells, ij = _cells(np.random.default_rng(1), fine=0.6, noise=0.02)
    band = print_band(cells, ij, SQUARE, 1.0, 12.0)
    assert LOWEST_BAND <= band < 12.0


def test_noise_over_every_band_singles_none_out():
    """Repeats unlike even at the coarsest band: noise, not the cloth's fine detail."""
    cells, ij = _cells(np.random.default_rng(2), fine=0.0, noise=3.0)
    assert print_band(cells, ij, SQUARE, 1.0, 12.0) == 12.0
