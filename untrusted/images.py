"""Images from untrusted files: the pixel count is read from the header and checked before
OpenCV decodes (and allocates) anything."""

from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np

from untrusted.errors import InputError
from untrusted.files import read_bytes
from untrusted.limits import MAX_IMAGE_BYTES, MAX_IMAGE_PIXELS

# OpenCV's own backstop for the formats parsed by neither header reader below (TIFF, WebP..).
# OpenCV reads it once, when its library loads (measured: set after `import cv2` it is
# ignored), so it is set before the import; where cv2 was loaded first it has no effect.
os.environ.setdefault("OPENCV_IO_MAX_IMAGE_PIXELS", str(MAX_IMAGE_PIXELS))

import cv2  # noqa: E402  (after the limit above, which OpenCV reads as it loads)

_JPEG_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}


def header_size(data: bytes) -> tuple[int, int] | None:
    """(width, height) from a PNG, BMP or JPEG header; None for other formats or a bad
    header."""
    if data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) >= 24:
        return struct.unpack(">II", data[16:24])
    if data[:2] == b"BM" and len(data) >= 26:
        width, height = struct.unpack("<ii", data[18:26])
        return abs(width), abs(height)
    if data[:2] == b"\xff\xd8":
        i = 2
        while i + 9 <= len(data):
            if data[i] != 0xFF:
                return None
            marker = data[i + 1]
            if marker in _JPEG_SOF:
                height, width = struct.unpack(">HH", data[i + 5 : i + 9])
                return width, height
            if marker == 0xD8 or 0xD0 <= marker <= 0xD7 or marker == 0x01:
                i += 2
                continue
            i += 2 + struct.unpack(">H", data[i + 2 : i + 4])[0]
    return None


def read_image(path: str | Path, *, max_pixels: int = MAX_IMAGE_PIXELS) -> np.ndarray:
    """(h, w, 3) uint8 BGR image of ``path``, or an InputError naming the file."""
    data = read_bytes(path, what="image", max_bytes=MAX_IMAGE_BYTES)
    size = header_size(data)
    if size is not None and size[0] * size[1] > max_pixels:
        raise InputError(path, f"image of {size[0]} x {size[1]} pixels exceeds the limit of "
                         f"{max_pixels:,} pixels")
    try:
        image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    except cv2.error:
        image = None
    if image is None:
        raise InputError(path, "not an image OpenCV can read")
    if image.shape[0] * image.shape[1] > max_pixels:
        raise InputError(path, f"image of {image.shape[1]} x {image.shape[0]} pixels exceeds "
                         f"the limit of {max_pixels:,} pixels")
    return image
