"""How alike neighbouring single repeats of a lattice are, along each of its directions.

A print repeats along both lattice vectors. Shading streaks, a camera's column bands or
a tossed print do not: read on a "lattice" that the autocorrelation's smooth bumps
suggest, their cells may still look alike along one vector (the streaks run along it)
and unlike along the other. So the likeness of repeats is measured along ``w1`` and
``w2`` apart, and the lattice is only as good as its worse direction.
"""

from __future__ import annotations

import numpy as np
from scipy import fft as sfft

from vision.consistency import WEIGHT_FLOOR
from vision.whitening import whitening

__all__ = ["BAND_LIKENESS", "BANDS", "LOWEST_BAND", "MAX_PAIRS", "MIN_PAIRS",
           "directional_likeness", "neighbour_correlation", "neighbour_pairs", "print_band",
           "worse_likeness"]

#: Neighbouring pairs a direction needs before its likeness is measured (a print one
#: repeat tall, such as a sweater's row of argyle diamonds, is not measured across).
MIN_PAIRS = 2
#: Pairs per direction compared (spread over the frame): their median is steady, and
#: all 400 repeats of a fine print cost 0.4 s per band.
MAX_PAIRS = 96

#: How alike neighbouring repeats must be over the harmonics up to a band for the band
#: to count as the print's (:func:`print_band`). Measured at 3/6/12 harmonics: the
#: bobbin lace 0.79/0.55/0.35, the knitted checker 0.91/0.73/0.51; prints of the
#: blurred, cloth and synthetic sources mostly above 0.9/0.9/0.85 ...
BAND_LIKENESS = 0.75
#: ... among these bands (harmonics per repeat), the first also telling whether the
#: coarse design repeats at all ...
BANDS = (3.0, 4.0, 6.0, 8.0, 12.0)
#: ... and never below this one: at 3-4 harmonics a jacquard's L-shaped brackets are
#: blobs, and their half turn reads as mirrors (a photograph in perspective, p2 as pmm).
LOWEST_BAND = 6.0


def _pair_correlations(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Correlation of each row of ``a`` with the same row of ``b`` (real or complex:
    spectra correlate as their cells do, by Parseval)."""
    norm = np.sqrt((np.abs(a) ** 2).sum(axis=1) * (np.abs(b) ** 2).sum(axis=1))
    return np.real((a * np.conj(b)).sum(axis=1)) / np.maximum(norm, 1e-12)


def neighbour_correlation(cells: np.ndarray) -> float:
    """Median correlation of each single repeat's cell (R, ...) with the next one's in
    the given order: how alike the repeats are (noise, distortion, print irregularity),
    1 when exact. ``cells`` may also be their spectra, complex."""
    flat = cells.reshape(len(cells), -1)
    return float(np.median(_pair_correlations(flat, np.roll(flat, -1, axis=0))))


def neighbour_pairs(ij: np.ndarray) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    """Per lattice vector (w1, then w2), the repeats (indices into ``ij`` (R, 2), the
    repeats' integer indices) that have a neighbour one step along it, and that
    neighbour; at most ``MAX_PAIRS`` pairs each, spread over all."""
    idx = np.rint(ij).astype(np.int64)
    lo = idx.min(axis=0) if len(idx) else np.zeros(2, np.int64)
    span = idx.max(axis=0) - lo + 2 if len(idx) else np.ones(2, np.int64)
    key = (idx[:, 0] - lo[0]) * span[1] + (idx[:, 1] - lo[1])
    order = np.argsort(key)
    out = []
    for step in (span[1], 1):  # one step along w1, then along w2
        at = np.minimum(np.searchsorted(key[order], key + step), max(len(key) - 1, 0))
        has = np.flatnonzero(key[order][at] == key + step) if len(key) else np.zeros(0, int)
        pick = np.linspace(0, len(has) - 1, min(len(has), MAX_PAIRS)).round().astype(int)
        out.append((has[pick], order[at[has[pick]]]))
    return tuple(out)


def directional_likeness(cells: np.ndarray, ij: np.ndarray,
                         weights: np.ndarray | None = None) -> tuple[float, float]:
    """Median correlation of repeats (R, ...) with their neighbour one step along
    ``w1`` and one step along ``w2`` (``ij`` (R, 2): the repeats' integer indices);
    NaN for a direction with fewer than ``MIN_PAIRS`` such pairs in view. ``weights``
    (one per element of a cell, e.g. a whitening of spectra) weigh the elements it
    keeps."""
    if len(cells) != len(ij):
        raise ValueError(f"{len(cells)} cells but {len(ij)} repeat indices")
    flat = cells.reshape(len(cells), -1)
    keep = slice(None) if weights is None else weights > WEIGHT_FLOOR * weights.max()
    scale = 1.0 if weights is None else weights[keep]
    out = []
    for first, second in neighbour_pairs(ij):
        if len(first) < MIN_PAIRS:
            out.append(float("nan"))
            continue
        out.append(float(np.median(_pair_correlations(flat[first][:, keep] * scale,
                                                      flat[second][:, keep] * scale))))
    return out[0], out[1]


def worse_likeness(spectra: np.ndarray, ij: np.ndarray, weights: np.ndarray) -> float:
    """The worse of :func:`directional_likeness` along w1 and w2 of the repeats'
    spectra (R, n*n) weighted by ``weights`` (n*n); the given order's neighbours where
    neither direction is in view."""
    along = np.array(directional_likeness(spectra, ij, weights))
    if np.isfinite(along).any():
        return float(np.nanmin(along))
    keep = weights > WEIGHT_FLOOR * weights.max()
    return neighbour_correlation(spectra[:, keep] * weights[keep])


def print_band(cells: np.ndarray, ij: np.ndarray, metric: np.ndarray, alpha: float,
               most: float) -> float:
    """Harmonics per repeat (of ``BANDS``, at most ``most``, at least ``LOWEST_BAND``)
    up to which neighbouring single repeats (R, n, n) still look alike
    (``BAND_LIKENESS``).

    Finer detail that differs from repeat to repeat where the coarse design repeats
    well is the cloth's, not the design's: a bobbin lace's hand-twisted threads, a
    knit's stitches under drape. What of it is the same in every repeat (the twist's
    handedness) still breaks the design's mirrors on the mean cell, so the symmetry is
    read below it. Where even the coarsest band's repeats look unlike, noise covers
    every band (a small print under blur and noise) and none is singled out: ``most``.
    """
    spectra = sfft.fft2(cells.astype(np.float32), workers=-1).reshape(len(cells), -1)
    n = cells.shape[-1]
    alike = [worse_likeness(spectra, ij, whitening(n, metric, alpha, band).ravel())
             >= BAND_LIKENESS for band in BANDS if band <= most]
    if not alike or not alike[0] or all(alike):
        return most
    return min(max(BANDS[alike.index(False) - 1], LOWEST_BAND), most)
