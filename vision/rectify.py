"""Camera frame -> top-down image of the table in machine millimetres.

Pixel ``(col, row)`` of the rectified image is centred on table point
``(x0 + col * s, y0 + row * s)`` mm (the simulators' convention), so a lattice found in
it converts to millimetres by one scale and one offset, with no perspective left.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from untrusted.limits import MAX_IMAGE_PIXELS
from vision.calibration import Calibration

__all__ = ["check_view", "pixel_to_mm", "rectified_size", "rectify", "visible_region"]


def visible_region(cal: Calibration, *, samples: int = 64) -> tuple[float, float, float,
                                                                     float]:
    """The largest axis-aligned table rectangle (x0, y0, x1, y1) mm inside the frame.

    Found from the frame's border mapped onto the table: each side of the box is pushed
    in to the innermost border point on that side, so no rectified pixel is black.
    """
    w, h = cal.resolution
    t = np.linspace(0, 1, samples)
    top = cal.image_to_table(np.column_stack([t * (w - 1), np.zeros(samples)]))
    bottom = cal.image_to_table(np.column_stack([t * (w - 1), np.full(samples, h - 1.0)]))
    left = cal.image_to_table(np.column_stack([np.zeros(samples), t * (h - 1)]))
    right = cal.image_to_table(np.column_stack([np.full(samples, w - 1.0), t * (h - 1)]))
    border = np.concatenate([top, right, bottom, left])
    centre = cal.image_to_table(np.array([[(w - 1) / 2, (h - 1) / 2]]))[0]
    # Which side of the centre each border segment lies on, in table axes.
    rel = border - centre
    x0 = rel[(rel[:, 0] < 0) & (np.abs(rel[:, 1]) <= np.abs(rel[:, 0]))][:, 0].max(initial=-np.inf)
    x1 = rel[(rel[:, 0] > 0) & (np.abs(rel[:, 1]) <= np.abs(rel[:, 0]))][:, 0].min(initial=np.inf)
    y0 = rel[(rel[:, 1] < 0) & (np.abs(rel[:, 0]) <= np.abs(rel[:, 1]))][:, 1].max(initial=-np.inf)
    y1 = rel[(rel[:, 1] > 0) & (np.abs(rel[:, 0]) <= np.abs(rel[:, 1]))][:, 1].min(initial=np.inf)
    box = np.array([x0, y0, x1, y1])
    if not np.all(np.isfinite(box)):
        raise ValueError("calibration: the frame does not enclose a table region")
    # Shrink until all four corners map inside the frame.
    for _ in range(20):
        corners = centre + np.array([[box[0], box[1]], [box[2], box[1]], [box[2], box[3]],
                                     [box[0], box[3]]])
        px = cal.table_to_image(corners)
        if np.all((px >= 0) & (px <= [w - 1, h - 1])):
            break
        box *= 0.97
    x0, y0, x1, y1 = box + np.concatenate([centre, centre])
    return float(x0), float(y0), float(x1), float(y1)


def rectify(frame: np.ndarray, cal: Calibration, *,
            region: tuple[float, float, float, float] | None = None,
            mm_per_px: float | None = None) -> tuple[np.ndarray, tuple[float, float, float,
                                                                         float], float]:
    """Top-down image of ``region`` (default: the visible table) at ``mm_per_px``
    (default: the frame-centre footprint). Returns (image, region, mm_per_px)."""
    w, h = cal.resolution
    if (frame.shape[1], frame.shape[0]) != (w, h):
        raise ValueError(f"frame is {frame.shape[1]}x{frame.shape[0]} px but the "
                         f"calibration is for {w}x{h} px")
    region = region or visible_region(cal)
    s = float(mm_per_px or cal.mm_per_px())
    nx, ny = rectified_size(region, s)
    x0, y0, x1, y1 = region
    # The table -> pixel map is smooth: compute it exactly on a coarse grid and let
    # remap interpolate (as the simulator does), which keeps 12 MP frames fast.
    step = 8
    gx = x0 + np.arange(0, nx + step, step) * s
    gy = y0 + np.arange(0, ny + step, step) * s
    mx, my = np.meshgrid(gx, gy)
    px = cal.table_to_image(np.column_stack([mx.ravel(), my.ravel()]))
    cx = px[:, 0].reshape(mx.shape).astype(np.float32)
    cy = px[:, 1].reshape(mx.shape).astype(np.float32)
    fx = (np.arange(nx, dtype=np.float32) / step)[None, :].repeat(ny, 0)
    fy = (np.arange(ny, dtype=np.float32) / step)[:, None].repeat(nx, 1)
    mapx = cv2.remap(cx, fx, fy, cv2.INTER_LINEAR)
    mapy = cv2.remap(cy, fx, fy, cv2.INTER_LINEAR)
    out = cv2.remap(frame, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return out, (float(x0), float(y0), float(x1), float(y1)), s


def rectified_size(region: tuple[float, float, float, float], mm_per_px: float
                   ) -> tuple[int, int]:
    """(width, height) px of ``region`` rectified at ``mm_per_px``; a ValueError if that is
    not a sane image (at most the image pixel limit), before anything is allocated."""
    x0, y0, x1, y1 = region
    if not 0 < mm_per_px < math.inf:
        raise ValueError(f"mm per pixel must be positive and finite, got {mm_per_px:g}")
    nx, ny = (x1 - x0) / mm_per_px, (y1 - y0) / mm_per_px
    if not (8 <= nx <= 20000 and 8 <= ny <= 20000 and nx * ny <= MAX_IMAGE_PIXELS):
        raise ValueError(f"the table region {x0:.4g}..{x1:.4g} x {y0:.4g}..{y1:.4g} mm at "
                         f"{mm_per_px:.4g} mm/px gives {nx:.4g} x {ny:.4g} px")
    return int(round(nx)), int(round(ny))


def check_view(cal: Calibration) -> None:
    """A ValueError unless ``cal`` maps its frame onto a table region that rectifies into
    a sane image, at most 4 times the frame's pixels (a camera's view of a flat table is
    within a few times that): a calibration file's maps, checked before any photo is read."""
    nx, ny = rectified_size(visible_region(cal), cal.mm_per_px())
    w, h = cal.resolution
    if nx * ny > 4 * w * h:
        raise ValueError(f"the frame of {w} x {h} px would rectify into {nx} x {ny} px")


def pixel_to_mm(xy: np.ndarray, region: tuple[float, float, float, float],
                mm_per_px: float) -> np.ndarray:
    """Rectified-image pixel positions (N, 2) -> machine mm."""
    return np.asarray(xy, float) * mm_per_px + np.array(region[:2], float)
