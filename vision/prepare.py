"""The working image of a photo: grey (or colour channels), shrunk to a working size,
smooth light (gain ramp, vignetting) divided out, zero mean. Lattice detection,
classification and the distortion measure all read the print from it."""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["WORK_SIDE", "prepare_colour", "prepare_image", "to_gray_float", "to_gray_shape"]

#: Largest side of the working image: the lattice is fitted on many peaks, so a
#: moderate resolution keeps sub-pixel precision while the FFT stays fast.
WORK_SIDE = 1024


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
    # (3,H,W) planes, not a view of the (H,W,3) pixels: the means below then run along
    # rows (a view made this function 9 times slower than prepare_image).
    chans = np.ascontiguousarray(np.moveaxis(_unit_float(img), 2, 0))
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
