"""The real advance of the roll, measured from the print itself.

After the conveyor has advanced the roll by a commanded length, the camera photographs
the table window again. The part of the cloth that was at the window's far end now lies
at its near end, so the two photographs share a strip of the same cloth: the rigid
motion (advance along the roll, drift across it, skew) that carries one onto the other
is what the conveyor really did, whatever the print's own bow and stretch.

Two steps. Coarse: tiles of the shared strip are matched by phase correlation [1]_. A
periodic print matches at every lattice vector, so each tile's shift is only known
modulo the print's repeat; it is taken nearest to the commanded advance (a conveyor
slips by millimetres, a repeat is tens of millimetres), and a rigid motion is fitted to
the tiles that agree. Fine: the rigid motion is refined on every pixel of the strip by
Gauss-Newton on the intensity difference (Lucas and Kanade [2]_), which is free of the
phase correlation's sub-pixel bias.

A print may say nothing along the roll: stripes running along it, a plain cloth, a
repeat along the roll no longer than the slip. Then the advance is not measured, and
says so (`Advance.unmeasured`) rather than handing back the commanded one as measured.
Two tests, both on the images: the photographs compared at every whole-pixel advance
within twice the conveyor's slip of the one found (a print that matches as well a few
pixels away has no unique match), and the formal error of each component from the
normal matrix of the shared strip's own print (the gradients of both photographs
multiplied with each other, so the sensor's noise, independent in the two, adds
nothing). A component left unmeasured keeps its prior: the commanded advance, no drift,
no skew. What the station itself put on the cloth, the kerfs of the bite it cut, can
then carry the advance (`station.steps.bites.measure_bite_advance`).

References
----------
.. [1] C. D. Kuglin, D. C. Hines, "The phase correlation image alignment method",
       Proc. IEEE Conf. Cybernetics and Society, 1975.
.. [2] S. Baker, I. Matthews, "Lucas-Kanade 20 years on: a unifying framework",
       IJCV 56(3), 2004. :DOI:`10.1023/B:VISI.0000011205.11775.fd`
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from vision.prepare import to_gray_float

#: the shortest strip of cloth the two photographs must share (mm): two tiles' worth of
#: a fine print; a commanded advance that leaves less is refused before the advance
MIN_OVERLAP_MM = 40.0
TILE_MM = 96.0  # a tile holds about two repeats of a 50 mm print
MAX_TILE_PX = 128
SMOOTH_PX = 1.0  # Gaussian before the gradients: the noise is per pixel, the print is not
AGREE_PX = 3.0  # a tile agrees with the motion to within this (its shift is whole pixels)
ITERATIONS = 12
STEP_DONE_PX = 1e-3
#: the conveyor's slip the along-roll scan looks across, each way from the match found
#: (issue 35: up to 3 mm per advance); a second match within twice this is ambiguous
MAX_SLIP_MM = 4.0
#: the along-roll match is unique when every advance two pixels or more from it leaves
#: this share more residual than it does: the sensor's noise moves the residual by about
#: 1 % over a strip; a print that says nothing along the roll leaves it flat
UNIQUE_SHARE = 0.25
#: a component whose formal error (one sigma) exceeds this is not measured (a third of
#: what issue 35 allows an advance: 0.3 mm, 0.05 degrees)
MAX_SIGMA_MM, MAX_SIGMA_DEG = 0.1, 0.015
#: the wider smoothing that first finds the drift and skew where the tiles could not,
#: aligning what it measures within this many times the limits (into the fine basin)
WIDE_SMOOTH_PX, WIDE_LIMITS = 3.0, 10.0
COMPONENTS = ("along", "across", "skew")


@dataclass(frozen=True)
class Advance:
    """What the roll did between two photographs of the window (mm, degrees).

    A table point ``p`` of the second photograph shows the cloth that the first showed
    at ``R(skew) (p - pivot) + pivot + (advance_mm, across_mm)``; ``pivot`` is the
    window's centre (mm from the photographs' first pixel centre)."""

    advance_mm: float
    across_mm: float
    skew_deg: float
    commanded_mm: float
    pivot_mm: tuple[float, float]
    residual: float  # rms grey-level difference left on the shared strip (0..1)
    tiles: int  # tiles that agreed on the coarse motion
    #: the components (of `COMPONENTS`) the photographs could not measure; each keeps its
    #: prior (the commanded advance, no drift, no skew)
    unmeasured: tuple[str, ...] = ()

    @property
    def along_measured(self) -> bool:
        return "along" not in self.unmeasured

    @property
    def slip_mm(self) -> float:
        return self.advance_mm - self.commanded_mm

    def to_dict(self) -> dict[str, float]:
        return {"advance_commanded_mm": round(self.commanded_mm, 4),
                "advance_measured_mm": round(self.advance_mm, 4),
                "across_mm": round(self.across_mm, 4), "skew_deg": round(self.skew_deg, 5),
                "residual": round(self.residual, 5), "tiles": self.tiles,
                "unmeasured": list(self.unmeasured)}


def measure_advance(before: np.ndarray, after: np.ndarray, *, commanded_mm: float,
                    mm_per_px: float = 1.0, lattice: np.ndarray | None = None) -> Advance:
    """The roll's motion between ``before`` and ``after`` (photographs of the same window,
    rectified to table mm at ``mm_per_px``), the roll advanced by ``commanded_mm`` along
    +x between them. ``lattice``: (2, 2) columns, the print's repeat vectors in mm (None:
    a print that does not repeat within a tile). A component the photographs cannot
    measure is named in ``unmeasured`` and keeps its prior (see the module's docstring).
    Raises ValueError, saying why, when the photographs cannot be compared."""
    a, b = to_gray_float(before), to_gray_float(after)
    if a.shape != b.shape:
        raise ValueError(f"the photographs differ in size: {a.shape} and {b.shape}")
    h, w = a.shape
    shared = w * mm_per_px - commanded_mm
    if not math.isfinite(commanded_mm) or commanded_mm < 0 or shared < MIN_OVERLAP_MM:
        raise ValueError(f"an advance of {commanded_mm:g} mm leaves {shared:g} mm of cloth in "
                         f"both photographs of the {w * mm_per_px:g} mm window; at least "
                         f"{MIN_OVERLAP_MM:g} mm must stay in view")
    frames = _Frames.of(a, b, SMOOTH_PX)
    prior = np.array([commanded_mm / mm_per_px, 0.0, 0.0])
    lattice_px = None if lattice is None else np.asarray(lattice, float) / mm_per_px
    coarse, tiles = _coarse_motion(frames.a, frames.b, prior[0], frames.pivot, lattice_px)
    reach = math.ceil(2 * MAX_SLIP_MM / mm_per_px)
    limits = np.array([MAX_SIGMA_MM / mm_per_px, MAX_SIGMA_MM / mm_per_px,
                       math.radians(MAX_SIGMA_DEG)])
    coarse[0], unique = _along_scan(frames, coarse, reach)
    free = _measurable(frames, coarse, limits, np.array([unique, True, True]))
    if not free.all():  # or the tiles' motion was rough, as where they matched only
        # across the roll (stripes along it, a few kerfs): first align what the
        # photographs smoothed wider measure (a wider basin), look along the roll again
        # from there, and judge again
        wide = _Frames.of(a, b, WIDE_SMOOTH_PX)
        for _ in range(2):
            coarse, _ = _refine(wide, coarse, _measurable(
                wide, coarse, WIDE_LIMITS * limits, np.array([unique, True, True])))
            if unique:
                break
            coarse[0], unique = _along_scan(frames, coarse, reach)
        free = _measurable(frames, coarse, limits, np.array([unique, True, True]))
    # a held advance is refined at the best match (on a print repeating along the roll,
    # a repeat from the true one: the drift and skew are the same there), a held drift
    # or skew at its prior (the tiles' guess at it is noise); all reported at the prior
    start = np.where(free, coarse, prior)
    start[0] = coarse[0]
    motion, residual = _refine(frames, start, free)
    motion = np.where(free, motion, prior)
    pivot = frames.pivot
    return Advance(float(motion[0] * mm_per_px), float(motion[1] * mm_per_px),
                   float(math.degrees(motion[2])), float(commanded_mm),
                   (float(pivot[0] * mm_per_px), float(pivot[1] * mm_per_px)),
                   residual, tiles, tuple(c for c, f in zip(COMPONENTS, free) if not f))


@dataclass(frozen=True)
class _Frames:
    """Both smoothed photographs with their gradients, and the window's centre (px)."""

    a: np.ndarray
    b: np.ndarray
    grad_a: tuple[np.ndarray, np.ndarray]
    grad_b: tuple[np.ndarray, np.ndarray]
    pivot: np.ndarray
    offsets: tuple[np.ndarray, np.ndarray]  # each pixel's (x, y) from the pivot
    #: the noise of neighbouring pixels is correlated by the smoothing: a strip of n
    #: pixels holds n / (4 pi sigma^2) independent ones, which scales the formal error
    noise_spread: float

    @classmethod
    def of(cls, a: np.ndarray, b: np.ndarray, smooth_px: float) -> _Frames:
        """The grey photographs ``a`` and ``b`` smoothed by a Gaussian of ``smooth_px``."""
        a = cv2.GaussianBlur(a, (0, 0), smooth_px)
        b = cv2.GaussianBlur(b, (0, 0), smooth_px)
        h, w = a.shape
        pivot = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
        ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
        return cls(a, b, _gradients(a), _gradients(b), pivot,
                   (xs - np.float32(pivot[0]), ys - np.float32(pivot[1])),
                   math.sqrt(4.0 * math.pi) * smooth_px)

    def warp(self, motion: np.ndarray, margin: float = 2.0
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Where each pixel of ``b`` shows in ``a`` under ``motion`` (tx, ty, theta): (mx,
        my) px, the mask of those at least ``margin`` px inside ``a``, and the pixels'
        offsets from the pivot (qx, qy)."""
        h, w = self.a.shape
        qx, qy = self.offsets
        c, s = math.cos(motion[2]), math.sin(motion[2])
        mx = (c * qx - s * qy + self.pivot[0] + motion[0]).astype(np.float32)
        my = (s * qx + c * qy + self.pivot[1] + motion[1]).astype(np.float32)
        inside = (mx >= margin) & (mx <= w - 1 - margin) & (my >= 2) & (my <= h - 3)
        return mx, my, inside, qx, qy


def _gradients(img: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return (cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3, scale=1 / 8),
            cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3, scale=1 / 8))


def _coarse_motion(a: np.ndarray, b: np.ndarray, commanded_px: float, pivot: np.ndarray,
                   lattice_px: np.ndarray | None) -> tuple[np.ndarray, int]:
    """(tx, ty, theta) from phase-correlated tiles of the shared strip, each shift taken
    nearest to the commanded advance modulo the print's lattice, and the tiles that
    agreed. Tiles that agree only across the roll (a print striped along it) give the
    drift and skew, the advance the commanded one; none agreeing, the prior alone."""
    centres, moves = _tile_moves(a, b, commanded_px)
    off = moves - np.array([commanded_px, 0.0])
    if lattice_px is not None:  # the nearest of the print's equivalent shifts
        off -= (lattice_px @ np.round(np.linalg.solve(lattice_px, off.T))).T
    moves = off + np.array([commanded_px, 0.0])
    # first the tiles near the median move, then every tile the rigid motion explains
    # (a skew spreads the moves across a wide window beyond any fixed tolerance)
    agree = np.all(np.abs(moves - np.median(moves, axis=0)) <= AGREE_PX, axis=1)
    if agree.sum() >= 3:
        motion = _rigid_fit(centres[agree], moves[agree], pivot)
        agree = np.hypot(*(moves - _rigid_moves(centres, motion, pivot)).T) <= AGREE_PX
        if agree.sum() >= 3:
            return _rigid_fit(centres[agree], moves[agree], pivot), int(agree.sum())
    return _one_axis_motion(centres, moves, commanded_px, pivot)


def _one_axis_motion(centres: np.ndarray, moves: np.ndarray, commanded_px: float,
                     pivot: np.ndarray) -> tuple[np.ndarray, int]:
    """(tx, ty, theta) from the tiles that agree along one axis only (stripes give each
    tile's move across them, not along): each axis's tiles that agree give its shift and
    the skew (x moves = tx - theta qy, y moves = ty + theta qx); an axis none agree on
    keeps its prior (the commanded advance, no drift), the skew the axis more agree on."""
    motion, tiles, best = np.array([commanded_px, 0.0, 0.0]), 0, 0
    for axis, arm in ((0, -(centres[:, 1] - pivot[1])), (1, centres[:, 0] - pivot[0])):
        agree = np.abs(moves[:, axis] - np.median(moves[:, axis])) <= AGREE_PX
        if agree.sum() < 3:
            continue
        (shift, theta), *_ = np.linalg.lstsq(
            np.column_stack([np.ones(int(agree.sum())), arm[agree]]), moves[agree, axis],
            rcond=None)
        motion[axis] = shift
        if agree.sum() > best:
            motion[2], best = theta, int(agree.sum())
        tiles = max(tiles, int(agree.sum()))
    return motion, tiles


def _tile_moves(a: np.ndarray, b: np.ndarray, commanded_px: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """(centres (n, 2), moves (n, 2)) px of the tiles of the shared strip: each tile of
    ``b`` phase-correlated with ``a`` at the commanded advance, after(p) = before(p +
    move)."""
    h, w = a.shape
    shift = int(round(commanded_px))
    tw = int(min(MAX_TILE_PX, w - shift))
    th = int(min(MAX_TILE_PX, h))
    cols = np.arange(0, w - shift - tw + 1, max(tw // 2, 1))
    rows = np.arange(0, h - th + 1, max(th // 2, 1))
    window = cv2.createHanningWindow((tw, th), cv2.CV_64F)
    centres, moves = [], []
    for r in rows:
        for c in cols:
            tile_b = b[r:r + th, c:c + tw].astype(np.float64)
            tile_a = a[r:r + th, c + shift:c + shift + tw].astype(np.float64)
            (sx, sy), _ = cv2.phaseCorrelate(tile_a, tile_b, window)
            centres.append((c + (tw - 1) / 2.0, r + (th - 1) / 2.0))
            moves.append((shift - sx, -sy))
    return np.array(centres), np.array(moves)


def _rigid_moves(p: np.ndarray, motion: np.ndarray, pivot: np.ndarray) -> np.ndarray:
    """(n, 2) moves of the points ``p`` under the small rigid ``motion`` (tx, ty, theta)."""
    q = p - pivot
    return motion[:2] + motion[2] * np.column_stack([-q[:, 1], q[:, 0]])


def _rigid_fit(p: np.ndarray, d: np.ndarray, pivot: np.ndarray) -> np.ndarray:
    """(tx, ty, theta) with d ~ t + theta J (p - pivot), least squares (small theta)."""
    q = p - pivot
    n = len(p)
    m = np.zeros((2 * n, 3))
    m[:n, 0], m[n:, 1] = 1.0, 1.0
    m[:n, 2], m[n:, 2] = -q[:, 1], q[:, 0]
    sol, *_ = np.linalg.lstsq(m, np.concatenate([d[:, 0], d[:, 1]]), rcond=None)
    return sol


def _along_scan(frames: _Frames, motion: np.ndarray, reach_px: int) -> tuple[float, bool]:
    """The advance (px) of the whole-pixel offsets from ``motion``'s within ``reach_px``
    that leaves the least residual on the shared strip, and whether it is the only one:
    every offset two pixels or more from it leaves `UNIQUE_SHARE` more, and it lies
    inside the scan (a print that says nothing along the roll leaves the scan flat; a
    repeat along the roll shorter than the reach matches again one repeat away)."""
    mx, my, inside, _, _ = frames.warp(motion, margin=2.0 + reach_px)
    cols = np.flatnonzero(inside.any(axis=0))
    if len(cols) == 0:
        return float(motion[0]), False
    box = (slice(None), slice(int(cols[0]), int(cols[-1]) + 1))
    mx, my, inside, b = mx[box], my[box], inside[box], frames.b[box][inside[box]]
    offsets = np.arange(-reach_px, reach_px + 1)
    cost = np.array([np.mean((cv2.remap(frames.a, mx + np.float32(k), my, cv2.INTER_LINEAR)
                              [inside] - b) ** 2) for k in offsets])
    best = int(np.argmin(cost))
    others = cost[np.abs(offsets - offsets[best]) >= 2]
    unique = (0 < best < len(offsets) - 1 and len(others) > 0
              and others.min() - cost[best] >= UNIQUE_SHARE * cost[best])
    return float(motion[0] + offsets[best]), bool(unique)


def _jacobian(grad: tuple[np.ndarray, np.ndarray], mx: np.ndarray, my: np.ndarray,
              inside: np.ndarray, qx: np.ndarray, qy: np.ndarray, theta: float,
              warped: bool) -> np.ndarray:
    """(n, 3) derivatives of the grey level by (tx, ty, theta) at the pixels ``inside``,
    from the gradients ``grad`` (of ``a`` sampled at (mx, my) when ``warped``, else of
    ``b`` at the pixels themselves); d(mx, my)/d(theta) = (-s qx - c qy, c qx - s qy)."""
    if warped:
        gx, gy = (cv2.remap(g, mx, my, cv2.INTER_LINEAR)[inside] for g in grad)
    else:
        gx, gy = grad[0][inside], grad[1][inside]
    c, s = math.cos(theta), math.sin(theta)
    qx, qy = qx[inside], qy[inside]
    dth = gx * (-s * qx - c * qy) + gy * (c * qx - s * qy)
    return np.stack([gx, gy, dth], axis=1).astype(np.float64)


def _measurable(frames: _Frames, motion: np.ndarray, limits: np.ndarray,
                free: np.ndarray) -> np.ndarray:
    """(3,) bool: the components of ``free`` that the print measures near ``motion``:
    with the others held, each one's formal error (one sigma, all of them free) within
    its ``limits``. While one is beyond, the worst is held and the rest judged again
    without it; a direction of no information at all (the print's normal matrix not
    positive there) holds the component it loads most."""
    normal, noise = _signal_normal(frames, motion)
    free = free.copy()
    while free.any():
        idx = np.flatnonzero(free)
        scaled = normal[np.ix_(idx, idx)] * np.outer(limits[idx], limits[idx])
        values, vectors = np.linalg.eigh(scaled)
        if values[0] <= 1e-12 * max(values[-1], 1e-300):
            free[idx[int(np.argmax(np.abs(vectors[:, 0])))]] = False
            continue
        ratio = noise * np.sqrt(np.einsum("ij,j,ij->i", vectors, 1.0 / values, vectors))
        if np.all(ratio <= 1.0):
            break
        free[idx[int(np.argmax(ratio))]] = False
    return free


def _signal_normal(frames: _Frames, motion: np.ndarray) -> tuple[np.ndarray, float]:
    """The print's own normal matrix (3, 3) of (tx, ty, theta) on the shared strip near
    ``motion``, and the noise it is weighed against: the gradients of one photograph
    times the other's (the sensor's noise in each is its own, so it adds nothing in
    expectation, where the Gauss-Newton matrix of one photograph counts it as
    information), and the residual's rms spread by the smoothing (`_Frames.noise_spread`). A
    motion's formal error along a unit direction d is noise / sqrt(d' normal d)."""
    mx, my, inside, qx, qy = frames.warp(motion)
    if inside.sum() < 16:
        return np.zeros((3, 3)), math.inf
    ja = _jacobian(frames.grad_a, mx, my, inside, qx, qy, motion[2], warped=True)
    jb = _jacobian(frames.grad_b, mx, my, inside, qx, qy, motion[2], warped=False)
    err = cv2.remap(frames.a, mx, my, cv2.INTER_LINEAR)[inside] - frames.b[inside]
    rms = float(np.sqrt(np.mean(err.astype(np.float64) ** 2)))
    return 0.5 * (ja.T @ jb + jb.T @ ja), frames.noise_spread * rms


def _refine(frames: _Frames, motion: np.ndarray, free: np.ndarray
            ) -> tuple[np.ndarray, float]:
    """Gauss-Newton on sum (a(R(theta)(p - pivot) + pivot + t) - b(p))^2 over the pixels of
    ``b`` whose cloth lies inside ``a``, moving only the components ``free`` (3,) bool;
    returns the motion and the rms difference."""
    a, b = frames.a, frames.b
    motion = np.asarray(motion, float).copy()
    residual = float("nan")
    for _ in range(ITERATIONS if free.any() else 1):
        mx, my, inside, qx, qy = frames.warp(motion)
        err = (cv2.remap(a, mx, my, cv2.INTER_LINEAR)[inside] - b[inside]).astype(np.float64)
        residual = float(np.sqrt(np.mean(err ** 2)))
        if not free.any():
            break
        jac = _jacobian(frames.grad_a, mx, my, inside, qx, qy, motion[2], warped=True)[:, free]
        step = np.zeros(3)
        step[free] = np.linalg.solve(jac.T @ jac, -jac.T @ err)
        motion += step
        if abs(step[0]) + abs(step[1]) + abs(step[2]) * max(a.shape) < STEP_DONE_PX:
            break
    return motion, residual
