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

    @property
    def slip_mm(self) -> float:
        return self.advance_mm - self.commanded_mm

    def to_dict(self) -> dict[str, float]:
        return {"advance_commanded_mm": round(self.commanded_mm, 4),
                "advance_measured_mm": round(self.advance_mm, 4),
                "across_mm": round(self.across_mm, 4), "skew_deg": round(self.skew_deg, 5),
                "residual": round(self.residual, 5), "tiles": self.tiles}


def measure_advance(before: np.ndarray, after: np.ndarray, *, commanded_mm: float,
                    mm_per_px: float = 1.0, lattice: np.ndarray | None = None) -> Advance:
    """The roll's motion between ``before`` and ``after`` (photographs of the same window,
    rectified to table mm at ``mm_per_px``), the roll advanced by ``commanded_mm`` along
    +x between them. ``lattice``: (2, 2) columns, the print's repeat vectors in mm (None:
    a print that does not repeat within a tile). Raises ValueError, saying why, when the
    photographs cannot be compared."""
    a, b = to_gray_float(before), to_gray_float(after)
    if a.shape != b.shape:
        raise ValueError(f"the photographs differ in size: {a.shape} and {b.shape}")
    h, w = a.shape
    shared = w * mm_per_px - commanded_mm
    if not math.isfinite(commanded_mm) or commanded_mm < 0 or shared < MIN_OVERLAP_MM:
        raise ValueError(f"an advance of {commanded_mm:g} mm leaves {shared:g} mm of cloth in "
                         f"both photographs of the {w * mm_per_px:g} mm window; at least "
                         f"{MIN_OVERLAP_MM:g} mm must stay in view")
    a = cv2.GaussianBlur(a, (0, 0), SMOOTH_PX)
    b = cv2.GaussianBlur(b, (0, 0), SMOOTH_PX)
    pivot = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    lattice_px = None if lattice is None else np.asarray(lattice, float) / mm_per_px
    coarse, tiles = _coarse_motion(a, b, commanded_mm / mm_per_px, pivot, lattice_px)
    motion, residual = _refine(a, b, coarse, pivot)
    return Advance(float(motion[0] * mm_per_px), float(motion[1] * mm_per_px),
                   float(math.degrees(motion[2])), float(commanded_mm),
                   (float(pivot[0] * mm_per_px), float(pivot[1] * mm_per_px)),
                   residual, tiles)


def _coarse_motion(a: np.ndarray, b: np.ndarray, commanded_px: float, pivot: np.ndarray,
                   lattice_px: np.ndarray | None) -> tuple[np.ndarray, int]:
    """(tx, ty, theta) from phase-correlated tiles of the shared strip, each shift taken
    nearest to the commanded advance modulo the print's lattice."""
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
            moves.append((shift - sx, -sy))  # after(p) = before(p + move)
    centres, moves = np.array(centres), np.array(moves)
    off = moves - np.array([commanded_px, 0.0])
    if lattice_px is not None:  # the nearest of the print's equivalent shifts
        off -= (lattice_px @ np.round(np.linalg.solve(lattice_px, off.T))).T
    moves = off + np.array([commanded_px, 0.0])
    # first the tiles near the median move, then every tile the rigid motion explains
    # (a skew spreads the moves across a wide window beyond any fixed tolerance)
    agree = np.all(np.abs(moves - np.median(moves, axis=0)) <= AGREE_PX, axis=1)
    for _ in range(2):
        if agree.sum() < 3:
            raise ValueError("the print under the shared strip matched in fewer than 3 "
                             "tiles: is the cloth plain, or did the roll stop?")
        motion = _rigid_fit(centres[agree], moves[agree], pivot)
        agree = np.hypot(*(moves - _rigid_moves(centres, motion, pivot)).T) <= AGREE_PX
    return motion, int(agree.sum())


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


def _refine(a: np.ndarray, b: np.ndarray, motion: np.ndarray, pivot: np.ndarray
            ) -> tuple[np.ndarray, float]:
    """Gauss-Newton on sum (a(R(theta)(p - pivot) + pivot + t) - b(p))^2 over the pixels of
    ``b`` whose cloth lies inside ``a``; returns the motion and the rms difference."""
    h, w = a.shape
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
    qx0, qy0 = xs - np.float32(pivot[0]), ys - np.float32(pivot[1])
    gx = cv2.Sobel(a, cv2.CV_32F, 1, 0, ksize=3, scale=1 / 8)
    gy = cv2.Sobel(a, cv2.CV_32F, 0, 1, ksize=3, scale=1 / 8)
    motion = np.asarray(motion, float).copy()
    residual = float("nan")
    for _ in range(ITERATIONS):
        c, s = math.cos(motion[2]), math.sin(motion[2])
        mx = (c * qx0 - s * qy0 + pivot[0] + motion[0]).astype(np.float32)
        my = (s * qx0 + c * qy0 + pivot[1] + motion[1]).astype(np.float32)
        inside = (mx >= 2) & (mx <= w - 3) & (my >= 2) & (my <= h - 3)
        warped = [cv2.remap(img, mx, my, cv2.INTER_LINEAR)[inside] for img in (a, gx, gy)]
        err = warped[0] - b[inside]
        # d(mx, my)/d(theta) = (-s qx - c qy, c qx - s qy)
        dth = warped[1] * (-s * qx0[inside] - c * qy0[inside]) \
            + warped[2] * (c * qx0[inside] - s * qy0[inside])
        jac = np.stack([warped[1], warped[2], dth], axis=1).astype(np.float64)
        step = np.linalg.solve(jac.T @ jac, -jac.T @ err.astype(np.float64))
        motion += step
        residual = float(np.sqrt(np.mean(err.astype(np.float64) ** 2)))
        if abs(step[0]) + abs(step[1]) + abs(step[2]) * max(h, w) < STEP_DONE_PX:
            break
    return motion, residual
