"""Quick synthetic prints for the vision tests.

The prints come from ``simulators.fabric`` (random prints of each group, symmetrised
with the ``solver.wallpaper`` table, so the truth is exact); the camera faults below are
a small, fast stand-in for the simulated camera, so that a whole group-accuracy sweep
fits in the test budget. Pixels are millimetres here (``mm_per_px = 1``).
"""

from __future__ import annotations

import cv2
import numpy as np

from simulators.fabric import random_print, render_print
from solver.wallpaper import Wallpaper


def perturb(img: np.ndarray, rng: np.random.Generator, *, blur: float = 0.0,
            noise: float = 0.0, jpeg: int | None = None, ramp: float = 0.0,
            persp: float = 0.0, fold: float = 0.0) -> np.ndarray:
    """Camera faults on a float [0,1] print (gray or BGR) -> uint8 BGR."""
    h, w = img.shape[:2]
    out = (0.1 + 0.8 * img).astype(np.float32)
    if out.ndim == 2:
        out = np.repeat(out[:, :, None], 3, axis=2)
    if persp:
        src = np.float32([[0, 0], [w, 0], [w, h], [0, h]])
        dst = (src + rng.uniform(-persp, persp, (4, 2)) * [w, h]).astype(np.float32)
        out = cv2.warpPerspective(out, cv2.getPerspectiveTransform(src, dst), (w, h),
                                  borderMode=cv2.BORDER_REFLECT)
    if fold:
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        k = rng.uniform(0.5, 1.0) * 2 * np.pi / max(h, w)
        dx = fold * np.sin(k * yy + rng.uniform(0, 6))
        dy = fold * np.sin(k * xx + rng.uniform(0, 6))
        out = cv2.remap(out, xx + dx, yy + dy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    if blur:
        out = cv2.GaussianBlur(out, (0, 0), blur)
    if ramp:
        yy, xx = np.mgrid[0:h, 0:w]
        gain = 1 - ramp + 2 * ramp * xx / w
        r2 = ((xx - w / 2) ** 2 + (yy - h / 2) ** 2) / (0.5 * max(h, w)) ** 2
        out = out * (gain * (1 - 0.3 * r2))[:, :, None]
    if noise:
        out = out + rng.normal(0, noise, out.shape)
    out = np.clip(out * 255, 0, 255).astype(np.uint8)
    if jpeg:
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(jpeg)])
        out = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    return out


def synth(group: str, *, seed: int, shape=(300, 400), period: float = 50.0,
          rotation: float | None = None, **faults) -> tuple[np.ndarray, Wallpaper]:
    """(uint8 BGR image, truth Wallpaper in pixels = mm)."""
    rng = np.random.default_rng(seed)
    rot = rng.uniform(0, 90) if rotation is None else rotation
    p = random_print(group, period, rotation=rot, seed=seed)
    img = render_print(p, (shape[1], shape[0]), 1.0).astype(np.float32) / 255.0
    return perturb(img, rng, **faults), p.wallpaper


def lattice_error(found: np.ndarray, truth: np.ndarray) -> float:
    """Largest relative vector error between two bases (columns) of the same lattice,
    after the unimodular change of basis that matches them; inf if the lattices differ."""
    u = np.linalg.solve(truth, found)
    ur = np.round(u)
    if abs(abs(np.linalg.det(ur)) - 1) > 1e-9 or np.abs(u - ur).max() > 0.2:
        return float("inf")
    diff = found - truth @ ur
    return float(np.max(np.linalg.norm(diff, axis=0) / np.linalg.norm(found, axis=0)))


def symmetry_error(found: Wallpaper, truth: Wallpaper) -> float:
    """How far the found group's operations (about the found origin) are from being
    symmetries of the true print, as a fraction of the repeat (0 = exact)."""
    p = found.origin + np.array([[0.0, 0.0], [3.0, 1.0], [-2.0, 4.0]])
    worst = 0.0
    for op in found.cartesian_ops():
        q = p @ op[:2, :2].T + op[:2, 2]
        worst = max(worst, float(np.hypot(*truth.mismatch(q, p).T).max()))
    return worst / np.sqrt(abs(np.linalg.det(truth.basis)))


def stripes(seed: int, *, shape=(300, 400), **faults) -> tuple[np.ndarray, float, float]:
    """1-D stripes (a frieze): (uint8 BGR image, period px, direction deg of the stripes)."""
    rng = np.random.default_rng(seed)
    ang = rng.uniform(0, 180)
    period = rng.uniform(12, 60)
    a = np.deg2rad(ang)
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    ph = 2 * np.pi * (xx * np.cos(a) + yy * np.sin(a)) / period
    prof = (0.5 + 0.5 * np.sign(np.sin(ph)) if seed % 2
            else 0.5 + 0.35 * np.sin(ph) + 0.15 * np.sin(2 * ph + rng.uniform(0, 6)))
    return perturb(prof, rng, **faults), period, (ang + 90.0) % 180.0


