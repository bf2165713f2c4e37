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
The steps live in :mod:`vision.prepare` (the working image),
:mod:`vision.autocorrelation` (its peaks) and :mod:`vision.basis` (choosing and fitting
the basis); this module reads them in order and tells lattice, stripes and plain apart.

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

import cv2
import numpy as np
from scipy import ndimage
from skimage.feature import peak_local_max

from solver.wallpaper import gauss_reduce
from vision.autocorrelation import (
    autocorrelation,
    peaks_near_centre,
    print_autocorrelation,
    radial_profile,
    subpixel,
)
from vision.basis import VERIFY_OVERLAP, choose_basis, nested, refine_basis, right_handed
from vision.prepare import WORK_SIDE, prepare_colour, prepare_image

__all__ = ["LatticeResult", "detect_lattice", "nested", "prepare_colour", "prepare_image",
           "sublattice", "yarn_repeat"]

#: Autocorrelation of the image's fine detail at which a 2-D repeat finer than any
#: print counts as the yarn showing (a weave's interlacing, a knit's stitches).
YARN_SEEN = 0.3


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
    prof = radial_profile(acf, ang[k], tf)
    x = (tf - tf.mean()) / max(np.ptp(tf), 1e-9)
    fit = np.polyval(np.polyfit(x, prof, 2), x)
    ripple = float(np.ptp(prof - fit))
    return float(np.rad2deg(ang[k])), float(score[k]), ripple


