"""What the light, lens and sensor do to the ideal image: gain ramp, vignetting, blur, shot
and read noise, JPEG compression."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class Imaging:
    """What the light, lens and sensor do to the ideal image."""

    exposure: float = 1.0
    light_ramp: tuple[float, float] = (0.12, -0.08)  # gain change edge-to-centre in x, y
    vignetting: float = 0.22  # relative fall-off in the image corners
    blur: float = 0.6  # Gaussian sigma, px (optics and demosaicing)
    noise: float = 2.0  # sd in grey levels at mid grey (shot + read noise)
    jpeg_quality: int | None = 92  # None: no compression

    @classmethod
    def ideal(cls) -> Imaging:
        return cls(light_ramp=(0.0, 0.0), vignetting=0.0, blur=0.0, noise=0.0,
                   jpeg_quality=None)




def expose(img: np.ndarray, im: Imaging, rng: np.random.Generator) -> np.ndarray:
    """The frame a sensor makes of ideal float32 BGR colours ``img`` (H, W, 3) in [0, 1]:
    light, blur, noise, rounding and JPEG; (H, W, 3) BGR uint8. ``rng`` seeds the noise."""
    h, w = img.shape[:2]
    # light: a gain ramp across the frame and vignetting (cos^4-like fall-off)
    nx = np.linspace(-1.0, 1.0, w, dtype=np.float32)[None, :]
    ny = np.linspace(-1.0, 1.0, h, dtype=np.float32)[:, None]
    gain = im.exposure * (1.0 + im.light_ramp[0] * nx + im.light_ramp[1] * ny)
    gain = (gain * (1.0 - im.vignetting * 0.5 * (nx * nx + ny * ny))).astype(np.float32)
    # (OpenCV's element-wise functions below are several times faster than NumPy's
    # on 12-megapixel float images, which matters for 4000 x 3000 frames.)
    img = cv2.multiply(img, cv2.merge([gain, gain, gain]), scale=255.0)
    if im.blur > 0:
        img = cv2.GaussianBlur(img, (0, 0), im.blur)
    if im.noise > 0:
        read = 0.5 * im.noise
        shot = (im.noise**2 - read**2) / 128.0
        var = cv2.add(cv2.multiply(cv2.max(img, 0.0), shot), read**2)
        # cv2.randn is ~5x faster than NumPy's normals; seeding OpenCV's generator
        # from the camera's own keeps every frame repeatable.
        cv2.setRNGSeed(int(rng.integers(2**31 - 1)))
        noise = cv2.randn(np.empty_like(img), (0.0,) * 3, (1.0,) * 3)  # per channel
        img = cv2.add(img, cv2.multiply(cv2.sqrt(var), noise))
    frame = cv2.convertScaleAbs(cv2.max(img, 0.0))  # rounds and saturates to uint8
    if im.jpeg_quality is not None:
        _, buf = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, im.jpeg_quality])
        frame = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    return frame
