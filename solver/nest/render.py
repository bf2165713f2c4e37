"""Draw a marker (OpenCV): the print under the pieces, outlines, notches, grain lines, ids."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from solver.nest.layout import Layout


def _print_image(fabric: dict, length: float, width: float, mm_px: float) -> np.ndarray:
    """The print rendered by the simulator, or a plain lattice drawing if that fails."""
    from solver.wallpaper import Wallpaper

    wp = Wallpaper.from_dict(fabric)
    try:
        from simulators.fabric import random_print, render_print

        p = random_print(wp.group, w1=wp.w1, w2=wp.w2, origin=tuple(wp.origin))
        img = render_print(p, (length, width), mm_px)
        return cv2.addWeighted(img, 0.55, np.full_like(img, 255), 0.45, 0)
    except Exception:  # noqa: BLE001 - the drawing must not fail because of a preview
        img = np.full((int(round(width / mm_px)), int(round(length / mm_px)), 3), 245, np.uint8)
        f = wp.to_fractional(np.array([[0, 0], [length, 0], [0, width], [length, width]]))
        lo, hi = np.floor(f.min(0)).astype(int) - 1, np.ceil(f.max(0)).astype(int) + 1
        glyph = np.array([[0.1, 0.1], [0.1, 0.4], [0.25, 0.4], [0.1, 0.25], [0.2, 0.25]])
        ops = wp.info.ops
        for i in range(lo[0], hi[0]):
            for j in range(lo[1], hi[1]):
                for op in ops:
                    pts = wp.to_cartesian(glyph @ op[:, :2].T + op[:, 2] + (i, j)) / mm_px
                    cv2.polylines(img, [np.round(pts * 16).astype(np.int32)], False,
                                  (190, 150, 120), 1, cv2.LINE_AA, shift=4)
        return img


def render_layout(layout: Layout, path: str | Path, *, max_px: int = 2400) -> None:
    """PNG of the marker; y (fabric width) runs down the image, x (length) to the right."""
    mm_px = max(layout.length, layout.width) / max_px
    h, w = int(round(layout.width / mm_px)), int(round(layout.length / mm_px))
    if layout.fabric:
        img = _print_image(layout.fabric, layout.length, layout.width, mm_px)[:h, :w]
    else:
        img = np.full((h, w, 3), 250, np.uint8)
    px = lambda p: np.round(np.asarray(p, float) / mm_px * 16).astype(np.int32)  # noqa: E731
    overlay = img.copy()
    for k in layout.keepouts:
        cv2.fillPoly(overlay, [px(k)], (60, 60, 200), cv2.LINE_AA, shift=4)
    for p in layout.pieces:
        if not layout.fabric:
            cv2.fillPoly(overlay, [px(p.outline)], (200, 220, 240), cv2.LINE_AA, shift=4)
    img = cv2.addWeighted(overlay, 0.6, img, 0.4, 0)
    for p in layout.pieces:
        cv2.polylines(img, [px(p.outline)], True, (40, 40, 40), 1, cv2.LINE_AA, shift=4)
        for hole in p.holes:
            cv2.polylines(img, [px(hole)], True, (40, 40, 40), 1, cv2.LINE_AA, shift=4)
        size = max(2.0, 0.01 * layout.width)
        for at, d in p.notches:
            cv2.line(img, *[tuple(v) for v in px([at, at + size * d])], (0, 0, 200), 1,
                     cv2.LINE_AA, shift=4)
        if p.grainline is not None:
            a, b = px(p.grainline)
            cv2.arrowedLine(img, tuple(a), tuple(b), (0, 120, 0), 1, cv2.LINE_AA, shift=4)
        c = p.outline.mean(0) / mm_px
        cv2.putText(img, p.id, (int(c[0]) - 10, int(c[1])), cv2.FONT_HERSHEY_SIMPLEX,
                    0.35, (20, 20, 20), 1, cv2.LINE_AA)
    if not cv2.imwrite(str(path), img):
        raise ValueError(f"{path}: cannot write the image")