def detect_lattice(image: np.ndarray, *, mm_per_px: float = 1.0, min_period_px: float = 6.0,
                   min_strength: float = 0.35, min_repeat_mm: float = 3.0,
                   stripe_threshold: float = 0.45, max_ripple: float = 0.04,
                   work_side: int = WORK_SIDE, prepared: tuple[np.ndarray, float] | None = None,
                   smooth_px: float = 1.0) -> LatticeResult:
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
    acf, wacf = print_autocorrelation(image, flat, scale, smooth_px)
    center = (np.array(acf.shape) // 2).astype(float)
    px_mm = mm_per_px / scale  # mm per working pixel
    d, vals, weave_peak = _repeat_peaks(acf, wacf > 0.25, center, min_strength,
                                        min_period_px, min_repeat_mm / px_mm)
    ridge_dir, ridge_score, ripple = _ridge_test(acf, min_period_px)
    if ridge_score >= stripe_threshold and ripple < max_ripple:
        return _weave_check(_stripes(acf, center, ridge_dir, px_mm, ridge_score,
                                     min_period_px, mm_per_px), min_repeat_mm)
    if len(vals) < 2 or vals.max() < min_strength:
        return LatticeResult("plain", mm_per_px=mm_per_px,
                             strength=float(vals.max()) if len(vals) else 0.0,
                             message="no periodic print: no repeat in the autocorrelation")
    core = wacf > 0.3
    inner = _well_overlapped(d, center, core)
    basis, support = choose_basis(acf, core, wacf >= VERIFY_OVERLAP, d[inner], vals[inner],
                                  min_strength)
    if basis is None:
        return LatticeResult("plain", mm_per_px=mm_per_px, strength=float(vals.max()),
                             message="no 2-D lattice explains the autocorrelation peaks")
    if weave_peak > support:
        # Cloth whose yarn repeats more strongly than the coarser lattice does over its
        # points: that "lattice" is a beat of the weave with the pixels (moire).
        return LatticeResult("plain", mm_per_px=mm_per_px, strength=weave_peak,
                             message=f"plain cloth: the weave (autocorrelation "
                                     f"{weave_peak:.2f}) repeats more strongly than any "
                                     f"print ({support:.2f})")
    return _weave_check(_fitted(acf, wacf > 0.25, basis, px_mm, mm_per_px, support),
                        min_repeat_mm)


def _repeat_peaks(acf: np.ndarray, valid: np.ndarray, center: np.ndarray, min_strength: float,
                  min_period_px: float, weave_px: float
                  ) -> tuple[np.ndarray, np.ndarray, float]:
    """The autocorrelation's peaks at lags of at least ``min_period_px`` (one of each
    +- pair): their lags (row, col) and heights; with the strongest peak at a lag finer
    than any print (``weave_px``), the weave's own repeat, or 0."""
    coords = peaks_near_centre(np.where(valid, acf, -1.0), 0.5 * min_strength)
    d = subpixel(acf, coords) - center if len(coords) else np.zeros((0, 2))
    vals = acf[coords[:, 0], coords[:, 1]] if len(coords) else np.zeros(0)
    lag = np.hypot(d[:, 0], d[:, 1])
    weave = (lag >= 2.0) & (lag < weave_px)
    weave_peak = float(vals[weave].max()) if weave.any() else 0.0
    keep = lag >= min_period_px
    # One of each +-pair; 1e-3: a row-axis pair's rounding noise must not drop both.
    keep &= (d[:, 0] > 1e-3) | ((np.abs(d[:, 0]) <= 1e-3) & (d[:, 1] > 0))
    return d[keep], vals[keep], weave_peak


def _well_overlapped(d: np.ndarray, center: np.ndarray, core: np.ndarray) -> np.ndarray:
    """Which peaks lie at a well-overlapped lag (``core``), to choose among: near the
    edge of the valid region the normalised autocorrelation rests on few pixels and runs
    high. All of them where fewer than two do."""
    rc = np.round(d + center).astype(int)
    inner = core[rc[:, 0], rc[:, 1]]
    return inner if inner.sum() >= 2 else np.ones(len(d), bool)


def _fitted(acf: np.ndarray, valid: np.ndarray, basis: np.ndarray, px_mm: float,
            mm_per_px: float, strength: float, message: str = "") -> LatticeResult:
    """The lattice of ``basis`` ((row, col) working px) fitted on the autocorrelation's
    peaks (:func:`vision.basis.refine_basis`), reduced, in (x, y) mm of the input image;
    the fit's standard errors follow the vectors through the reduction."""
    basis, sig, n_used = refine_basis(acf, valid, basis)
    b1, b2 = right_handed(*gauss_reduce(basis[:, 0], basis[:, 1], obtuse=True)[:2])
    s = float(np.hypot(*sig)) * px_mm
    return LatticeResult("lattice", w1=b1[::-1] * px_mm, w2=b2[::-1] * px_mm,
                         sigma_w1=np.full(2, s), sigma_w2=np.full(2, s), mm_per_px=mm_per_px,
                         strength=strength, n_peaks=n_used, message=message)


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


def _weave_check(res: LatticeResult, min_repeat_mm: float) -> LatticeResult:
    """Plain cloth when the repeat found is finer than any print: the weave or yarn."""
    repeat = res.period if res.kind == "stripes" else float(np.hypot(*res.w1))
    if res.kind not in ("lattice", "stripes") or not repeat < min_repeat_mm:
        return res
    return LatticeResult("plain", mm_per_px=res.mm_per_px, strength=res.strength,
                         message=f"plain cloth: its repeat of {repeat:.3g} mm is the weave "
                                 f"(finer than the {min_repeat_mm:g} mm a print needs)")


def sublattice(lat: LatticeResult, index: np.ndarray, image: np.ndarray, *,
               prepared: tuple[np.ndarray, float], smooth_px: float = 1.0,
               message: str = "") -> LatticeResult:
    """The sublattice of ``lat`` with basis ``lat.basis @ index`` (an integer matrix),
    reduced and refined on the autocorrelation peaks of its own points only: a lattice
    read too fine is fitted to peaks that are not all repeats."""
    flat, scale = prepared
    acf, wacf = print_autocorrelation(image, flat, scale, smooth_px)
    px_mm = lat.mm_per_px / scale
    coarse = lat.basis @ np.asarray(index, float)  # (x, y) mm
    return _fitted(acf, wacf > 0.25, coarse[::-1] / px_mm, px_mm, lat.mm_per_px, lat.strength,
                   message)


def _stripes(acf, center, ridge_dir, px_mm, score, min_period_px, mm_per_px) -> LatticeResult:
    """Period along the stripes' normal from the autocorrelation profile."""
    ang = np.deg2rad(ridge_dir + 90.0)
    h2, w2 = acf.shape
    rmax = 0.4 * min(h2, w2)
    t = np.arange(0, rmax, 0.25)
    prof = radial_profile(acf, ang, t)
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
