"""The mean unit cell of a print: every whole repeat in the image sampled on an ``N x N``
grid of fractional coordinates of the lattice basis, registered to the running mean by a
circular cross-correlation (so perspective and folds that move repeats by a fraction of
a cell do not blur it), and averaged; with the split-half reliability of that mean."""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict

import cv2
import numpy as np
from scipy import fft as sfft

__all__ = ["CELL_N", "mean_cell", "repeat_cells", "split_half_reliability"]

#: Grid of the mean cell: divisible by 2, 3, 4 and 6 so that every operation of every
#: group maps grid points onto grid points.
CELL_N = 96

#: The last answers of :func:`repeat_cells`, by their arguments' content: the step check
#: (:func:`vision.repeat.true_lattice`) and the classifier (and its strict second read
#: of a rendering) sample the same repeats of the same working image, a tenth of the
#: time of reading a photograph. Two answers: one per image in flight.
_RECENT: OrderedDict[tuple, tuple] = OrderedDict()
_RECENT_SIZE = 2
_RECENT_LOCK = threading.Lock()


def _cell_maps(anchor: np.ndarray, basis: np.ndarray, n: int, shape: tuple[int, int],
               max_repeats: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sampling maps (R, n, n) x and y of the repeats lying wholly inside the image.

    ``basis`` columns are w1, w2 in working (x, y) pixels; the cell grid point (a, b)
    of repeat (i, j) is ``anchor + (a/n + i) w1 + (b/n + j) w2``.
    """
    h, w = shape
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], float) - anchor
    frac = corners @ np.linalg.inv(basis).T
    lo = np.floor(frac.min(0)).astype(int) - 1
    hi = np.ceil(frac.max(0)).astype(int) + 1
    ii, jj = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1),
                         indexing="ij")
    ij = np.stack([ii.ravel(), jj.ravel()], 1).astype(float)
    cell_corners = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], float)
    pts = anchor + (ij[:, None, :] + cell_corners[None]) @ basis.T  # (R,4,2)
    margin = 2.0
    inside = np.all((pts[..., 0] >= margin) & (pts[..., 0] <= w - 1 - margin)
                    & (pts[..., 1] >= margin) & (pts[..., 1] <= h - 1 - margin), axis=1)
    ij = ij[inside]
    if len(ij) > max_repeats:  # keep the central ones: least distorted by the view
        d = np.linalg.norm((ij + 0.5) @ basis.T, axis=1)
        ij = ij[np.argsort(d)[:max_repeats]]
    g = np.arange(n) / n
    ga, gb = np.meshgrid(g, g, indexing="ij")  # [a, b]: a along w1, b along w2
    fa = ij[:, 0, None, None] + ga[None]
    fb = ij[:, 1, None, None] + gb[None]
    x = anchor[0] + fa * basis[0, 0] + fb * basis[0, 1]
    y = anchor[1] + fa * basis[1, 0] + fb * basis[1, 1]
    return x.astype(np.float32), y.astype(np.float32), ij


def repeat_cells(flat: np.ndarray, basis: np.ndarray, *, cell_n: int = CELL_N,
                 max_repeats: int = 400, prefilter: float = 1.0) -> tuple[np.ndarray, tuple]:
    """The anchor (the central repeat's cell is centred on the image, so that at least
    one whole repeat is sampled even when only about three fit across) and
    :func:`mean_cell`'s answer for the lattice ``basis`` (working (x, y) px). The image
    is band-limited to the cell grid first: sampling a sharp print more coarsely than
    its pixels by interpolation leaves errors that differ between a point and its
    symmetric partner, and a whitening would amplify them."""
    key = _content_key(flat, basis, cell_n, max_repeats, prefilter)
    with _RECENT_LOCK:
        if key in _RECENT:
            _RECENT.move_to_end(key)
            return _RECENT[key]
    h, w = flat.shape
    anchor = np.array([(w - 1) / 2.0, (h - 1) / 2.0]) - basis @ np.array([0.5, 0.5])
    spacing = float(np.linalg.norm(basis, axis=0).max()) / cell_n
    if spacing > 1.0:
        flat = cv2.GaussianBlur(flat, (0, 0), prefilter * spacing)
    found = _frozen((anchor, mean_cell(flat, basis, anchor, n=cell_n, max_repeats=max_repeats)))
    with _RECENT_LOCK:
        _RECENT[key] = found
        while len(_RECENT) > _RECENT_SIZE:
            _RECENT.popitem(last=False)
    return found


def _content_key(flat: np.ndarray, basis: np.ndarray, *options: float) -> tuple:
    """What :func:`repeat_cells` answers from: the image's pixels (their SHA-256, 2 ms
    for a 1024 px working image), the basis and the options."""
    pixels = hashlib.sha256(np.ascontiguousarray(flat).data).digest()
    return (flat.shape, flat.dtype.str, pixels, np.asarray(basis, float).tobytes(), options)


def _frozen(answer: object) -> object:
    """``answer`` with its arrays read-only: it is handed to every caller that asks again,
    so none may change it in place."""
    if isinstance(answer, np.ndarray):
        answer.setflags(write=False)
        return answer
    if isinstance(answer, tuple):
        return tuple(_frozen(a) for a in answer)
    return answer


def mean_cell(flat: np.ndarray, basis: np.ndarray, anchor: np.ndarray, *, n: int = CELL_N,
              max_repeats: int = 400, register: bool = True):
    """Mean unit cell (n, n) over the repeats, the means of its two halves (even and odd
    repeats), the number of repeats, their (i, j) indices, their registration shifts
    (R, 2) in cell units and the registered cells themselves (R, n, n).

    Registration: each repeat's cell is circularly cross-correlated with the mean of
    the others (all FFTs at once), shifted by the peak (Fourier shift theorem, exact for
    a periodic cell) and averaged again; two rounds.
    """
    x, y, ij = _cell_maps(anchor, basis, n, flat.shape, max_repeats)
    r = len(ij)
    if r == 0:
        raise ValueError("no whole repeat of the print lies inside the image")
    # cv2.remap takes maps of fewer than 32767 rows: sample in batches of repeats.
    per = max(1, 32000 // n)
    cells = np.concatenate([
        cv2.remap(flat, x[k:k + per].reshape(-1, n), y[k:k + per].reshape(-1, n),
                  cv2.INTER_LINEAR).reshape(-1, n, n)
        for k in range(0, r, per)]).astype(np.float64)
    cells -= cells.mean(axis=(1, 2), keepdims=True)
    shifts = np.zeros((r, 2))
    spec = sfft.fft2(cells.astype(np.complex64), workers=-1)
    if register and r > 1:
        spec, shifts = _registered(spec, n)
    cells = sfft.ifft2(spec, workers=-1).real.astype(np.float64)
    motif = cells.mean(axis=0)
    halves = (cells[0::2].mean(0), cells[1::2].mean(0) if r >= 2 else cells[0])
    return motif, halves, r, ij, shifts, cells


def _registered(spec: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The cells' spectra (R, n, n) each shifted onto the mean of all (two rounds), and
    the shifts (R, 2) in cell units, in the frame of the central repeats (median 0)."""
    r = len(spec)
    shifts = np.zeros((r, 2))
    k = np.fft.fftfreq(n) * n
    ka, kb = np.meshgrid(k, k, indexing="ij")
    for _ in range(2):
        ref = spec.mean(axis=0)
        # Peak of the circular cross-correlation at each repeat's shift.
        xc = sfft.ifft2(spec * np.conj(ref)[None], workers=-1).real
        flatidx = xc.reshape(r, -1).argmax(1)
        pa, pb = np.unravel_index(flatidx, (n, n))
        # Sub-sample: parabola through the neighbours along each axis.
        rr = np.arange(r)
        c0 = xc[rr, pa, pb]
        da = _parabola_peak(c0, xc[rr, (pa - 1) % n, pb], xc[rr, (pa + 1) % n, pb])
        db = _parabola_peak(c0, xc[rr, pa, (pb - 1) % n], xc[rr, pa, (pb + 1) % n])
        sa = ((pa + 0.5) % n - 0.5) + np.clip(da, -0.5, 0.5)
        sb = ((pb + 0.5) % n - 0.5) + np.clip(db, -0.5, 0.5)
        sa = np.where(sa > n / 2, sa - n, sa)
        sb = np.where(sb > n / 2, sb - n, sb)
        # Only small moves are registration; a large one is a bad repeat match.
        ok = np.hypot(sa, sb) < 0.25 * n
        sa, sb = np.where(ok, sa, 0.0), np.where(ok, sb, 0.0)
        shifts += np.stack([sa, sb], 1) / n
        # Separable phase ramp exp(2 pi i (k_a s_a + k_b s_b) / n).
        pa_ = np.exp(2j * np.pi * k[None, :] * sa[:, None] / n).astype(np.complex64)
        pb_ = np.exp(2j * np.pi * k[None, :] * sb[:, None] / n).astype(np.complex64)
        spec = spec * pa_[:, :, None] * pb_[:, None, :]
    # Keep the frame of the central repeats: undo the mean shift.
    mean_shift = np.median(shifts, axis=0)
    phase = np.exp(-2j * np.pi * (ka * mean_shift[0] + kb * mean_shift[1]))
    spec = spec * phase[None].astype(np.complex64)
    shifts -= mean_shift
    return spec, shifts


def _parabola_peak(c0: np.ndarray, cm: np.ndarray, cp: np.ndarray) -> np.ndarray:
    """Offset of the vertex of the parabola through (-1, cm), (0, c0), (1, cp); 0 where
    it is flat."""
    den = cm - 2 * c0 + cp
    return np.where(np.abs(den) > 1e-12, 0.5 * (cm - cp) / np.where(
        np.abs(den) > 1e-12, den, 1.0), 0.0)


def split_half_reliability(a: np.ndarray, b: np.ndarray) -> float:
    """Reliability of the mean of two half-means: their correlation, stepped up by the
    Spearman-Brown formula. A symmetric print's operations cannot score above it."""
    a, b = a.ravel(), b.ravel()
    if np.array_equal(a, b):
        # One repeat only: no second copy to measure the noise by. Taking the cell as
        # exact lets only operations that hold on it closely count (the safe side: a
        # single smooth cell looks nearly symmetric under many operations).
        return 1.0
    if a.std() <= 0 or b.std() <= 0:
        return 0.5
    rho = max(float(np.corrcoef(a, b)[0, 1]), 1e-3)
    return 2 * rho / (1 + rho)
