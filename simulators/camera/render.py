"""Colours of table points: the sheet's print filtered for each pixel's footprint, the
board on its paper, the bare table around them; and distortion-free top-down views."""

from __future__ import annotations

import math

import cv2
import numpy as np

from simulators.camera.scene import Board, Sheet
from simulators.fabric import Print, to_uint8

_TABLE_BGR = np.array([0.30, 0.34, 0.27], np.float32)  # a grey-green cutting mat
_PAPER_BGR = np.array([0.97, 0.97, 0.96], np.float32)


def _sample_print(p: Print, fx: np.ndarray, fy: np.ndarray,
                  footprint: float | np.ndarray) -> np.ndarray:
    """Print colours filtered for each pixel's own footprint.

    A tilted view sees the fabric at different scales across the frame; one filter
    would blur the near side or alias the far side. Two band-limited textures (finest
    and coarsest footprint) are blended per pixel by log footprint, like mip-mapping.
    """
    if np.ndim(footprint) == 0:
        return p.colour_at(fx, fy, float(footprint))
    lo, hi = float(footprint.min()), float(footprint.max())
    if hi <= 1.2 * lo:
        return p.colour_at(fx, fy, 0.5 * (lo + hi))
    near, far = p.colour_at(fx, fy, lo), p.colour_at(fx, fy, hi)
    t = np.clip(np.log(footprint / np.float32(lo)) / np.float32(math.log(hi / lo)), 0, 1)
    return cv2.blendLinear(far, near, t.astype(np.float32), (1.0 - t).astype(np.float32))


def render_table(x: np.ndarray, y: np.ndarray, footprint: float | np.ndarray,
                 sheet: Sheet | None, board: Board | None) -> np.ndarray:
    """Float32 BGR colours of table points (mm), anti-aliased for ``footprint`` mm per
    pixel (a number, or one per pixel): the table, the sheet over it, the board on top."""
    out = np.empty(x.shape + (3,), np.float32)
    out[:] = _TABLE_BGR
    fp = np.maximum(footprint, 1e-6)
    if sheet is not None:
        out = _paint_sheet(out, x, y, fp, sheet)
    if board is not None:
        out = _paint_board(out, x, y, fp, board)
    return out


def _paint_sheet(out: np.ndarray, x: np.ndarray, y: np.ndarray, fp: float | np.ndarray,
                 sheet: Sheet) -> np.ndarray:
    lx, ly = sheet.table_to_local(x, y)
    cover = np.float32(1.0)
    if sheet.size is not None:  # the sheet is a rectangle; the print inside may not be
        w, h = sheet.size
        inside = np.minimum(np.minimum(lx, w - lx), np.minimum(ly, h - ly))
        cover = np.clip(inside / fp + 0.5, 0.0, 1.0).astype(np.float32)[..., None]
    fx, fy = sheet.local_to_fabric(lx, ly)
    colour = _sample_print(sheet.print, fx, fy, fp)
    shade = sheet.shading(lx)
    if not np.isscalar(shade):
        colour *= np.asarray(shade, np.float32)[..., None]
    return _blend(colour, out, cover)


def _paint_board(out: np.ndarray, x: np.ndarray, y: np.ndarray, fp: float | np.ndarray,
                 board: Board) -> np.ndarray:
    """The board's printed image, blurred to the finest footprint, on its white paper."""
    bx, by = board.table_to_board(x, y)
    bw, bh = board.extent_mm
    m = board.margin_mm
    paper = np.minimum(np.minimum(bx + m, bw + m - bx), np.minimum(by + m, bh + m - by))
    cover = np.clip(paper / fp + 0.5, 0.0, 1.0).astype(np.float32)[..., None]
    fine = float(np.min(fp))
    img, ppm = board.image(float(np.clip(4.0 / fine, 4.0, 16.0)))
    sigma = 0.5 * fine * ppm
    if sigma > 0.3:
        img = cv2.GaussianBlur(img, (0, 0), sigma)
    grey = cv2.remap(img, (bx * ppm - 0.5).astype(np.float32),
                     (by * ppm - 0.5).astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=1.0)
    colour = grey[..., None] * _PAPER_BGR
    return _blend(colour, out, cover)


def _blend(top: np.ndarray, below: np.ndarray, cover) -> np.ndarray:
    """``cover * top + (1 - cover) * below`` with a per-pixel (H, W, 1) or scalar cover."""
    if np.isscalar(cover) or np.ndim(cover) == 0:
        return top if float(cover) >= 1.0 else below + float(cover) * (top - below)
    c = np.ascontiguousarray(cover[..., 0], np.float32)
    return cv2.blendLinear(top, below, c, 1.0 - c)


def render_rectified(sheet: Sheet | Print | None, region: tuple[float, float, float, float],
                     mm_per_px: float, *, board: Board | None = None) -> np.ndarray:
    """A distortion-free top-down image of the table region ``(x0, y0, x1, y1)`` mm.

    Pixel ``(col, row)`` is centred on table point ``(x0 + col * s, y0 + row * s)``.
    A bare :class:`Print` is laid on the table as an endless sheet at the origin.
    Returns (H, W, 3) BGR uint8.
    """
    if mm_per_px <= 0:
        raise ValueError(f"mm per pixel must be positive, got {mm_per_px}")
    x0, y0, x1, y1 = (float(v) for v in region)
    w, h = int(round((x1 - x0) / mm_per_px)), int(round((y1 - y0) / mm_per_px))
    if not (1 <= w <= 20000 and 1 <= h <= 20000):
        raise ValueError(f"region {region} at {mm_per_px} mm/px gives {w}x{h} px")
    if isinstance(sheet, Print):
        sheet = Sheet(sheet, size=None)
    xs = x0 + np.arange(w) * mm_per_px
    ys = y0 + np.arange(h) * mm_per_px
    x, y = np.meshgrid(xs.astype(np.float32), ys.astype(np.float32))
    return to_uint8(render_table(x, y, mm_per_px, sheet, board))


