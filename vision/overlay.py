"""The picture an operator confirms a detection on: the lattice, the symmetry elements
of the group found and the distortion grid drawn over the photo, with the runners-up."""

from __future__ import annotations

import math

import cv2
import numpy as np

from solver.wallpaper import Wallpaper
from vision.fabric import FabricDetection

__all__ = ["draw_overlay", "symmetry_elements"]

def draw_overlay(image: np.ndarray, det: FabricDetection) -> np.ndarray:
    """The image with the lattice (grey), mirror lines (blue, solid), glide lines
    (green, dashed), rotation centres (red, with their order) and the local lattices of
    the distortion grid (yellow arrows)."""
    out = image.copy() if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    wp = det.classification.wallpaper  # image mm frame (without offset)
    s = det.mm_per_px
    h, w = out.shape[:2]

    def px(p):
        return tuple(int(round(v)) for v in (np.asarray(p) / s))

    if wp is None:
        _caption(out, [f"no lattice: {det.lattice.kind}", det.lattice.message])
        return out
    region = (0.0, 0.0, (w - 1) * s, (h - 1) * s)
    f = wp.to_fractional(np.array([[0, 0], [region[2], 0], [0, region[3]],
                                   [region[2], region[3]]]))
    lo, hi = np.floor(f.min(0)).astype(int) - 1, np.ceil(f.max(0)).astype(int) + 1
    for i in range(lo[0], hi[0] + 1):
        cv2.line(out, px(wp.to_cartesian([[i, lo[1]]])[0]), px(wp.to_cartesian([[i, hi[1]]])[0]),
                 (160, 160, 160), 1, cv2.LINE_AA)
    for j in range(lo[1], hi[1] + 1):
        cv2.line(out, px(wp.to_cartesian([[lo[0], j]])[0]), px(wp.to_cartesian([[hi[0], j]])[0]),
                 (160, 160, 160), 1, cv2.LINE_AA)
    # Symmetry elements near the origin's cell only (the rest repeat).
    o = wp.origin
    span = 1.6 * float(np.linalg.norm(wp.basis, axis=0).max())
    centres, lines = symmetry_elements(wp, (o[0] - span, o[1] - span, o[0] + span,
                                            o[1] + span))
    for p, d, glide in lines:
        a, b = p - d * span, p + d * span
        if glide:
            for t in np.linspace(0, 1, 17)[::2]:
                cv2.line(out, px(a + (b - a) * t), px(a + (b - a) * min(1.0, t + 1 / 16)),
                         (0, 200, 0), 2, cv2.LINE_AA)
        else:
            cv2.line(out, px(a), px(b), (255, 80, 0), 2, cv2.LINE_AA)
    for p, order in centres:
        cv2.circle(out, px(p), 5, (0, 0, 255), -1, cv2.LINE_AA)
        cv2.putText(out, str(order), px(p + 0.5 * s * np.array([8, -8])),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 255), 1, cv2.LINE_AA)
    cv2.circle(out, px(o), 8, (0, 255, 255), 2, cv2.LINE_AA)
    d = det.distortion
    for c, a, b in zip(d.centres, d.w1, d.w2, strict=True):
        for v in (a, b):
            cv2.arrowedLine(out, px(c), px(c + v), (0, 220, 255), 2, cv2.LINE_AA,
                            tipLength=0.15)
    # The runners-up, so the operator confirming the print sees what else it may be.
    cls = det.classification
    post = sorted(cls.posterior.items(), key=lambda kv: -kv[1])
    label = f"{cls.group} {cls.confidence:.2f}" + "".join(
        f", {g} {p:.2f}" for g, p in post[:3] if p >= 0.01 and g != cls.group)
    _caption(out, [label, d.warning, cls.message])
    return out


def _caption(image: np.ndarray, texts: list[str | None], scale: float = 0.6) -> None:
    """``texts`` (empty ones skipped) written over the top of ``image``, each wrapped to
    its width, on a dark band so that they read over any print."""
    font, thick = cv2.FONT_HERSHEY_SIMPLEX, 1
    width = image.shape[1] - 20
    lines: list[str] = []
    for text in filter(None, texts):
        line = ""
        for word in text.split():
            wider = f"{line} {word}".strip()
            if line and cv2.getTextSize(wider, font, scale, thick)[0][0] > width:
                lines.append(line)
                wider = word
            line = wider
        lines.append(line)
    step = int(cv2.getTextSize("Ag", font, scale, thick)[0][1] * 1.8)
    band = image[:step * len(lines) + 10]
    band[:] = (band * 0.35).astype(image.dtype)
    for k, line in enumerate(lines):
        cv2.putText(image, line, (10, step * (k + 1)), font, scale, (255, 255, 255), thick,
                    cv2.LINE_AA)


def symmetry_elements(wp: Wallpaper, region: tuple[float, float, float, float]
                      ) -> tuple[list[tuple[np.ndarray, int]], list[tuple[np.ndarray,
                                                                          np.ndarray, bool]]]:
    """Rotation centres (point, order) and reflection lines (point, direction, is_glide)
    of ``wp`` inside ``region`` = (x0, y0, x1, y1) mm, for drawing."""
    x0, y0, x1, y1 = region
    corners = np.array([[x0, y0], [x1, y0], [x0, y1], [x1, y1]])
    f = wp.to_fractional(corners)
    lo, hi = np.floor(f.min(0)).astype(int) - 1, np.ceil(f.max(0)).astype(int) + 1
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    reach = 0.5 * math.hypot(x1 - x0, y1 - y0)
    centres, lines = [], []
    for op in wp.cartesian_ops()[1:]:
        lin, t = op[:2, :2], op[:2, 2]
        if np.linalg.det(lin) > 0:
            ang = math.degrees(math.atan2(lin[1, 0], lin[0, 0])) % 360
            order = round(360 / ang)
            for i in range(lo[0], hi[0] + 1):
                for j in range(lo[1], hi[1] + 1):
                    # Rotation composed with the translation by i w1 + j w2.
                    c = np.linalg.solve(np.eye(2) - lin, t + wp.basis @ (i, j))
                    if x0 <= c[0] <= x1 and y0 <= c[1] <= y1:
                        centres.append((c, order))
        else:
            ev, vec = np.linalg.eigh((lin + lin.T) / 2)
            d = vec[:, np.argmax(ev)]
            for i in range(lo[0], hi[0] + 1):
                for j in range(lo[1], hi[1] + 1):
                    tt = t + wp.basis @ (i, j)
                    glide = (tt @ d) * d
                    p = (tt - glide) / 2
                    p = p + ((centre - p) @ d) * d  # the axis point nearest the region
                    if np.hypot(*(p - centre)) > reach:
                        continue
                    gl = wp.lattice_residual(glide[None])[0]
                    lines.append((p, d, bool(np.hypot(*gl) > 1e-6 * np.hypot(*wp.w1))))
    return centres, lines
