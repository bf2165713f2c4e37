"""Whitening of a print's cells: the fine detail, where a missing symmetry shows, weighted
up, isotropically under the metric of the undistorted print (so every symmetry it
tests is kept), and rolled off where detail is the cloth's rather than the print's.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["symmetric_metric", "whitened", "whitening"]


def symmetric_metric(basis: np.ndarray, holo: list[np.ndarray]) -> np.ndarray:
    """The lattice metric averaged over the tested isometries: the metric of the
    undistorted print, under which every tested isometry is exact."""
    g = basis.T @ basis
    return sum((a.T @ g @ a for a in holo), g) / (len(holo) + 1)


def whitened(motif: np.ndarray, metric: np.ndarray, alpha: float,
             band: float = float("inf")) -> np.ndarray:
    """The cell(s) (..., n, n) with |frequency|^alpha weighting, rolled off at ``band``."""
    out = np.fft.ifft2(np.fft.fft2(motif) * whitening(motif.shape[-1], metric, alpha,
                                                      band)).real
    return out - out.mean(axis=(-2, -1), keepdims=True)


def whitening(n: int, metric: np.ndarray, alpha: float, band: float) -> np.ndarray:
    """Weights (n, n) of the harmonics of an n x n cell: |frequency|^alpha under
    ``metric``, rolled off (Gaussian) at ``band`` harmonics per repeat length."""
    k = np.fft.fftfreq(n) * n
    ka, kb = np.meshgrid(k, k, indexing="ij")
    # Cartesian |frequency| of harmonic (ka, kb) of the cell: k^T G^-1 k (isometries of
    # the metric G keep it, so the weighting keeps every symmetry).
    gi = np.linalg.inv(metric)
    f = np.sqrt(np.maximum(gi[0, 0] * ka**2 + 2 * gi[0, 1] * ka * kb + gi[1, 1] * kb**2,
                           0.0))
    # f in cycles per repeat length (sqrt of the cell area): the fine end is thread-scale
    # texture (twill lines, yarn) that need not share the print's symmetry.
    f = f * math.sqrt(math.sqrt(max(np.linalg.det(metric), 1e-12)))
    return f**alpha * np.exp(-0.5 * (f / band) ** 2)
