"""The print's autocorrelation and its peaks: normalised by the window's own
autocorrelation (so long lags are not biased), over the colour channels where the image
has them, with sub-pixel peak positions and lattice points within a radius."""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np
from scipy import fft as sfft
from scipy import ndimage
from skimage.feature import peak_local_max

from vision.prepare import prepare_colour, to_gray_shape

__all__ = ["autocorrelation", "lattice_points", "peaks_near_centre", "print_autocorrelation",
           "radial_profile", "subpixel"]

#: Autocorrelation peaks a lattice is chosen from: those nearest zero lag. A fine print
#: in a large frame has thousands, all about as tall; the tallest few hundred are then
#: any of them, and its shortest repeats need not be among them (a 32 px gingham in a
#: 4096 px frame was read on a lattice of index 156).
MAX_PEAKS = 400


def _tukey(n: int, alpha: float = 0.3) -> np.ndarray:
    x = np.linspace(0, 1, n)
    w = np.ones(n)
    edge = alpha / 2
    lo = x < edge
    hi = x > 1 - edge
    w[lo] = 0.5 * (1 + np.cos(np.pi * (x[lo] / edge - 1)))
    w[hi] = 0.5 * (1 + np.cos(np.pi * ((x[hi] - 1) / edge + 1)))
    return w


