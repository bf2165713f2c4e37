"""Where the print really lies under a piece: local maps of a distorted print.

A real roll's print bows, skews and stretches along and across the roll, so the ideal
lattice the marker was planned on drifts off the print by millimetres over a metre. The
station knows where it expects each point of the planned print to lie in the window (the
marker carried by the roll's measured motion); this module measures where it really is.

`PrintReference` folds the planning photograph into one mean cell of the detected
lattice: the ideal print, free of the photograph's own bow, that can be drawn anywhere.
`local_shifts` compares square tiles of a window photograph with the ideal print drawn
where the station expects it, all tiles at once by phase correlation [1]_ (one batched
FFT): each tile gives the shift of the real print from the expected one, taken modulo
the lattice nearest to zero (the drift is millimetres, a repeat tens of millimetres).
`fit_local_map` fits an affine map to the shifts over a piece, and says how far the
print departs from any affine map there (what the piece's seams will be off by).
`nearest_rigid` is the rotation and translation that best follow such a map over a
piece's seam points: a piece that must keep its shape (its seams their lengths) is
placed by it, and the map's residual there is what its seams will be off by.

References
----------
.. [1] C. D. Kuglin, D. C. Hines, "The phase correlation image alignment method",
       Proc. IEEE Conf. Cybernetics and Society, 1975.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from vision.prepare import to_gray_float

TILE_PX = 128  # a tile holds at least one repeat of an 80 mm print at 1 mm per pixel
MIN_CELL_SAMPLES, MAX_CELL_SAMPLES = 24, 256
OUTLIER_MM = 2.0  # a tile further than this from the piece's affine fit is left out
REMAP_CHUNK = 32000  # points per OpenCV remap call (its maps' limit is 32767 rows)
WHITEN_FLOOR = 1.0  # of the mean cross-power: frequencies the print lacks stay quiet


@dataclass(frozen=True)
class PrintReference:
    """The ideal print as planned: ``cell`` (m, m) float32 grey, the mean of the planning
    photograph over every cell of the lattice ``basis`` ((2, 2) columns, mm) with its
    origin at ``origin`` (mm), sampled at fractional coordinates ``(c / m, r / m)``
    (column along ``basis[:, 0]``). Coordinates are the marker's mm."""

    cell: np.ndarray
    basis: np.ndarray
    origin: np.ndarray

    @classmethod
    def from_photo(cls, photo: np.ndarray, basis: np.ndarray, origin, *,
                   mm_per_px: float = 1.0) -> PrintReference:
        """The mean cell of ``photo`` (rectified to marker mm, pixel (c, r) at ``(c, r) *
        mm_per_px``). Raises ValueError when the photograph holds under 4 cells."""
        grey = to_gray_float(photo).astype(np.float64)
        basis = np.asarray(basis, float).reshape(2, 2)
        h, w = grey.shape
        cell_area = abs(np.linalg.det(basis))
        if not cell_area > 0 or h * w * mm_per_px**2 < 4 * cell_area:
            raise ValueError(f"a {w}x{h} px photograph holds fewer than 4 cells of the "
                             f"print (cell {cell_area:.0f} mm^2)")
        longest = float(np.hypot(*basis).max()) / mm_per_px
        m = int(np.clip(math.ceil(longest), MIN_CELL_SAMPLES, MAX_CELL_SAMPLES))
        ys, xs = np.mgrid[0:h, 0:w] * mm_per_px
        frac = np.linalg.solve(basis, np.stack([xs.ravel() - origin[0],
                                                ys.ravel() - origin[1]]))
        bins = np.rint((frac - np.floor(frac)) * m).astype(np.int64) % m
        index = bins[1] * m + bins[0]
        counts = np.bincount(index, minlength=m * m)
        sums = np.bincount(index, weights=grey.ravel(), minlength=m * m)
        cell = np.where(counts > 0, sums / np.maximum(counts, 1), grey.mean())
        return cls(cell.reshape(m, m).astype(np.float32), basis,
                   np.asarray(origin, float).reshape(2))

    def render(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Grey values of the ideal print at marker points ``(x, y)`` (mm, any shape)."""
        inv = np.linalg.inv(self.basis)
        dx, dy = np.ravel(x) - self.origin[0], np.ravel(y) - self.origin[1]
        m = self.cell.shape[0]
        u = (((inv[0, 0] * dx + inv[0, 1] * dy) % 1.0) * m).astype(np.float32)
        v = (((inv[1, 0] * dx + inv[1, 1] * dy) % 1.0) * m).astype(np.float32)
        out = np.empty(u.shape, np.float32)
        for start in range(0, len(u), REMAP_CHUNK):  # OpenCV maps stay under 32767 rows
            part = slice(start, start + REMAP_CHUNK)
            out[part] = cv2.remap(self.cell, u[part, None], v[part, None], cv2.INTER_LINEAR,
                                  borderMode=cv2.BORDER_WRAP)[:, 0]
        return out.reshape(np.shape(x))


def tile_centres(box: np.ndarray, shape: tuple[int, int], *, mm_per_px: float = 1.0,
                 tile_px: int = TILE_PX) -> np.ndarray:
    """(n, 2) pixel centres of tiles covering ``box`` ((2, 2): min and max corner, mm)
    at half a tile's step, each tile inside a photograph of ``shape`` (rows, cols)."""
    h, w = shape
    half = tile_px // 2
    lo = np.clip(np.floor(box[0] / mm_per_px), half, [w - half, h - half])
    hi = np.clip(np.ceil(box[1] / mm_per_px), half, [w - half, h - half])
    steps = [np.unique(np.linspace(a, b, max(2, math.ceil((b - a) / half) + 1)).round())
             for a, b in zip(lo, hi)]
    cx, cy = np.meshgrid(*steps)
    return np.column_stack([cx.ravel(), cy.ravel()]).astype(int)


def local_shifts(photo: np.ndarray, reference: PrintReference, window_to_marker: np.ndarray,
                 centres: np.ndarray, *, mm_per_px: float = 1.0, tile_px: int = TILE_PX
                 ) -> np.ndarray:
    """(n, 2) mm: at each tile centre (pixels, (n, 2)), how far the real print in
    ``photo`` lies from the ideal print drawn where the marker map ``window_to_marker``
    ((2, 3), window mm -> marker mm) expects it, reduced modulo the lattice to the
    shortest shift. The print expected at window point p is seen at p + shift."""
    grey = to_gray_float(photo).astype(np.float32)
    centres = np.asarray(centres, int).reshape(-1, 2)
    offs = np.arange(tile_px) - tile_px // 2
    rows = centres[:, 1, None, None] + offs[None, :, None]
    cols = centres[:, 0, None, None] + offs[None, None, :]
    seen = grey[rows, cols]
    wx = (cols * mm_per_px).astype(np.float64) + np.zeros_like(rows)
    wy = (rows * mm_per_px).astype(np.float64) + np.zeros_like(cols)
    a = np.asarray(window_to_marker, float)
    mx = a[0, 0] * wx + a[0, 1] * wy + a[0, 2]
    my = a[1, 0] * wx + a[1, 1] * wy + a[1, 2]
    expected = reference.render(mx, my)
    shift_px = _phase_correlate(seen, expected)
    lattice = np.linalg.inv(a[:, :2]) @ reference.basis  # the print's repeat in the window
    shift = shift_px * mm_per_px
    return shift - (lattice @ np.round(np.linalg.solve(lattice, shift.T))).T


def _phase_correlate(seen: np.ndarray, expected: np.ndarray) -> np.ndarray:
    """(n, 2) sub-pixel (x, y) shifts s with seen(p) ~ expected(p - s), for stacks of
    (n, t, t) tiles: normalised cross-power spectrum, peak refined by a parabola."""
    t = seen.shape[-1]
    hann = np.outer(np.hanning(t), np.hanning(t)).astype(np.float32)
    prep = [(s - s.mean(axis=(1, 2), keepdims=True)) * hann for s in (seen, expected)]
    cross = np.fft.rfft2(prep[0]) * np.conj(np.fft.rfft2(prep[1]))
    mag = np.abs(cross)
    floor = WHITEN_FLOOR * mag.mean(axis=(1, 2), keepdims=True) + 1e-12
    corr = np.fft.irfft2(cross / (mag + floor), s=(t, t))
    n = len(corr)
    peak = corr.reshape(n, -1).argmax(axis=1)
    py, px = np.divmod(peak, t)
    k = np.arange(n)

    def vertex(minus: np.ndarray, centre: np.ndarray, plus: np.ndarray) -> np.ndarray:
        den = minus - 2.0 * centre + plus
        return np.where(np.abs(den) > 1e-12, 0.5 * (minus - plus) / np.where(
            den == 0, 1.0, den), 0.0)

    c = corr[k, py, px]
    dx = vertex(corr[k, py, (px - 1) % t], c, corr[k, py, (px + 1) % t])
    dy = vertex(corr[k, (py - 1) % t, px], c, corr[k, (py + 1) % t, px])
    wrap = lambda p: (p + t // 2) % t - t // 2  # noqa: E731
    return np.column_stack([wrap(px) + dx, wrap(py) + dy])


@dataclass(frozen=True)
class LocalMap:
    """The print under one piece: ``correction`` (2, 3), window mm -> window mm, carries
    the point where the station expected the print onto where it lies (an affine map);
    ``beyond_mm`` is how far the measured print departs from it at worst (what the
    piece's seams are expected off by), over ``tiles`` tiles."""

    correction: np.ndarray
    beyond_mm: float
    tiles: int

    @property
    def strain(self) -> float:
        """Largest stretch or shear of the correction (a fraction): what placing the
        piece on the print as it lies changes of its shape."""
        return float(np.abs(np.linalg.svd(self.correction[:, :2], compute_uv=False)
                            - 1.0).max())


def fit_local_map(points_mm: np.ndarray, shifts_mm: np.ndarray) -> LocalMap:
    """The affine map through the measured ``shifts_mm`` (n, 2) at ``points_mm`` (n, 2)
    (a translation with fewer than 3 tiles or tiles in a line); tiles off the first fit
    by more than `OUTLIER_MM` are left out (a tile that matched the wrong way)."""
    p, s = np.asarray(points_mm, float).reshape(-1, 2), np.asarray(shifts_mm, float)
    if not len(p):
        raise ValueError("no tile of the photograph lies over the piece")
    keep = np.ones(len(p), bool)
    for _ in range(2):
        lin, shift = _affine_fit(p[keep], s[keep])
        off = np.hypot(*(s - p @ lin.T - shift).T)
        keep = off <= max(OUTLIER_MM, float(np.median(off)) * 3.0)
    lin, shift = _affine_fit(p[keep], s[keep])
    off = np.hypot(*(s[keep] - p[keep] @ lin.T - shift).T)
    return LocalMap(np.column_stack([np.eye(2) + lin, shift]), float(off.max()),
                    int(keep.sum()))


def _affine_fit(p: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(linear (2, 2), shift (2,)) with s ~ linear p + shift, least squares about the
    points' centre; a translation alone when the points do not span the plane."""
    if len(p) < 3 or np.linalg.matrix_rank(p - p.mean(axis=0), tol=1.0) < 2:
        return np.zeros((2, 2)), s.mean(axis=0)
    centre = p.mean(axis=0)
    design = np.column_stack([p - centre, np.ones(len(p))])
    sol, *_ = np.linalg.lstsq(design, s, rcond=None)
    lin = sol[:2].T
    return lin, sol[2] - lin @ centre


def nearest_rigid(correction: np.ndarray, points: np.ndarray, weights: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(rigid (2, 3), residual (n,) mm): the rotation and translation nearest the affine
    ``correction`` (2, 3) over ``points`` (n, 2) weighted by ``weights`` (n,) (least
    squares, the closed-form weighted Procrustes), and how far the correction moves each
    point beyond it. The rotation is proper: a mirrored piece stays mirrored."""
    a = np.asarray(correction, float)
    p = np.asarray(points, float).reshape(-1, 2)
    w = np.asarray(weights, float).reshape(-1)
    if len(p) != len(w) or not len(p) or not (w >= 0).all() or not w.sum() > 0:
        raise ValueError(f"{len(p)} points need as many weights, not negative and not all "
                         f"zero (got {len(w)})")
    centre = w @ p / w.sum()
    x = p - centre
    y = x @ a[:, :2].T  # where the correction takes each point, about the centre's image
    theta = np.arctan2(w @ (x[:, 0] * y[:, 1] - x[:, 1] * y[:, 0]), w @ np.sum(x * y, axis=1))
    c, s = np.cos(theta), np.sin(theta)
    rot = np.array([[c, -s], [s, c]])
    shift = a[:, :2] @ centre + a[:, 2] - rot @ centre
    return np.column_stack([rot, shift]), np.hypot(*(y - x @ rot.T).T)
