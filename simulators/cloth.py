"""What real cloth does to a print: weave texture, stretch, wrinkles, misregistration.

The synthetic camera photographs a perfect print on a flat sheet; real fabric carries
its yarn at thread scale, is stretched a few per cent by handling and spreading,
wrinkles, and its colour separations may be printed slightly out of register. These
functions apply each fault to a top-down image (``render_print``'s or a rectified
frame), with a known geometric effect, to make harder training and test data for
``vision``, and render plain cloth (weave only, no print) to check that the weave is
never taken for a print.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

__all__ = ["WEAVES", "misregister", "plain_cloth", "stretch", "weave_texture", "wrinkle"]

#: Structures of the thread texture: plain weave (1/1), 2/2 twill (diagonal lines that
#: break the print's mirrors at thread scale) and rib knit (wales along one axis).
WEAVES = ("plain", "twill", "rib")


def weave_texture(shape: tuple[int, int], thread_px: float, *, weave: str = "plain",
                  contrast: float = 0.12, angle_deg: float = 0.0,
                  rng: np.random.Generator | None = None) -> np.ndarray:
    """(H, W) float32 gain around 1: the light and shade of the yarn.

    ``thread_px`` is the thread spacing in pixels; threads vary in thickness and
    brightness (slubs) from one to the next, as spun yarn does.
    """
    if weave not in WEAVES:
        raise ValueError(f"unknown weave {weave!r}; expected one of {', '.join(WEAVES)}")
    if not thread_px > 0:
        raise ValueError(f"thread spacing must be positive, got {thread_px}")
    rng = rng if rng is not None else np.random.default_rng(0)
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    a = math.radians(angle_deg)
    u = (xx * math.cos(a) + yy * math.sin(a)) / thread_px  # across the warp threads
    v = (-xx * math.sin(a) + yy * math.cos(a)) / thread_px  # across the weft picks
    n_u = int(np.abs(u).max()) + 2
    n_v = int(np.abs(v).max()) + 2
    jit_u = 1.0 + 0.25 * rng.standard_normal(2 * n_u + 1).astype(np.float32)
    jit_v = 1.0 + 0.25 * rng.standard_normal(2 * n_v + 1).astype(np.float32)
    iu = np.floor(u).astype(int)
    iv = np.floor(v).astype(int)
    bump_u = np.sin(np.pi * (u - iu)) * jit_u[iu + n_u]  # a thread's round profile
    bump_v = np.sin(np.pi * (v - iv)) * jit_v[iv + n_v]
    if weave == "rib":
        tex = bump_u
    else:
        up = ((iu + iv) % 2 == 0) if weave == "plain" else ((iu + iv) % 4 < 2)
        tex = np.where(up, bump_u, bump_v)
    tex = tex - tex.mean()
    return (1.0 + contrast * tex / max(float(tex.std()), 1e-6)).astype(np.float32)


def plain_cloth(size_px: tuple[int, int], thread_px: float, *, weave: str = "plain",
                colour: tuple[float, float, float] = (0.45, 0.42, 0.48),
                shading: float = 0.06, seed: int = 0) -> np.ndarray:
    """(H, W, 3) uint8 BGR photo of unprinted cloth: one colour, the yarn's texture, and
    soft shading bands (uneven dyeing or light) a few hundred threads wide."""
    rng = np.random.default_rng(seed)
    w, h = size_px
    # Rendered at 3x and area-averaged, as a sensor integrates over its pixels: thread
    # edges sampled point-wise would alias into a coarse moire no camera sees.
    tex = weave_texture((3 * h, 3 * w), 3 * thread_px, weave=weave,
                        angle_deg=rng.uniform(-3, 3), rng=rng)
    tex = cv2.resize(tex, (w, h), interpolation=cv2.INTER_AREA)
    xx = np.arange(w, dtype=np.float32) / max(w, 1)
    bands = 1.0 + shading * sum(rng.uniform(0.3, 1.0) * np.sin(2 * np.pi * f * xx
                                                               + rng.uniform(0, 6.3))
                                for f in rng.uniform(1.5, 6.0, 3)) / 3
    img = np.asarray(colour, np.float32)[None, None] * (tex * bands[None, :])[..., None]
    img += rng.normal(0.0, 0.01, img.shape).astype(np.float32)
    return np.clip(np.rint(img * 255), 0, 255).astype(np.uint8)


def _warp(img: np.ndarray, mx: np.ndarray, my: np.ndarray) -> np.ndarray:
    return cv2.remap(img, mx.astype(np.float32), my.astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REFLECT)


def stretch(img: np.ndarray, aspect: float, *, shear_deg: float = 0.0,
            angle_deg: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Stretch the cloth by ``aspect`` (1.08 = 8 % longer) along ``angle_deg`` and shear
    it by ``shear_deg``, about the image centre. Returns the image and the 2x2 map J
    taking a print vector before to after (lattice vectors become ``J @ w``)."""
    a = math.radians(angle_deg)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    jac = rot @ np.array([[aspect, math.tan(math.radians(shear_deg))], [0.0, 1.0]]) @ rot.T
    h, w = img.shape[:2]
    c = np.array([(w - 1) / 2, (h - 1) / 2])
    inv = np.linalg.inv(jac)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    dx, dy = xx - c[0], yy - c[1]
    return _warp(img, c[0] + inv[0, 0] * dx + inv[0, 1] * dy,
                 c[1] + inv[1, 0] * dx + inv[1, 1] * dy), jac


def wrinkle(img: np.ndarray, amplitude_px: float, wavelength_px: float, *, n: int = 4,
            shade: float = 0.15, rng: np.random.Generator | None = None) -> np.ndarray:
    """Wrinkles: a few random creases, each a smooth local displacement (the cloth
    pulled towards the fold) with the light and shadow of its slopes."""
    rng = rng if rng is not None else np.random.default_rng(0)
    h, w = img.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    dx = np.zeros((h, w), np.float32)
    dy = np.zeros((h, w), np.float32)
    light = np.ones((h, w), np.float32)
    for _ in range(n):
        a = rng.uniform(0, math.pi)
        nx, ny = -math.sin(a), math.cos(a)  # across the crease
        cx, cy = rng.uniform(0, w), rng.uniform(0, h)
        s = ((xx - cx) * nx + (yy - cy) * ny) / wavelength_px
        t = ((xx - cx) * math.cos(a) + (yy - cy) * math.sin(a)) / (3 * wavelength_px)
        env = np.exp(-t * t)  # a crease fades out along its length
        prof = np.exp(-s * s) * env
        dx += amplitude_px * s * prof * nx
        dy += amplitude_px * s * prof * ny
        light *= 1.0 + shade * (-2 * s * prof)  # one slope lit, the other in shade
    out = _warp(img, xx - dx, yy - dy).astype(np.float32)
    out *= light[..., None] if out.ndim == 3 else light
    return np.clip(out, 0, 255).astype(img.dtype)


def misregister(img: np.ndarray, shift_px: tuple[float, float],
                channel: int = 0) -> np.ndarray:
    """One colour separation printed ``shift_px`` (x, y) out of register."""
    if img.ndim != 3:
        raise ValueError("misregistration needs a colour image (H, W, 3)")
    out = img.copy()
    m = np.float32([[1, 0, shift_px[0]], [0, 1, shift_px[1]]])
    out[..., channel] = cv2.warpAffine(img[..., channel], m, img.shape[1::-1],
                                       flags=cv2.INTER_LINEAR,
                                       borderMode=cv2.BORDER_REFLECT)
    return out
