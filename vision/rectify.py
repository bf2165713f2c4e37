"""Camera frame -> top-down image of the table in machine millimetres.

Pixel ``(col, row)`` of the rectified image is centred on table point
``(x0 + col * s, y0 + row * s)`` mm (the simulators' convention), so a lattice found in
it converts to millimetres by one scale and one offset, with no perspective left.
"""

from __future__ import annotations

import cv2
import numpy as np

from vision.calibration import Calibration, rectified_size, visible_region

# visible_region and rectified_size live with the calibration, whose check needs them.
__all__ = ["pixel_to_mm", "rectified_size", "rectify", "visible_region"]


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


def pixel_to_mm(xy: np.ndarray, region: tuple[float, float, float, float],
                mm_per_px: float) -> np.ndarray:
    """Rectified-image pixel positions (N, 2) -> machine mm."""
    return np.asarray(xy, float) * mm_per_px + np.array(region[:2], float)