@lru_cache(maxsize=8)
def _window(h: int, w: int) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """Tukey window, its own autocorrelation (cropped, max 1) and the FFT size. The
    window is the outer product of two 1-D ones, and so is its autocorrelation: two
    1-D correlations instead of a 2-D FFT. The FFT size: an image padded to 1.5 times
    its size each way correlates circularly without wrapping onto the lags kept (half
    the image's size each way, see :func:`_crop`); twice, 1.8 times the transform."""
    win = np.outer(_tukey(h), _tukey(w)).astype(np.float32)
    shape = (sfft.next_fast_len(h + h // 2, real=True),
             sfft.next_fast_len(w + w // 2, real=True))
    return win, np.outer(_own_correlation(h), _own_correlation(w)).astype(np.float32), shape


def _own_correlation(n: int) -> np.ndarray:
    """The 1-D Tukey window's autocorrelation at lags -n//2..n//2 (as :func:`_crop`
    keeps them), 1 at lag 0."""
    t = _tukey(n)
    full = np.correlate(t, t, mode="full")  # lag 0 at index n - 1
    return full[n - 1 - n // 2:n + n // 2] / full[n - 1]


def _crop(full: np.ndarray, h: int, w: int) -> np.ndarray:
    """Lags within (-h/2, h/2) x (-w/2, w/2) of a circular correlation, zero lag at the
    centre index (h//2, w//2): longer lags overlap too little to matter."""
    rows = np.r_[-(h // 2):h // 2 + 1] % full.shape[0]
    cols = np.r_[-(w // 2):w // 2 + 1] % full.shape[1]
    return full[np.ix_(rows, cols)]


def autocorrelation(flat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normalised autocorrelation (centred, value 1 at lag 0) and the overlap weight.
    ``flat`` is one image (H,W) or colour channels (C,H,W), whose correlations add up:
    a print repeats in colour, not only in its grey.

    Dividing by the window's autocorrelation removes the triangular fall-off with lag,
    so a peak at a long lag is as tall as the pattern's true correlation there.
    """
    h, w = flat.shape[-2:]
    win, wacf, shape = _window(h, w)
    fx = sfft.rfft2(flat * win, s=shape, axes=(-2, -1), workers=-1)
    power = (fx.real**2 + fx.imag**2).astype(np.float32)
    if power.ndim == 3:
        power = power.sum(axis=0)
    acf = _crop(sfft.irfft2(power, s=shape, workers=-1), h, w)
    norm = acf / np.maximum(wacf, 0.05)
    norm /= max(float(norm[h // 2, w // 2]), 1e-12)
    return norm.astype(np.float32), wacf


def subpixel(img: np.ndarray, rc: np.ndarray) -> np.ndarray:
    """Quadratic (3x3 least-squares paraboloid) refinement of integer peak positions."""
    rc = np.asarray(rc, int)
    h, w = img.shape
    r = np.clip(rc[:, 0], 1, h - 2)
    c = np.clip(rc[:, 1], 1, w - 2)
    dy, dx = np.mgrid[-1:2, -1:2]
    patch = img[r[:, None, None] + dy, c[:, None, None] + dx].reshape(len(r), 9)
    x = dx.ravel().astype(float)
    y = dy.ravel().astype(float)
    a = np.stack([np.ones(9), x, y, x * x, x * y, y * y], axis=1)
    coef = np.linalg.lstsq(a, patch.T, rcond=None)[0].T  # (K,6)
    _, bx, by, axx, axy, ayy = coef.T
    det = 4 * axx * ayy - axy**2
    ok = (det > 1e-12) & (axx < 0) & (ayy < 0)
    ox = np.where(ok, (-2 * ayy * bx + axy * by) / np.where(ok, det, 1), 0.0)
    oy = np.where(ok, (-2 * axx * by + axy * bx) / np.where(ok, det, 1), 0.0)
    ox = np.clip(ox, -1, 1)
    oy = np.clip(oy, -1, 1)
    return np.stack([r + oy, c + ox], axis=1)


def lattice_points(basis: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Integer index pairs (upper half plane, no origin) and their vectors within radius."""
    binv = np.linalg.inv(basis)
    # |n_k| <= radius * ||row k of B^-1||
    lim = np.ceil(radius * np.linalg.norm(binv, axis=1)).astype(int) + 1
    lim = np.minimum(lim, 60)
    i, j = np.meshgrid(np.arange(-lim[0], lim[0] + 1), np.arange(-lim[1], lim[1] + 1),
                       indexing="ij")
    n = np.stack([i.ravel(), j.ravel()], axis=1)
    v = n @ basis.T
    keep = (np.hypot(v[:, 0], v[:, 1]) <= radius) & ((v[:, 1] > 1e-9) | (
        (np.abs(v[:, 1]) <= 1e-9) & (v[:, 0] > 1e-9)))
    return n[keep], v[keep]


def peaks_near_centre(acf: np.ndarray, threshold: float) -> np.ndarray:
    """(row, col) of the autocorrelation's peaks above ``threshold``: all, tallest first,
    or when there are more, the ``MAX_PEAKS`` nearest zero lag (the centre), nearest
    first. Only a disc holding about twice as many local maxima is searched: spacing
    thousands of peaks apart costs 0.4 s."""
    center = np.array(acf.shape) // 2
    local = np.argwhere((acf == ndimage.maximum_filter(acf, size=5)) & (acf > threshold))
    if len(local) > 2 * MAX_PEAKS:
        reach2 = np.partition(((local - center) ** 2).sum(axis=1), 2 * MAX_PEAKS)[2 * MAX_PEAKS]
        rows, cols = np.ogrid[:acf.shape[0], :acf.shape[1]]
        acf = np.where((rows - center[0]) ** 2 + (cols - center[1]) ** 2 <= reach2, acf, -1.0)
    coords = peak_local_max(acf, min_distance=2, threshold_abs=threshold, exclude_border=2)
    if len(coords) <= MAX_PEAKS:
        return coords  # tallest first
    return coords[np.argsort(((coords - center) ** 2).sum(axis=1), kind="stable")[:MAX_PEAKS]]


def radial_profile(acf: np.ndarray, angle: float, lags: np.ndarray) -> np.ndarray:
    """The autocorrelation at ``lags`` (px) from zero lag along ``angle`` (radians),
    interpolated cubically: a ridge or a peak a few pixels wide off the pixel axes falls
    between pixels, and linear interpolation makes it ripple each time the line crosses
    a column (a 7 px rib turned 2 degrees: 0.06 along its ridge, 0.001 cubic) and pulls
    peaks onto whole lags (its period read 7.25 px for 7.5)."""
    cy, cx = acf.shape[0] // 2, acf.shape[1] // 2
    r = int(np.ceil(lags.max())) + 4
    near = acf[max(cy - r, 0):cy + r + 1, max(cx - r, 0):cx + r + 1]
    oy, ox = cy - max(cy - r, 0), cx - max(cx - r, 0)
    return ndimage.map_coordinates(near, [oy + np.sin(angle) * lags, ox + np.cos(angle) * lags],
                                   order=3, mode="nearest")


def print_autocorrelation(image: np.ndarray, flat: np.ndarray, scale: float,
                           smooth_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Autocorrelation (and its overlap weight) of the working image ``flat``, over its
    colour channels where ``image`` is the same view in colour, smoothed ``smooth_px``."""
    colour = _same_view_colour(image, flat, scale)
    chans = flat[None] if colour is None else colour
    chans = np.stack([cv2.GaussianBlur(c, (0, 0), max(1.0, smooth_px)) for c in chans])
    return autocorrelation(chans)


def _same_view_colour(image: np.ndarray, flat: np.ndarray,
                      scale: float) -> np.ndarray | None:
    """The colour channels of ``image`` when ``flat`` is its grey working image (not a
    rectified or cropped view of it, whose colour the caller does not hand over)."""
    shape = np.array(to_gray_shape(image), float) * scale
    if np.ndim(image) != 3 or np.abs(shape - flat.shape).max() > 1.5:
        return None
    return prepare_colour(image, flat.shape)
