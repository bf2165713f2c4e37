"""Find the translation lattice of a periodic print: two shortest repeat vectors w1, w2.

Method (own code, after the published ideas cited below): flatten the light, take the
autocorrelation of the colour channels through the FFT (normalised by the window's own
autocorrelation so that long lags are not biased), find its peaks, choose the *densest*
lattice whose points all carry strong autocorrelation (a denser lattice would land on
empty lags; a sparser one is a sub-lattice). Small, blurred or wrinkled prints lower
the autocorrelation with lag, so a candidate is ranked by its shortest repeats (checked
only at well-overlapped lags: a sparse lattice seen at two long lags wins there by
chance), and its index-2/3/4 refinements are tested by the lags they add against
what its own lags carry at the same lag. Then fit both vectors by weighted least
squares on many sub-pixel peaks ``p = i w1 + j w2`` at once, which gives precision
and an uncertainty well beyond the position error of any single peak.

Stripes (1-D repeats, a frieze across the cloth) show as a ridge of high autocorrelation
along the stripes; they are reported with their period and direction, never as a
2-D lattice. Plain cloth has no off-origin peaks, or only weak ones (shading bands), or
repeats finer than the smallest print repeat (``min_repeat_mm``: the weave, the yarn, a
rib knit's wales), or a coarser "lattice" that holds less well than the weave's own
repeat (a moire of the yarn with the pixels); it is reported as ``"plain"``.

References
----------
.. [1] Y. Liu, R. T. Collins, Y. Tsin, "A computational model for periodic pattern
       perception based on frieze and wallpaper groups", IEEE PAMI 26(3), 2004.
       :DOI:`10.1109/TPAMI.2004.1262332` (autocorrelation peaks, lattice from peaks).
.. [2] J. Hays, M. Leordeanu, A. A. Efros, Y. Liu, "Discovering texture regularity as a
       higher-order correspondence problem", ECCV 2006 (lattice as the pattern that
       explains the most repeats).
.. [3] M. von Gagern, "Automatic detection of wallpaper groups", 2008 (lattice by
       autocorrelation before symmetry tests).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache, lru_cache

import cv2
import numpy as np
from scipy import fft as sfft
from scipy import ndimage
from skimage.feature import peak_local_max

from solver.wallpaper import gauss_reduce

__all__ = ["LatticeResult", "detect_lattice", "nested", "prepare_colour", "prepare_image",
           "sublattice", "yarn_repeat"]

#: Autocorrelation of the image's fine detail at which a 2-D repeat finer than any
#: print counts as the yarn showing (a weave's interlacing, a knit's stitches).
YARN_SEEN = 0.3

#: Largest side of the working image: the lattice is fitted on many peaks, so a
#: moderate resolution keeps sub-pixel precision while the FFT stays fast.
WORK_SIDE = 1024

#: Autocorrelation peaks a lattice is chosen from: those nearest zero lag. A fine print
#: in a large frame has thousands, all about as tall; the tallest few hundred are then
#: any of them, and its shortest repeats need not be among them (a 32 px gingham in a
#: 4096 px frame was read on a lattice of index 156).
MAX_PEAKS = 400


@dataclass
class LatticeResult:
    """Outcome of :func:`detect_lattice`.

    ``kind`` is ``"lattice"`` (w1, w2 set), ``"stripes"`` (period and direction set) or
    ``"plain"`` (no print: plain cloth, whose only repeat is the weave). Vectors are in
    millimetres of the input image frame (x right, y down, scaled by ``mm_per_px``);
    ``*_px`` give the same in input pixels.
    Unavailable numbers are NaN so callers never branch on the shape of the answer.
    """

    kind: str
    w1: np.ndarray = field(default_factory=lambda: np.full(2, np.nan))
    w2: np.ndarray = field(default_factory=lambda: np.full(2, np.nan))
    sigma_w1: np.ndarray = field(default_factory=lambda: np.full(2, np.nan))
    sigma_w2: np.ndarray = field(default_factory=lambda: np.full(2, np.nan))
    mm_per_px: float = 1.0
    strength: float = 0.0
    n_peaks: int = 0
    period: float = float("nan")
    direction_deg: float = float("nan")
    message: str = ""

    @property
    def found(self) -> bool:
        return self.kind == "lattice"

    @property
    def basis(self) -> np.ndarray:
        """(2,2) columns w1, w2 in mm."""
        return np.column_stack([self.w1, self.w2])

    @property
    def basis_px(self) -> np.ndarray:
        return self.basis / self.mm_per_px

    def to_dict(self) -> dict:
        out = {"kind": self.kind, "strength": round(float(self.strength), 4),
               "message": self.message}
        if self.kind == "lattice":
            out.update(w1=self.w1.tolist(), w2=self.w2.tolist(),
                       sigma_w1=self.sigma_w1.tolist(), sigma_w2=self.sigma_w2.tolist(),
                       n_peaks=self.n_peaks)
        if self.kind == "stripes":
            out.update(period=self.period, direction_deg=self.direction_deg)
        return out


def _gray(image: np.ndarray) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim == 3:
        if img.shape[2] == 4:
            img = img[:, :, :3]
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.shape[2] == 3 else img[:, :, 0]
    if img.ndim != 2:
        raise ValueError(f"image must be 2-D gray or HxWx3 BGR, got shape {np.shape(image)}")
    return img


def to_gray_float(image: np.ndarray) -> np.ndarray:
    """BGR/gray uint8/float image -> float32 gray in [0, 1]-ish."""
    return _unit_float(_gray(image))


def _unit_float(img: np.ndarray) -> np.ndarray:
    """uint8/uint16/float pixels -> float32 in [0, 1]-ish."""
    if img.dtype == np.uint8:
        return img.astype(np.float32) / 255.0
    if img.dtype == np.uint16:
        return img.astype(np.float32) / 65535.0
    return img.astype(np.float32)


def prepare_image(image: np.ndarray, *, work_side: int = WORK_SIDE) -> tuple[np.ndarray, float]:
    """Gray, downscale to ``work_side`` and divide out smooth light (gain ramp, vignetting).

    Returns the zero-mean contrast image and the scale (working px per input px). The
    light is modelled as a low-order polynomial surface, fitted on block means, because
    a polynomial cannot follow the print itself whatever its period.
    """
    gray = _gray(image)
    if gray.shape[0] < 16 or gray.shape[1] < 16:
        raise ValueError(f"image is too small for lattice detection: {gray.shape}")
    if gray.dtype.kind == "f" and not np.isfinite(gray).all():
        raise ValueError("image contains NaN or infinite values; fill or crop them first")
    scale = min(1.0, work_side / max(gray.shape))
    if scale < 1.0:
        # Shrink first (uint8 is fastest), convert after: a 12 MP frame costs ~20 ms.
        size = (max(16, round(gray.shape[1] * scale)), max(16, round(gray.shape[0] * scale)))
        src = gray if gray.dtype in (np.uint8, np.uint16, np.float32) \
            else gray.astype(np.float32)
        gray = cv2.resize(src, size, interpolation=cv2.INTER_AREA)
        scale = gray.shape[1] / to_gray_shape(image)[1]
    gray = to_gray_float(gray)
    light = _light_surface(gray)
    flat = gray / np.maximum(light, 1e-3) - 1.0
    flat -= float(flat.mean())
    return flat.astype(np.float32), float(scale)


def prepare_colour(image: np.ndarray, shape: tuple[int, int]) -> np.ndarray | None:
    """The colour channels as :func:`prepare_image` makes the grey one (working size
    ``shape``, smooth light divided out, zero mean), stacked (3,H,W); None for a grey
    image. Lattice detection correlates all three: two inks of equal grey (a pink and a
    lilac) are one print in grey, and its lattice would be the finer one they share."""
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] < 3:
        return None
    img = img[:, :, :3]
    if img.dtype not in (np.uint8, np.uint16, np.float32):
        img = img.astype(np.float32)
    if img.shape[:2] != shape:
        img = cv2.resize(img, (shape[1], shape[0]), interpolation=cv2.INTER_AREA)
    chans = np.moveaxis(_unit_float(img), 2, 0)
    # The light (gain ramp, vignetting) is the same for every ink: one surface, fitted
    # on the channels' mean, divides all three.
    light = np.maximum(_light_surface(chans.mean(axis=0)), 1e-3)
    out = chans / light
    out /= np.maximum(out.mean(axis=(1, 2), keepdims=True), 1e-3)
    out -= 1.0
    return (out - out.mean(axis=(1, 2), keepdims=True)).astype(np.float32)


def to_gray_shape(image: np.ndarray) -> tuple[int, int]:
    return int(np.shape(image)[0]), int(np.shape(image)[1])


def _light_surface(gray: np.ndarray, degree: int = 3) -> np.ndarray:
    h, w = gray.shape
    bs = max(4, min(h, w) // 24)
    hb, wb = h // bs, w // bs
    blocks = gray[: hb * bs, : wb * bs].reshape(hb, bs, wb, bs).mean(axis=(1, 3))
    yc = (np.arange(hb) + 0.5) * bs / h * 2 - 1
    xc = (np.arange(wb) + 0.5) * bs / w * 2 - 1
    yy, xx = np.meshgrid(yc, xc, indexing="ij")
    terms = [(i, j) for i in range(degree + 1) for j in range(degree + 1 - i)]
    a = np.stack([xx.ravel() ** i * yy.ravel() ** j for i, j in terms], axis=1)
    coef, *_ = np.linalg.lstsq(a, blocks.ravel(), rcond=None)
    yf = (np.arange(h) + 0.5) / h * 2 - 1
    xf = (np.arange(w) + 0.5) / w * 2 - 1
    cm = np.zeros((degree + 1, degree + 1))
    for c, (i, j) in zip(coef, terms, strict=True):
        cm[j, i] = c
    # sum_ij c_ij y^j x^i as one product of Vandermonde matrices.
    surf = (np.vander(yf, degree + 1, increasing=True) @ cm
            @ np.vander(xf, degree + 1, increasing=True).T).astype(np.float32)
    return np.maximum(surf, np.float32(0.05 * max(float(blocks.mean()), 1e-3)))


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
    """Tukey window, its own autocorrelation (cropped, max 1) and the FFT size."""
    win = np.outer(_tukey(h), _tukey(w)).astype(np.float32)
    shape = (sfft.next_fast_len(2 * h, real=True), sfft.next_fast_len(2 * w, real=True))
    fw = sfft.rfft2(win, s=shape, workers=-1)
    wacf = _crop(sfft.irfft2(fw * np.conj(fw), s=shape, workers=-1), h, w)
    return win, (wacf / wacf.max()).astype(np.float32), shape


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


def _subpixel(img: np.ndarray, rc: np.ndarray) -> np.ndarray:
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


def _sample(img: np.ndarray, rc: np.ndarray) -> np.ndarray:
    return ndimage.map_coordinates(img, [rc[:, 0], rc[:, 1]], order=1, mode="constant",
                                   cval=0.0)


def _lattice_points(basis: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
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


def _peaks_near_centre(acf: np.ndarray, threshold: float) -> np.ndarray:
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


def _ridge_test(acf: np.ndarray, r_min: float) -> tuple[float, float, float]:
    """Stripe test on the autocorrelation: (direction deg, level, ripple).

    A 1-D print keeps the autocorrelation high along its stripes at every lag (level),
    and smooth there (ripple: residual after a quadratic trend, which absorbs the slow
    fall-off from perspective or folds). A 2-D print with a weak second direction has
    a high level too, but dips periodically between its repeats.
    """
    h2, w2 = acf.shape
    cy, cx = h2 // 2, w2 // 2
    rmax = 0.2 * min(h2, w2)
    t = np.linspace(max(r_min, 3.0), rmax, 64)
    ang = np.deg2rad(np.arange(0, 180, 0.5))
    xs = cx + np.cos(ang)[:, None] * t[None, :]
    ys = cy + np.sin(ang)[:, None] * t[None, :]
    vals = ndimage.map_coordinates(acf, [ys.ravel(), xs.ravel()], order=1).reshape(xs.shape)
    score = np.percentile(vals, 10, axis=1)
    k = int(np.argmax(score))
    tf = np.arange(max(r_min, 3.0), rmax, 0.5)
    prof = _radial_profile(acf, ang[k], tf)
    x = (tf - tf.mean()) / max(np.ptp(tf), 1e-9)
    fit = np.polyval(np.polyfit(x, prof, 2), x)
    ripple = float(np.ptp(prof - fit))
    return float(np.rad2deg(ang[k])), float(score[k]), ripple


def detect_lattice(
    image: np.ndarray,
    *,
    mm_per_px: float = 1.0,
    min_period_px: float = 6.0,
    min_strength: float = 0.35,
    min_repeat_mm: float = 3.0,
    stripe_threshold: float = 0.45,
    max_ripple: float = 0.04,
    work_side: int = WORK_SIDE,
    prepared: tuple[np.ndarray, float] | None = None,
    smooth_px: float = 1.0,
) -> LatticeResult:
    """Two shortest translation vectors of the print in ``image`` (a rectified photo).

    Parameters
    ----------
    image : (H,W) or (H,W,3) array
        Gray or BGR image whose pixels are square in table millimetres.
    mm_per_px : float
        Pixel size, to report vectors in millimetres.
    min_period_px : float
        Shortest repeat considered, in working-image pixels (finer texture is weave).
    min_strength : float
        Normalised autocorrelation a repeat must reach to count as a print (plain
        cloth's shading bands and yarn irregularity reach about 0.25, prints 0.6-1).
    min_repeat_mm : float
        Shortest repeat of a print in mm; a finer lattice or stripe is the weave, and
        the cloth is reported as plain.
    stripe_threshold : float
        Autocorrelation kept along one direction at all lags above which the print is
        1-D stripes, provided it does not dip periodically by more than ``max_ripple``.
    prepared : (flat, scale), optional
        :func:`prepare_image`'s answer for this image, to share it between steps.
    smooth_px : float
        Gaussian blur (working pixels) of the image before its autocorrelation: one
        pixel against noise; more to find the print above the yarn
        (:func:`yarn_repeat`).

    Returns
    -------
    LatticeResult
        ``kind`` "lattice" with reduced w1, w2 (|w1| <= |w2|, 90..120 degrees apart) and
        their standard errors, "stripes" with period (mm) and direction, or "plain".
    """
    if mm_per_px <= 0 or not np.isfinite(mm_per_px):
        raise ValueError(f"mm_per_px must be a positive number, got {mm_per_px}")
    flat, scale = prepared or prepare_image(image, work_side=work_side)
    acf, wacf = _print_autocorrelation(image, flat, scale, smooth_px)
    center = (np.array(acf.shape) // 2).astype(float)
    valid = wacf > 0.25
    px_mm = mm_per_px / scale  # mm per working pixel

    coords = _peaks_near_centre(np.where(valid, acf, -1.0), 0.5 * min_strength)
    d = _subpixel(acf, coords) - center if len(coords) else np.zeros((0, 2))
    vals = acf[coords[:, 0], coords[:, 1]] if len(coords) else np.zeros(0)
    lag = np.hypot(d[:, 0], d[:, 1])
    # The weave's own repeat: the strongest peak at a lag finer than any print.
    weave = (lag >= 2.0) & (lag < min_repeat_mm / px_mm)
    weave_peak = float(vals[weave].max()) if weave.any() else 0.0
    keep = lag >= min_period_px
    # One of each +-pair; 1e-3: a row-axis pair's rounding noise must not drop both.
    keep &= (d[:, 0] > 1e-3) | ((np.abs(d[:, 0]) <= 1e-3) & (d[:, 1] > 0))
    d, vals = d[keep], vals[keep]

    ridge_dir, ridge_score, ripple = _ridge_test(acf, min_period_px)
    if ridge_score >= stripe_threshold and ripple < max_ripple:
        return _weave_check(_stripes(acf, center, ridge_dir, px_mm, ridge_score,
                                     min_period_px, mm_per_px), min_repeat_mm)
    if len(vals) < 2 or vals.max() < min_strength:
        return LatticeResult("plain", mm_per_px=mm_per_px,
                             strength=float(vals.max()) if len(vals) else 0.0,
                             message="no periodic print: no repeat in the autocorrelation")

    # Choose among peaks with a well-overlapped lag only: near the edge of the valid
    # region the normalised autocorrelation rests on few pixels and runs high.
    core = wacf > 0.3
    rc = np.round(d + center).astype(int)
    inner = core[rc[:, 0], rc[:, 1]]
    if inner.sum() < 2:
        inner = np.ones(len(d), bool)
    basis, support = _choose_basis(acf, core, wacf >= VERIFY_OVERLAP, d[inner], vals[inner],
                                   min_strength)
    if basis is None:
        return LatticeResult("plain", mm_per_px=mm_per_px, strength=float(vals.max()),
                             message="no 2-D lattice explains the autocorrelation peaks")
    basis, sig, n_used = _refine(acf, valid, basis)
    b1, b2 = _right_handed(*gauss_reduce(basis[:, 0], basis[:, 1], obtuse=True)[:2])
    if weave_peak > support:
        # Cloth whose yarn repeats more strongly than the coarser lattice does over its
        # points: that "lattice" is a beat of the weave with the pixels (moire).
        return LatticeResult("plain", mm_per_px=mm_per_px, strength=weave_peak,
                             message=f"plain cloth: the weave (autocorrelation "
                                     f"{weave_peak:.2f}) repeats more strongly than any "
                                     f"print ({support:.2f})")
    # Map the (row, col) working-pixel vectors into (x, y) mm of the input image.
    w1 = b1[::-1] * px_mm
    w2 = b2[::-1] * px_mm
    # Uncertainty: the fit's standard errors follow the vectors through the reduction.
    s = float(np.hypot(*sig)) * px_mm
    return _weave_check(LatticeResult("lattice", w1=w1, w2=w2, sigma_w1=np.full(2, s),
                                      sigma_w2=np.full(2, s), mm_per_px=mm_per_px,
                                      strength=support, n_peaks=n_used), min_repeat_mm)


def yarn_repeat(flat: np.ndarray, px_mm: float, min_repeat_mm: float = 3.0) -> float:
    """Side (mm) of the yarn's repeat where the image shows the yarn as a 2-D lattice
    finer than any print (``min_repeat_mm``); NaN where it does not.

    A yarn-dyed check's colours sit on the threads that cross at each point, warp here
    and weft there in the weave's order, and a knit shows its stitches: at thread scale
    a woven gingham is not even p4m. Only the image's fine detail is searched (the
    print's shapes smoothed away at a sixth of the smallest print repeat), for two
    independent lags d1, d2 whose autocorrelation, and that at d1 + d2 and d1 - d2 (a
    lattice, not the ridges of a print's straight edges), reach ``YARN_SEEN``. The
    side is the longer of the two shortest such lags: a plain weave's two-thread
    diagonal, a twill's four-thread one.
    """
    reach = min_repeat_mm / px_mm
    fine = flat - cv2.GaussianBlur(flat, (0, 0), reach / 6.0)
    acf, _ = autocorrelation(fine)
    center = np.array(acf.shape) // 2
    r = int(min(reach, *(center - 2)))
    near = acf[center[0] - r:center[0] + r + 1, center[1] - r:center[1] + r + 1]
    coords = peak_local_max(near, min_distance=1, threshold_abs=YARN_SEEN,
                            exclude_border=1, num_peaks=60)
    d = (coords - r).astype(float)
    n = np.hypot(d[:, 0], d[:, 1])
    keep = (n >= 2.0) & (n < reach)
    d, n = d[keep], n[keep]
    if not len(n):
        return float("nan")
    d1 = d[np.argmin(n)]
    cross = np.abs(d[:, 0] * d1[1] - d[:, 1] * d1[0]) / np.maximum(n * n.min(), 1e-9)
    partners = np.flatnonzero(cross > 0.3)
    # only the shortest partners: a far one closing by chance (a moire of yarn finer than
    # the pixels) would smooth the print away with it
    partners = partners[n[partners] <= 1.5 * n[partners].min()] if len(partners) else partners
    for j in sorted(partners, key=lambda k: n[k]):
        ends = np.round(center + np.stack([d1 + d[j], d1 - d[j]])).astype(int)
        if (ends >= 0).all() and (ends < acf.shape).all() and \
                acf[ends[:, 0], ends[:, 1]].min() >= YARN_SEEN:
            return float(n[j]) * px_mm
    return float("nan")  # the shortest lag has no partner: no 2-D yarn lattice


def _same_view_colour(image: np.ndarray, flat: np.ndarray,
                      scale: float) -> np.ndarray | None:
    """The colour channels of ``image`` when ``flat`` is its grey working image (not a
    rectified or cropped view of it, whose colour the caller does not hand over)."""
    shape = np.array(to_gray_shape(image), float) * scale
    if np.ndim(image) != 3 or np.abs(shape - flat.shape).max() > 1.5:
        return None
    return prepare_colour(image, flat.shape)


def _right_handed(b1: np.ndarray, b2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The reduced basis (row, col) turned right-handed in (x, y) where the reduction
    leaves the choice to noise: at a right angle ``-b2`` is as reduced as ``b2``."""
    det = b1[1] * b2[0] - b1[0] * b2[1]  # x1 y2 - y1 x2
    if det < 0 and abs(float(b1 @ b2)) <= 0.02 * float(np.hypot(*b1) * np.hypot(*b2)):
        return b1, -b2
    return b1, b2


def _weave_check(res: LatticeResult, min_repeat_mm: float) -> LatticeResult:
    """Plain cloth when the repeat found is finer than any print: the weave or yarn."""
    repeat = res.period if res.kind == "stripes" else float(np.hypot(*res.w1))
    if res.kind not in ("lattice", "stripes") or not repeat < min_repeat_mm:
        return res
    return LatticeResult("plain", mm_per_px=res.mm_per_px, strength=res.strength,
                         message=f"plain cloth: its repeat of {repeat:.3g} mm is the weave "
                                 f"(finer than the {min_repeat_mm:g} mm a print needs)")


def _support(smooth, center, basis, radius):
    _, pts = _lattice_points(basis, radius)
    samp = ndimage.map_coordinates(smooth, [pts[:, 0] + center[0], pts[:, 1] + center[1]],
                                   order=1, cval=np.nan)
    samp = samp[np.isfinite(samp)]
    if len(samp) < 2:
        return -1.0
    # Mean of the lower half: every point of a true lattice is a repeat, while a
    # spurious denser lattice has empty lags among its points.
    return float(np.mean(np.sort(samp)[: max(2, len(samp) // 2)]))


#: Index of the nested lattices tried around the best-supported one: a partial symmetry
#: taken for a repeat, or a fundamental repeat lost in blur, differs from the true
#: lattice by index 2, 3 or 4 (half, third and quarter cells, and their products).
NEST_INDEX = (2, 3, 4)

#: Evidence (:func:`_coset_evidence`) at which a refinement's added lags count as
#: repeats. Calibrated on small blurred prints (seeds 11 and 23 of ``bench.vision``'s
#: ``blurred``, apart from the benchmark's seed 0): 0.85 takes glides' half shifts,
#: 0.95 misses fundamentals that wrinkles lowered.
REFINE_AT = 0.9

#: Evidence below which half of the chosen lattice's lags (an index-2 coset) is no
#: repeat. True lattices of small blurred prints keep 0.81 or more at 99 % (seeds 11
#: and 23); a glide's half shift that blur made look like a repeat scores 0.65.
COARSEN_BELOW = 0.7

#: Fewest lags on each side of an evidence comparison.
MIN_EVIDENCE = 2

#: Lags over which a lattice's support is measured, in its longest basis vector: its
#: shortest repeats (near: w1, w2 and the short diagonal), which blur, wrinkles and
#: perspective lower least and which rank the candidates, and several shells (far).
NEAR_REACH = 1.3
FAR_REACH = 2.6

#: Near support that makes a lattice a print even when its far lags decorrelate (a
#: wrinkled or tilted print); otherwise the far support must reach ``min_strength``.
#: Tilted frames' false fine lattices (partial repeats of motifs) reach 0.53; small
#: blurred prints' true lattices 0.55 and more (seeds 11 and 23, ``blurred``).
NEAR_STRENGTH = 0.55

#: Near supports this close count as equal (then the denser lattice is taken).
TIE = 0.02

#: Window overlap (its own autocorrelation) at the lags where a lattice is verified.
VERIFY_OVERLAP = 0.45


@cache
def _index_matrices(k: int) -> tuple[np.ndarray, ...]:
    """Integer matrices M (Hermite normal form) with det k: ``B M`` runs over every
    sub-lattice of index k of the lattice with basis B, ``B M^-T`` (not ``B M^-1``,
    which misses the centred one) over every lattice that holds it with index k."""
    return tuple(np.array([[a, b], [0, k // a]], float) for a in range(1, k + 1)
                 if k % a == 0 for b in range(a))


def _canonical(basis: np.ndarray) -> np.ndarray:
    r1, r2, _ = gauss_reduce(basis[:, 0], basis[:, 1], obtuse=True)
    if r1[0] < 0 or (r1[0] == 0 and r1[1] < 0):
        r1, r2 = -r1, -r2
    return np.column_stack([r1, r2])


def _key(basis: np.ndarray) -> tuple:
    return tuple(np.round(basis.T.ravel() / 1.5).astype(int))


def _verifiable(reliable: np.ndarray, center: np.ndarray, basis: np.ndarray) -> bool:
    """Whether the lattice's three shortest repeats (w1, w2 and the short diagonal of a
    reduced basis) lie at lags the window overlaps well (``reliable``): a lattice seen
    only at long lags, where the normalised autocorrelation rests on few pixels and
    runs high by chance, cannot be told from a multiple of the true one."""
    pts = np.round(np.stack([basis[:, 0], basis[:, 1], basis[:, 0] + basis[:, 1]])
                   + center).astype(int)
    inside = ((pts >= 0) & (pts < reliable.shape)).all(axis=1)
    return bool(inside.all() and reliable[pts[:, 0], pts[:, 1]].all())


def _coset_evidence(smooth: np.ndarray, center: np.ndarray, fine: np.ndarray,
                    coarse: np.ndarray) -> float:
    """How well the lags of ``fine`` that ``coarse`` (a sub-lattice of it) lacks repeat
    the print: their mean autocorrelation over what the coarse lattice's own points
    carry at the same lags. The autocorrelation falls with lag under blur and wrinkles,
    so the reference is a straight-line fit (never rising) of value against lag over the
    coarse points in the same disc; a true repeat scores about 1, a partial symmetry (a
    glide's half shift, a near-mirror) clearly less."""
    radius = max(2.6 * np.linalg.norm(fine, axis=0).max(),
                 2.2 * np.linalg.norm(coarse, axis=0).max())
    _, pts = _lattice_points(fine, radius)
    vals = ndimage.map_coordinates(smooth, (pts + center).T, order=1, cval=np.nan)
    frac = pts @ np.linalg.inv(coarse).T
    on_coarse = np.abs(frac - np.round(frac)).max(axis=1) < 0.1
    lag = np.hypot(pts[:, 0], pts[:, 1])
    ok = np.isfinite(vals)
    ref_v, ref_l = vals[ok & on_coarse], lag[ok & on_coarse]
    new_v, new_l = vals[ok & ~on_coarse], lag[ok & ~on_coarse]
    if min(len(ref_v), len(new_v)) < MIN_EVIDENCE:
        return float("nan")  # too few well-overlapped lags to weigh
    slope = 0.0
    if len(ref_v) >= 3 and np.ptp(ref_l) > 1e-6:
        slope = min(0.0, float(np.polyfit(ref_l, ref_v, 1)[0]))
    expect = float(np.mean(ref_v)) + slope * (float(np.mean(new_l)) - float(np.mean(ref_l)))
    return float(np.mean(new_v)) / max(expect, 1e-6)


def _choose_basis(acf, valid, reliable, d, vals, min_strength):
    """Densest lattice whose points all carry strong autocorrelation.

    Candidates are pairs of peaks; one whose shortest repeats lie at poorly overlapped
    lags gives way to a checkable one that refines it. The one with the best near
    support (its shortest repeats) wins, and is tested against its nested lattices: a
    refinement (its candidates from the peaks, and every lattice holding it with index
    2-4) is taken when the lags it adds repeat
    the print nearly as well as its own lags do at the same lag (``REFINE_AT``: the
    winner was a multiple whose fundamental peaks blur and wrinkles lowered), and never
    when they do clearly less (a partial symmetry, such as a glide's half shift under
    blur, is no repeat).
    """
    smooth = ndimage.maximum_filter(acf, size=3)
    smooth = np.where(valid, smooth, np.nan)
    center = np.array([acf.shape[0] // 2, acf.shape[1] // 2], float)
    vmax = float(vals.max())
    strong = np.flatnonzero(vals >= 0.45 * vmax)
    # Candidates: the shortest strong peaks (a fine print) and the tallest ones (the
    # true repeats when side lobes of the motif crowd the short lags).
    length = np.hypot(d[:, 0], d[:, 1])
    short = strong[np.argsort(length[strong])[:12]]
    top = np.flatnonzero(vals >= 0.85 * vmax)
    short_top = top[np.argsort(length[top])[:12]]
    cand = d[np.unique(np.concatenate([short, short_top]))]
    bases: dict = {}
    for a in range(len(cand)):
        for b in range(a + 1, len(cand)):
            u, v = cand[a], cand[b]
            cross = abs(u[0] * v[1] - u[1] * v[0])
            if cross < 0.2 * np.hypot(*u) * np.hypot(*v):
                continue
            basis = _canonical(np.column_stack([u, v]))
            bases.setdefault(_key(basis), basis)
    # Lattices whose shortest repeats can be checked, when there are any (a print of
    # fewer than three repeats across offers none: then its lattice is taken as seen,
    # on strong near support only: its far shells lie where the window hardly overlaps,
    # and plain cloth's shading bands reach min_strength there).
    checkable = {k: b for k, b in bases.items() if _verifiable(reliable, center, b)}
    bases = checkable or bases
    if not bases:
        return None, 0.0
    scored = [tuple(_support(smooth, center, basis, reach * np.linalg.norm(basis, axis=0).max())
                    for reach in (NEAR_REACH, FAR_REACH)) for basis in bases.values()]
    eligible = [i for i, (near, far) in enumerate(scored)
                if near >= NEAR_STRENGTH or (checkable and far >= min_strength)]
    if not eligible:
        return None, max(far for _, far in scored)
    # The best near support wins; one within ``TIE`` of it and denser is preferred (a
    # multiple shares the true lattice's strongest lags and can tie with it).
    top = max(scored[i][0] for i in eligible)
    current = min((list(bases.values())[i] for i in eligible if scored[i][0] >= top - TIE),
                  key=lambda b: abs(np.linalg.det(b)))
    seen = {_key(current)}
    for _ in range(6):
        area = abs(np.linalg.det(current))
        finer = [_canonical(current @ np.linalg.inv(m.T)) for k in NEST_INDEX
                 for m in _index_matrices(k)]
        finer += [b for b in bases.values() if abs(np.linalg.det(b)) < area - 0.5
                  and nested(b, current)]
        finer = [b for b in finer if _key(b) not in seen and _on_peaks(b, d)
                 and _verifiable(reliable, center, b)]
        ev = [_coset_evidence(smooth, center, b, current) for b in finer]
        # The best-evidenced refinement first, one step at a time: a refinement of high
        # index mixes true added lags with spurious ones and averages them.
        ok = [(e, -abs(np.linalg.det(b)), i) for i, (b, e) in enumerate(zip(finer, ev,
                                                                           strict=True))
              if e >= REFINE_AT]
        if not ok:
            break
        current = finer[max(ok)[2]]
        seen.add(_key(current))
    # Half of the lattice's lags clearly weaker than the other half at the same lag: a
    # partial symmetry (a glide's half shift) taken for a repeat; the half that holds.
    coarser = [_canonical(current @ m) for m in _index_matrices(2)]
    coarser = [b for b in coarser if _verifiable(reliable, center, b)]
    ev = [_coset_evidence(smooth, center, current, b) for b in coarser]
    if ev and np.nanmin(ev, initial=np.inf) < COARSEN_BELOW:
        current = coarser[int(np.nanargmin(ev))]
    return current, _support(smooth, center, current,
                             FAR_REACH * np.linalg.norm(current, axis=0).max())


def _on_peaks(basis: np.ndarray, peaks: np.ndarray) -> bool:
    """Whether both basis vectors are autocorrelation peaks (up to sign): a repeat of
    the print is one, a lag inside the blurred central peak or between peaks is not."""
    tol = np.maximum(1.5, 0.05 * np.linalg.norm(basis, axis=0))
    dist = np.minimum(np.linalg.norm(peaks[:, None, :] - basis.T[None], axis=2),
                      np.linalg.norm(peaks[:, None, :] + basis.T[None], axis=2))
    return bool((dist.min(axis=0) <= tol).all())


def nested(fine: np.ndarray, coarse: np.ndarray) -> bool:
    """Whether every point of lattice ``coarse`` is a point of ``fine``."""
    m = np.linalg.solve(fine, coarse)
    return bool(np.abs(m - np.round(m)).max() < 0.1)


def _print_autocorrelation(image: np.ndarray, flat: np.ndarray, scale: float,
                           smooth_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Autocorrelation (and its overlap weight) of the working image ``flat``, over its
    colour channels where ``image`` is the same view in colour, smoothed ``smooth_px``."""
    colour = _same_view_colour(image, flat, scale)
    chans = flat[None] if colour is None else colour
    chans = np.stack([cv2.GaussianBlur(c, (0, 0), max(1.0, smooth_px)) for c in chans])
    return autocorrelation(chans)


def sublattice(lat: LatticeResult, index: np.ndarray, image: np.ndarray, *,
               prepared: tuple[np.ndarray, float], smooth_px: float = 1.0,
               message: str = "") -> LatticeResult:
    """The sublattice of ``lat`` with basis ``lat.basis @ index`` (an integer matrix),
    reduced and refined on the autocorrelation peaks of its own points only: a lattice
    read too fine is fitted to peaks that are not all repeats."""
    flat, scale = prepared
    acf, wacf = _print_autocorrelation(image, flat, scale, smooth_px)
    px_mm = lat.mm_per_px / scale
    coarse = lat.basis @ np.asarray(index, float)  # (x, y) mm
    basis, sig, n_used = _refine(acf, wacf > 0.25, coarse[::-1] / px_mm)
    b1, b2 = _right_handed(*gauss_reduce(basis[:, 0], basis[:, 1], obtuse=True)[:2])
    s = float(np.hypot(*sig)) * px_mm
    return LatticeResult("lattice", w1=b1[::-1] * px_mm, w2=b2[::-1] * px_mm,
                         sigma_w1=np.full(2, s), sigma_w2=np.full(2, s),
                         mm_per_px=lat.mm_per_px, strength=lat.strength,
                         n_peaks=n_used, message=message)


def _refine(acf, valid, basis, rounds: int = 3):
    """Weighted least squares on many sub-pixel peaks p = i w1 + j w2."""
    h2, w2 = acf.shape
    center = np.array([h2 // 2, w2 // 2], float)
    sig = np.full(2, np.nan)
    n_used = 0
    radius_full = 0.75 * min(h2, w2)
    for it in range(rounds):
        radius = radius_full if it else min(radius_full, 4.5 * np.abs(basis).sum(0).max())
        n, pts = _lattice_points(basis, radius)
        rc = pts + center
        inside = (rc[:, 0] > 3) & (rc[:, 0] < h2 - 4) & (rc[:, 1] > 3) & (rc[:, 1] < w2 - 4)
        n, rc = n[inside], rc[inside]
        ir = np.round(rc).astype(int)
        ok = valid[ir[:, 0], ir[:, 1]]
        n, rc, ir = n[ok], rc[ok], ir[ok]
        if len(n) < 2:
            break
        # Snap to the local maximum within a small window, then sub-pixel refine.
        win = max(2, int(0.15 * min(np.hypot(*basis[:, 0]), np.hypot(*basis[:, 1]))))
        win = min(win, 6)
        offs = np.arange(-win, win + 1)
        dy, dx = np.meshgrid(offs, offs, indexing="ij")
        rr = np.clip(ir[:, 0, None] + dy.ravel()[None], 1, h2 - 2)
        cc = np.clip(ir[:, 1, None] + dx.ravel()[None], 1, w2 - 2)
        vals = acf[rr, cc]
        k = np.argmax(vals, axis=1)
        peak = np.stack([rr[np.arange(len(k)), k], cc[np.arange(len(k)), k]], axis=1)
        pv = vals[np.arange(len(k)), k]
        good = pv > 0.3 * max(float(pv.max()), 1e-6)
        sub = _subpixel(acf, peak)
        pos = sub - center
        wgt = np.clip(pv, 0, None) * good
        if wgt.sum() <= 0 or good.sum() < 2:
            break
        sw = np.sqrt(wgt)[:, None]
        sol, *_ = np.linalg.lstsq(n * sw, pos * sw, rcond=None)
        res = pos - n @ sol
        r = np.hypot(res[:, 0], res[:, 1])
        thr = max(3 * np.median(r[good]) * 1.4826, 0.5)
        good2 = good & (r < thr)
        if good2.sum() >= 2:
            wgt = np.clip(pv, 0, None) * good2
            sw = np.sqrt(wgt)[:, None]
            sol, *_ = np.linalg.lstsq(n * sw, pos * sw, rcond=None)
            res = pos - n @ sol
        if (good2.sum() < 3 or np.linalg.matrix_rank(n[good2]) < 2
                or np.abs(sol.T - basis).max() > 0.25 * np.linalg.norm(basis, axis=0).min()):
            break  # too few peaks to refine on: keep the peak-pair estimate
        basis = sol.T
        m = int(good2.sum())
        dof = max(m - 2, 1)
        s2 = float((wgt[:, None] * res**2).sum() / max(wgt.sum(), 1e-12)) * m / dof
        ntn = (n * wgt[:, None]).T @ n / max(wgt.mean(), 1e-12)
        try:
            cov = np.linalg.inv(ntn) * s2
            sig = np.sqrt(np.clip(np.diag(cov), 0, None))
        except np.linalg.LinAlgError:
            sig = np.full(2, np.nan)
        n_used = m
    return basis, sig, n_used


def _radial_profile(acf: np.ndarray, angle: float, lags: np.ndarray) -> np.ndarray:
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


def _stripes(acf, center, ridge_dir, px_mm, score, min_period_px, mm_per_px) -> LatticeResult:
    """Period along the stripes' normal from the autocorrelation profile."""
    ang = np.deg2rad(ridge_dir + 90.0)
    h2, w2 = acf.shape
    rmax = 0.4 * min(h2, w2)
    t = np.arange(0, rmax, 0.25)
    prof = _radial_profile(acf, ang, t)
    start = int(min_period_px / 0.25)
    pk = np.flatnonzero((prof[1:-1] > prof[:-2]) & (prof[1:-1] >= prof[2:])) + 1
    pk = pk[pk >= start]
    if len(pk) == 0:
        return LatticeResult("plain", strength=score, mm_per_px=mm_per_px,
                             message="1-D texture without a measurable period")
    # Use the best-aligned multiple of the first strong peak for precision.
    first = pk[np.argmax(prof[pk] > 0.5 * prof[pk].max())]
    p1 = t[first]
    mult = np.round(t[pk] / p1)
    ok = (mult >= 1) & (np.abs(t[pk] / p1 - mult) < 0.15)
    period = float(np.sum(t[pk][ok] * mult[ok]) / np.sum(mult[ok] ** 2)) if ok.any() else p1
    direction = float(ridge_dir % 180.0)
    return LatticeResult("stripes", strength=score, mm_per_px=mm_per_px,
                         period=period * px_mm, direction_deg=direction,
                         message=f"1-D stripes (a frieze, not a lattice): period "
                                 f"{period * px_mm:.3f} mm, running at {direction:.1f} deg")
