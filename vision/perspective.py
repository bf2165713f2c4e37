"""Perspective left in a photo, found from how the lattice changes across the frame.

A print seen in perspective repeats at a scale and shear that change smoothly over the
image; the local lattices of :mod:`vision.distortion` measure that change. A pinhole
view of a flat sheet maps it by a homography, whose part that matters here is the
vanishing line: with image points ``x`` relative to the frame centre, the map
``g(x) = x / (1 + c . x)`` (identity with unit Jacobian at the centre) undoes the
perspective, so that every local lattice ``J_g(x) B(x)`` becomes the same lattice. ``c``
is fitted by least squares on the local lattices and kept only when it explains most of
their variation and that variation is more than noise.

The print's designed lattice cannot be read off such a photo to better than the change
the view makes across it: a square knit check that a tilted, curved view shows 16
degrees sheared is still a square check. The group decision is therefore made on the
rectified image, with the lattice tolerances widened by the measured change
(:func:`vision.classify.classify`, ``allowance``); the change is reported.

References
----------
.. [1] R. Hartley, A. Zisserman, *Multiple View Geometry in Computer Vision*, 2nd ed.,
       Cambridge 2004, Sec. 2.7 (affine rectification from the vanishing line).
.. [2] F. Schaffalitzky, A. Zisserman, "Geometric grouping of repeated elements within
       images", BMVC 1998 (the homography from repeated elements' local changes).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import least_squares

__all__ = ["View", "fit_view"]

#: Smallest lattice change across the frame (relative) that counts as perspective; a
#: smaller one is within what the local fits scatter and the decision tolerates anyway.
MIN_CHANGE = 0.04

#: Share of the local lattices' variation the perspective must explain.
MIN_EXPLAINED = 0.6


@dataclass(frozen=True)
class View:
    """A perspective found in an image: ``c`` (per working pixel, relative to the frame
    centre ``centre``) and what it implies."""

    c: np.ndarray  # (2,) in working (x, y) px^-1
    centre: np.ndarray  # (2,) working px
    scale: float  # working px per input px
    change: float  # largest relative lattice change across the frame it explains
    explained: float  # share of the local lattices' variation it explains

    def rectify(self, flat: np.ndarray) -> tuple[np.ndarray, tuple[int, int]]:
        """The working image with the perspective undone (same scale and frame at the
        centre), cropped to the centred box that the photo covers. Returns the image
        and the box's top-left corner (working px) in the input frame."""
        h, w = flat.shape
        c = self.c
        half = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
        # Shrink the box until every border point's source lies inside the photo.
        frac = 1.0
        t = np.linspace(-1.0, 1.0, 33)
        edge = np.concatenate([np.column_stack([t, np.full_like(t, s)]) for s in (-1, 1)]
                              + [np.column_stack([np.full_like(t, s), t]) for s in (-1, 1)])
        for _ in range(40):
            y = edge * half * frac
            den = 1.0 - y @ c
            x = y / den[:, None] + self.centre
            if np.all(den > 0.05) and np.all((x >= 0) & (x <= [w - 1, h - 1])):
                break
            frac *= 0.95
        bw, bh = (np.floor(half * frac) * 2 + 1).astype(int)
        x0, y0 = int(round(self.centre[0] - (bw - 1) / 2)), int(round(self.centre[1]
                                                                      - (bh - 1) / 2))
        yy, xx = np.mgrid[0:bh, 0:bw].astype(np.float32)
        ry = yy + (y0 - self.centre[1])
        rx = xx + (x0 - self.centre[0])
        den = (1.0 - c[0] * rx - c[1] * ry).astype(np.float32)
        mapx = (rx / den + self.centre[0]).astype(np.float32)
        mapy = (ry / den + self.centre[1]).astype(np.float32)
        out = cv2.remap(flat, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                        borderValue=0.0)
        return out - np.float32(out.mean()), (x0, y0)

    def to_dict(self) -> dict:
        """The vanishing line in input pixels (a x + b y + 1 = 0 about the frame centre),
        the lattice change it explains and the share of the variation."""
        return {"vanishing_line_per_px": [round(float(v), 7) for v in self.c * self.scale],
                "lattice_change": round(self.change, 4),
                "explained": round(self.explained, 3)}


def _jacobians(c: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(K, 2, 2) Jacobians of g(x) = x / (1 + c . x) at points x (K, 2)."""
    den = 1.0 + x @ c
    g = x / den[:, None]
    return (np.eye(2)[None] - g[:, :, None] * c[None, None, :]) / den[:, None, None]


def _residual(c: np.ndarray, x: np.ndarray, local: np.ndarray, size: float) -> np.ndarray:
    """Each local lattice carried to the centre by g, minus their mean, relative."""
    carried = _jacobians(c, x) @ local
    return ((carried - carried.mean(axis=0)) / size).ravel()


def fit_view(centres: np.ndarray, local: np.ndarray, shape: tuple[int, int],
             scale: float) -> View | None:
    """The perspective behind local lattices, or None when there is none to speak of.

    Parameters
    ----------
    centres : (K, 2)
        Tile centres, working (x, y) px.
    local : (K, 2, 2)
        Local lattice bases (columns w1, w2, sign-aligned) at those centres, working px.
    shape : (h, w)
        The working image's shape (its centre is the view's fixed point).
    """
    if len(centres) < 4:
        return None
    h, w = shape
    centre = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    x = np.asarray(centres, float) - centre
    if np.linalg.matrix_rank(x - x.mean(0), tol=1e-6) < 2:
        return None
    size = float(np.linalg.norm(local, axis=1).mean())
    reach = float(np.abs(x).max())
    base = _residual(np.zeros(2), x, local, size)
    sol = least_squares(_residual, np.zeros(2), args=(x, local, size),
                        bounds=(-0.9 / reach, 0.9 / reach))
    c = sol.x
    total, left = float(base @ base), float(sol.fun @ sol.fun)
    if total <= 0:
        return None
    explained = 1.0 - left / total
    # The lattice change over the measured tiles that the perspective accounts for.
    jac = _jacobians(c, x)
    change = float(np.abs(np.linalg.svd(jac, compute_uv=False) - 1.0).max())
    if explained < MIN_EXPLAINED or change < MIN_CHANGE:
        return None
    return View(c, centre, float(scale), change, explained)
